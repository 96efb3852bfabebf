/* Stand-in for Force Dimension's dhdc.h (DHD API): the standard calls conica's backend uses, with
   the published names, signatures and return conventions (0 success, -1 error with dhdErrno set,
   positive non-errors DHD_TIMEGUARD / DHD_MOTOR_SATURATED; char ID = -1 is the default device).
   Units as in the SDK: m, m/s, N. Implemented by sdk_stubs/fake (CONICA_DEVICE_STUBS). */
#ifndef CONICA_STUB_DHDC_H
#define CONICA_STUB_DHDC_H

#ifndef __API
#define __API
#endif

#ifdef __cplusplus
extern "C" {
#endif

typedef unsigned char uchar;
typedef unsigned short ushort;
typedef unsigned int uint;
typedef unsigned long ulong;

enum dhd_errors {
  DHD_NO_ERROR,
  DHD_ERROR,
  DHD_ERROR_COM,
  DHD_ERROR_DHC_BUSY,
  DHD_ERROR_NO_DRIVER_FOUND,
  DHD_ERROR_NO_DEVICE_FOUND,
  DHD_ERROR_NOT_AVAILABLE,
  DHD_ERROR_TIMEOUT,
  DHD_ERROR_GEOMETRY,
  DHD_ERROR_EXPERT_MODE_DISABLED,
  DHD_ERROR_NOT_IMPLEMENTED,
  DHD_ERROR_OUT_OF_MEMORY,
  DHD_ERROR_DEVICE_NOT_READY,
  DHD_ERROR_FILE_NOT_FOUND,
  DHD_ERROR_CONFIGURATION,
  DHD_ERROR_INVALID_INDEX
};

typedef int* dhdErrorVal;
typedef const char* dhdErrorStr;
dhdErrorVal __API dhdErrnoLocation();
#define dhdErrno (*dhdErrnoLocation())
dhdErrorStr __API dhdErrorGetLastStr();
dhdErrorStr __API dhdErrorGetStr(int error);

#define DHD_DEVICE_NONE 0
#define DHD_DEVICE_OMEGA3 33
#define DHD_ON 1
#define DHD_OFF 0
#define DHD_MAX_DEVICE 4
#define DHD_MAX_BUTTONS 16
#define DHD_TIMEGUARD 1
#define DHD_MOTOR_SATURATED 2

int __API dhdGetDeviceCount();
int __API dhdOpen();
int __API dhdOpenID(char ID);
int __API dhdClose(char ID = -1);
int __API dhdStop(char ID = -1);
int __API dhdGetSystemType(char ID = -1);
const char* __API dhdGetSystemName(char ID = -1);
int __API dhdGetButton(int index, char ID = -1);
int __API dhdEnableForce(uchar val, char ID = -1);
int __API dhdSetGravityCompensation(int val = DHD_ON, char ID = -1);
int __API dhdSetBrakes(int val = DHD_ON, char ID = -1);
int __API dhdGetPosition(double* px, double* py, double* pz, char ID = -1);
int __API dhdGetForce(double* fx, double* fy, double* fz, char ID = -1);
int __API dhdSetForce(double fx, double fy, double fz, char ID = -1);
int __API dhdGetLinearVelocity(double* vx, double* vy, double* vz, char ID = -1);
double __API dhdGetTime();

#ifdef __cplusplus
}
#endif

#endif
