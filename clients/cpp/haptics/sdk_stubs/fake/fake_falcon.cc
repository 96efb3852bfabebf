// libnifalcon classes over fake_sdk::falcon::Device.
#include <falcon/core/FalconDevice.h>
#include <falcon/firmware/FalconFirmwareNovintSDK.h>
#include <falcon/kinematic/FalconKinematicStamper.h>
#include <falcon/util/FalconFirmwareBinaryNvent.h>

#include <algorithm>

#include "fake_devices.h"

namespace conica::fake_sdk::falcon {
namespace {
Device& world() {
  static Device d;
  return d;
}
}  // namespace
void reset() { world() = Device{}; }
Device& device() { return world(); }
}  // namespace conica::fake_sdk::falcon

namespace libnifalcon {

using conica::fake_sdk::falcon::device;

bool FalconFirmware::isFirmwareLoaded() { return m_isFirmwareLoaded = device().firmware_loaded; }

// Accepts exactly the image of falcon/util/FalconFirmwareBinaryNvent.h, on an open device.
bool FalconFirmware::loadFirmware(bool, const unsigned int& firmware_size, uint8_t* buffer) {
  auto& d = device();
  if (!d.open) {
    m_errorCode = FALCON_FIRMWARE_NO_COMM_SET;
    return false;
  }
  const bool ok = buffer != nullptr && firmware_size == NOVINT_FALCON_NVENT_FIRMWARE_SIZE &&
                  std::equal(buffer, buffer + firmware_size, NOVINT_FALCON_NVENT_FIRMWARE);
  if (!ok) {
    ++d.firmware_rejected;
    m_errorCode = FALCON_FIRMWARE_FILE_NOT_VALID;
    return false;
  }
  ++d.firmware_uploads;
  d.firmware_loaded = m_isFirmwareLoaded = true;
  return true;
}

FalconFirmwareNovintSDK::FalconFirmwareNovintSDK() = default;
FalconFirmwareNovintSDK::~FalconFirmwareNovintSDK() = default;

// One packet: needs the firmware; homing mode held for homing_loops packets homes all three
// encoders.
bool FalconFirmwareNovintSDK::runIOLoop() {
  auto& d = device();
  if (!d.open || !d.firmware_loaded) {
    m_errorCode = FALCON_FIRMWARE_NO_FIRMWARE_LOADED;
    return false;
  }
  if (m_homingMode && ++d.homing_seen >= d.homing_loops)
    m_homingStatus = ENCODER_1_HOMED | ENCODER_2_HOMED | ENCODER_3_HOMED;
  ++m_loopCount;
  return true;
}

FalconKinematicStamper::FalconKinematicStamper(bool) {}
void FalconKinematicStamper::initialize() {}
bool FalconKinematicStamper::getForces(double[3], double[3], int16_t (&enc)[3]) {
  enc[0] = enc[1] = enc[2] = 0;
  return true;
}
bool FalconKinematicStamper::getAngles(double[3], double angles[3]) {
  angles[0] = angles[1] = angles[2] = 0;
  return true;
}
bool FalconKinematicStamper::getPosition(int16_t[3], double position[3]) {
  const auto& p = device().position_m;
  std::copy(p.begin(), p.end(), position);
  return true;
}

FalconDevice::FalconDevice() = default;
FalconDevice::~FalconDevice() {
  if (m_open) close();
}
bool FalconDevice::isFirmwareLoaded() {
  return m_falconFirmware != nullptr && m_falconFirmware->isFirmwareLoaded();
}
bool FalconDevice::getDeviceCount(unsigned int& count) {
  count = static_cast<unsigned int>(std::max(0, device().count));
  return true;
}
bool FalconDevice::open(unsigned int index) {
  if (static_cast<int>(index) >= device().count) {
    m_errorCode = FALCON_DEVICE_NO_COMM_SET;
    return false;
  }
  device().open = m_open = true;
  device().homing_seen = 0;
  return true;
}
void FalconDevice::close() {
  device().open = m_open = false;
  device().motor_force = {};
}
bool FalconDevice::isOpen() { return m_open; }

bool FalconDevice::runIOLoop(unsigned int exe_flags) {
  auto& d = device();
  if (m_falconFirmware == nullptr) {
    m_errorCode = FALCON_DEVICE_NO_FIRMWARE_SET;
    return false;
  }
  if ((exe_flags & FALCON_LOOP_FIRMWARE) && !m_falconFirmware->runIOLoop()) {
    ++m_errorCount;
    return false;
  }
  ++d.io_loops;
  if (!m_falconFirmware->isHomed() || !(exe_flags & FALCON_LOOP_KINEMATIC)) {
    d.motor_force = {};
    d.motor_log.push_back(d.motor_force);
    return true;
  }
  if (m_falconKinematic == nullptr) {
    m_errorCode = FALCON_DEVICE_NO_KINEMATIC_SET;
    return false;
  }
  int16_t angles[3] = {0, 0, 0};
  double p[3];
  m_falconKinematic->getPosition(angles, p);
  m_position = {p[0], p[1], p[2]};
  d.motor_force = {m_forceVec[0], m_forceVec[1], m_forceVec[2]};
  d.motor_log.push_back(d.motor_force);
  return true;
}

}  // namespace libnifalcon
