/* Stand-in for OpenHaptics' HD/hd.h (HDAPI): device, frame, state and scheduler calls with the
   published names and signatures. See hdDefines.h; implemented by sdk_stubs/fake. */
#ifndef CONICA_STUB_HD_H
#define CONICA_STUB_HD_H

#include <HD/hdDefines.h>

#define HDAPI
#define HDAPIENTRY
#define HDCALLBACK

#ifdef __cplusplus
extern "C" {
#endif

/* Device */
HDAPI HHD HDAPIENTRY hdInitDevice(HDstring pConfigName);
HDAPI void HDAPIENTRY hdDisableDevice(HHD hHD);
HDAPI void HDAPIENTRY hdMakeCurrentDevice(HHD hHD);
HDAPI HHD HDAPIENTRY hdGetCurrentDevice(void);

/* Frames: state read and forces set between begin and end; forces are sent at hdEndFrame. */
HDAPI void HDAPIENTRY hdBeginFrame(HHD hHD);
HDAPI void HDAPIENTRY hdEndFrame(HHD hHD);

/* State */
HDAPI void HDAPIENTRY hdGetBooleanv(HDenum pname, HDboolean* params);
HDAPI void HDAPIENTRY hdGetIntegerv(HDenum pname, HDint* params);
HDAPI void HDAPIENTRY hdGetFloatv(HDenum pname, HDfloat* params);
HDAPI void HDAPIENTRY hdGetDoublev(HDenum pname, HDdouble* params);
HDAPI HDstring HDAPIENTRY hdGetString(HDenum pname);
HDAPI void HDAPIENTRY hdSetFloatv(HDenum pname, const HDfloat* params);
HDAPI void HDAPIENTRY hdSetDoublev(HDenum pname, const HDdouble* params);

/* Capabilities */
HDAPI void HDAPIENTRY hdEnable(HDenum cap);
HDAPI void HDAPIENTRY hdDisable(HDenum cap);
HDAPI HDboolean HDAPIENTRY hdIsEnabled(HDenum cap);

/* Errors: a stack; hdGetError pops the oldest, HD_SUCCESS when empty. */
HDAPI HDErrorInfo HDAPIENTRY hdGetError(void);
HDAPI HDstring HDAPIENTRY hdGetErrorString(HDerror errorCode);
#define HD_DEVICE_ERROR(X) (((X).errorCode) != HD_SUCCESS)

/* Scheduler: callbacks run in the servo thread (1 kHz); HD_CALLBACK_CONTINUE keeps an
   asynchronous callback scheduled for the next tick, HD_CALLBACK_DONE ends it. */
typedef unsigned int HDCallbackCode;
#define HD_CALLBACK_DONE 0
#define HD_CALLBACK_CONTINUE 1
typedef unsigned long HDSchedulerHandle;
typedef HDCallbackCode(HDCALLBACK* HDSchedulerCallback)(void* pUserData);

HDAPI void HDAPIENTRY hdStartScheduler(void);
HDAPI void HDAPIENTRY hdStopScheduler(void);
HDAPI HDSchedulerHandle HDAPIENTRY hdScheduleAsynchronous(HDSchedulerCallback pCallback,
                                                          void* pUserData, HDushort nPriority);
HDAPI void HDAPIENTRY hdScheduleSynchronous(HDSchedulerCallback pCallback, void* pUserData,
                                            HDushort nPriority);
HDAPI void HDAPIENTRY hdUnschedule(HDSchedulerHandle hHandle);
#define HD_WAIT_CHECK_STATUS 0
#define HD_WAIT_INFINITE 1
HDAPI HDboolean HDAPIENTRY hdWaitForCompletion(HDSchedulerHandle hHandle, HDuint param);
HDAPI void HDAPIENTRY hdSetSchedulerRate(HDulong nRate);

#ifdef __cplusplus
}
#endif

#endif
