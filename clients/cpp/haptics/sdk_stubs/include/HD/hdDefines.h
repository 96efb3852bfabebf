/* Stand-in for OpenHaptics' HD/hdDefines.h: the types, codes and parameter names conica's
   backend uses, with the values of the published SDK, so the backend compiles and is tested
   without the SDK (CONICA_DEVICE_STUBS). Units as in OpenHaptics: mm, mm/s, N; Y up, Z toward
   the user. Not a device driver: the fake library (sdk_stubs/fake) implements the calls. */
#ifndef CONICA_STUB_HD_DEFINES_H
#define CONICA_STUB_HD_DEFINES_H

#include <limits.h>
#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef unsigned int HDuint;
typedef unsigned char HDboolean;
typedef unsigned long HDulong;
typedef unsigned short HDushort;
typedef int HDint;
typedef float HDfloat;
typedef double HDdouble;
typedef long HDlong;
typedef char HDchar;

typedef unsigned int HDerror;
typedef unsigned int HDenum;
typedef const char* HDstring;
typedef unsigned int HHD;

typedef struct {
  HDerror errorCode;     /* an HD_ error code */
  int internalErrorCode; /* the device's own code */
  HHD hHD;               /* the device current when it happened */
} HDErrorInfo;

#define HD_TRUE 1
#define HD_FALSE 0

/* Error codes */
#define HD_SUCCESS 0x0000
#define HD_INVALID_ENUM 0x0100
#define HD_INVALID_VALUE 0x0101
#define HD_INVALID_OPERATION 0x0102
#define HD_INVALID_INPUT_TYPE 0x0103
#define HD_BAD_HANDLE 0x0104
#define HD_WARM_MOTORS 0x0200
#define HD_EXCEEDED_MAX_FORCE 0x0201
#define HD_EXCEEDED_MAX_FORCE_IMPULSE 0x0202
#define HD_EXCEEDED_MAX_VELOCITY 0x0203
#define HD_FORCE_ERROR 0x0204
#define HD_DEVICE_FAULT 0x0300
#define HD_DEVICE_ALREADY_INITIATED 0x0301
#define HD_COMM_ERROR 0x0302
#define HD_COMM_CONFIG_ERROR 0x0303
#define HD_TIMER_ERROR 0x0304
#define HD_ILLEGAL_BEGIN 0x0400
#define HD_ILLEGAL_END 0x0401
#define HD_FRAME_ERROR 0x0402
#define HD_INVALID_PRIORITY 0x0500
#define HD_SCHEDULER_FULL 0x0501
#define HD_INVALID_LICENSE 0x0600

/* Get parameters */
#define HD_CURRENT_BUTTONS 0x2000
#define HD_CURRENT_POSITION 0x2050 /* mm */
#define HD_CURRENT_VELOCITY 0x2051 /* mm/s */
#define HD_CURRENT_TRANSFORM 0x2052
#define HD_LAST_POSITION 0x2250
#define HD_DEVICE_MODEL_TYPE 0x2501
#define HD_UPDATE_RATE 0x2600                  /* Hz */
#define HD_NOMINAL_MAX_STIFFNESS 0x2602        /* N/mm */
#define HD_NOMINAL_MAX_FORCE 0x2603            /* N */
#define HD_NOMINAL_MAX_CONTINUOUS_FORCE 0x2604 /* N */

/* Set parameters */
#define HD_CURRENT_FORCE 0x2700 /* N */
#define HD_LAST_FORCE 0x2800

/* Capabilities */
#define HD_FORCE_OUTPUT 0x4000
#define HD_MAX_FORCE_CLAMPING 0x4001
#define HD_FORCE_RAMPING 0x4002
#define HD_SOFTWARE_FORCE_LIMIT 0x4003

/* Scheduler priorities */
#define HD_MAX_SCHEDULER_PRIORITY USHRT_MAX
#define HD_MIN_SCHEDULER_PRIORITY 0
#define HD_DEFAULT_SCHEDULER_PRIORITY ((HD_MAX_SCHEDULER_PRIORITY + HD_MIN_SCHEDULER_PRIORITY) / 2)

#define HD_DEVICE_BUTTON_1 (1 << 0)
#define HD_DEVICE_BUTTON_2 (1 << 1)

#define HD_INVALID_HANDLE 0xFFFFFFFF
#define HD_DEFAULT_DEVICE NULL

#ifdef __cplusplus
}
#endif

#endif
