// Stand-in for libnifalcon's falcon/core/FalconFirmware.h: the firmware policy (raw motor I/O,
// LEDs, homing, firmware upload), names and signatures as published. Implemented by
// sdk_stubs/fake (CONICA_DEVICE_STUBS).
#pragma once

#include <stdint.h>

#include <array>

#include "falcon/core/FalconCore.h"

namespace libnifalcon {

class FalconFirmware : public FalconCore {
 public:
  enum { GREEN_LED = 0x2, BLUE_LED = 0x4, RED_LED = 0x8 };
  enum { ENCODER_1_HOMED = 0x1, ENCODER_2_HOMED = 0x2, ENCODER_3_HOMED = 0x4 };
  enum {
    FALCON_FIRMWARE_NO_COMM_SET = 3000,
    FALCON_FIRMWARE_NO_FIRMWARE_SET,
    FALCON_FIRMWARE_NO_FIRMWARE_LOADED,
    FALCON_FIRMWARE_FILE_NOT_VALID,
    FALCON_FIRMWARE_CHECKSUM_MISMATCH
  };

  FalconFirmware() = default;
  ~FalconFirmware() override = default;

  virtual bool runIOLoop() = 0;
  void setForces(const std::array<int, 3>& force) { m_forceValues = force; }
  std::array<int, 3> getEncoderValues() { return m_encoderValues; }
  void setLEDStatus(unsigned int leds) { m_ledStatus = leds; }
  uint8_t getLEDStatus() { return static_cast<uint8_t>(m_ledStatus); }
  // Homing must be requested in every packet for the Falcon to home and stay homed; until all
  // three encoders are homed the kinematics (position, force) are not run.
  void setHomingMode(bool value) { m_homingMode = value; }
  unsigned int getHomingModeStatus() { return m_homingStatus; }
  bool isHomed() {
    return (m_homingStatus & (ENCODER_1_HOMED | ENCODER_2_HOMED | ENCODER_3_HOMED)) ==
           (ENCODER_1_HOMED | ENCODER_2_HOMED | ENCODER_3_HOMED);
  }
  bool isFirmwareLoaded();
  bool loadFirmware(bool skip_checksum, const unsigned int& firmware_size, uint8_t* buffer);
  uint64_t getLoopCount() { return m_loopCount; }

 protected:
  bool m_isFirmwareLoaded = false;
  bool m_homingMode = false;
  unsigned int m_ledStatus = 0;
  std::array<int, 3> m_forceValues{};
  std::array<int, 3> m_encoderValues{};
  unsigned int m_homingStatus = 0;
  uint64_t m_loopCount = 0;
};

}  // namespace libnifalcon
