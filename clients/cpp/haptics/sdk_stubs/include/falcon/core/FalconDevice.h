// Stand-in for libnifalcon's falcon/core/FalconDevice.h: the glue class (communication, firmware,
// kinematic and grip policies set by template), names and signatures as published; position in
// metres, force in newtons, in the Falcon's frame (x right, y up, z toward the user). Implemented
// by sdk_stubs/fake (CONICA_DEVICE_STUBS).
#pragma once

#include <array>
#include <memory>
#include <string>

#include "falcon/core/FalconCore.h"
#include "falcon/core/FalconFirmware.h"
#include "falcon/core/FalconKinematic.h"

namespace libnifalcon {

class FalconDevice : public FalconCore {
 public:
  enum {
    FALCON_DEVICE_NO_COMM_SET = 1000,
    FALCON_DEVICE_NO_FIRMWARE_SET,
    FALCON_DEVICE_NO_KINEMATIC_SET,
    FALCON_DEVICE_NO_GRIP_SET,
    FALCON_DEVICE_NO_FIRMWARE_LOADED,
    FALCON_DEVICE_FIRMWARE_NOT_VALID,
    FALCON_DEVICE_FIRMWARE_CHECKSUM_MISMATCH
  };
  enum { FALCON_LOOP_FIRMWARE = 0x1, FALCON_LOOP_KINEMATIC = 0x2, FALCON_LOOP_GRIP = 0x4 };

  FalconDevice();
  ~FalconDevice() override;

  bool isFirmwareLoaded();
  bool getDeviceCount(unsigned int& count);
  bool open(unsigned int index);
  void close();
  bool isOpen();
  // One I/O cycle: firmware packet out and in; when homed, the kinematics turn the encoders into
  // the position and the force set by setForce into motor values.
  bool runIOLoop(unsigned int exe_flags = (FALCON_LOOP_FIRMWARE | FALCON_LOOP_KINEMATIC |
                                           FALCON_LOOP_GRIP));

  template <class T>
  void setFalconFirmware() {
    m_falconFirmware.reset(new T());
  }
  template <class T>
  void setFalconKinematic() {
    m_falconKinematic.reset(new T());
  }

  std::array<double, 3> getPosition() { return m_position; }          // m
  void setForce(std::array<double, 3> force) { m_forceVec = force; }  // N
  std::shared_ptr<FalconFirmware> getFalconFirmware() { return m_falconFirmware; }
  std::shared_ptr<FalconKinematic> getFalconKinematic() { return m_falconKinematic; }
  unsigned int getErrorCount() { return m_errorCount; }

 protected:
  unsigned int m_errorCount = 0;
  std::shared_ptr<FalconKinematic> m_falconKinematic;
  std::shared_ptr<FalconFirmware> m_falconFirmware;
  std::array<double, 3> m_position{};
  std::array<double, 3> m_forceVec{};
  bool m_open = false;
};

}  // namespace libnifalcon
