// Force Dimension DHD calls over fake_sdk::dhd::Device.
#include <dhdc.h>

#include <chrono>
#include <cmath>

#include "fake_devices.h"

namespace conica::fake_sdk::dhd {
namespace {
struct World {
  Device dev;
  int err = DHD_NO_ERROR;
};
World& world() {
  static World w;
  return w;
}
int fail(int code) {
  world().err = code;
  return -1;
}
// -1 unless the device is open, reachable and ID names it (-1 or 0).
int check(char id) {
  const auto& d = world().dev;
  if (id != -1 && id != 0) return fail(DHD_ERROR_INVALID_INDEX);
  if (!d.open) return fail(DHD_ERROR_DEVICE_NOT_READY);
  if (d.comm_error) return fail(DHD_ERROR_COM);
  return 0;
}
}  // namespace
void reset() { world() = World{}; }
Device& device() { return world().dev; }
}  // namespace conica::fake_sdk::dhd

using conica::fake_sdk::dhd::check;
using conica::fake_sdk::dhd::device;
using conica::fake_sdk::dhd::fail;
using conica::fake_sdk::dhd::world;

extern "C" {

dhdErrorVal dhdErrnoLocation() { return &world().err; }
dhdErrorStr dhdErrorGetStr(int error) {
  switch (error) {
    case DHD_NO_ERROR:
      return "no error";
    case DHD_ERROR_COM:
      return "communication error between the host and the device";
    case DHD_ERROR_NO_DEVICE_FOUND:
      return "no compatible Force Dimension device found";
    case DHD_ERROR_DEVICE_NOT_READY:
      return "the device is not ready (not open)";
    case DHD_ERROR_INVALID_INDEX:
      return "invalid device index";
    default:
      return "DHD error";
  }
}
dhdErrorStr dhdErrorGetLastStr() { return dhdErrorGetStr(world().err); }

int dhdGetDeviceCount() { return device().count; }
int dhdOpen() {
  auto& d = device();
  if (d.count <= 0) return fail(DHD_ERROR_NO_DEVICE_FOUND);
  d.open = true;
  d.force_enabled = false;
  return 0;
}
int dhdOpenID(char id) {
  if (id != 0) return fail(DHD_ERROR_INVALID_INDEX);
  return dhdOpen();
}
int dhdClose(char id) {
  if (check(id) < 0) return -1;
  auto& d = device();
  d.open = false;
  d.force_enabled = false;
  d.motor_force = {};
  return 0;
}
int dhdStop(char id) {
  if (check(id) < 0) return -1;
  device().force_enabled = false;
  device().motor_force = {};
  return 0;
}
int dhdGetSystemType(char id) { return check(id) < 0 ? -1 : DHD_DEVICE_OMEGA3; }
const char* dhdGetSystemName(char id) { return check(id) < 0 ? nullptr : "omega.3 (fake)"; }
int dhdGetButton(int index, char id) {
  if (check(id) < 0) return -1;
  return index == 0 && device().button ? DHD_ON : DHD_OFF;
}
int dhdEnableForce(uchar val, char id) {
  if (check(id) < 0) return -1;
  device().force_enabled = val == DHD_ON;
  if (!device().force_enabled) device().motor_force = {};
  return 0;
}
int dhdSetGravityCompensation(int, char id) { return check(id); }
int dhdSetBrakes(int, char id) { return check(id); }
int dhdGetPosition(double* px, double* py, double* pz, char id) {
  if (check(id) < 0) return -1;
  const auto& d = device();
  *px = d.position_m[0];
  *py = d.position_m[1];
  *pz = d.position_m[2];
  return d.timeguard ? DHD_TIMEGUARD : 0;
}
int dhdGetLinearVelocity(double* vx, double* vy, double* vz, char id) {
  if (check(id) < 0) return -1;
  const auto& d = device();
  *vx = d.velocity_m_s[0];
  *vy = d.velocity_m_s[1];
  *vz = d.velocity_m_s[2];
  return 0;
}
int dhdGetForce(double* fx, double* fy, double* fz, char id) {
  if (check(id) < 0) return -1;
  const auto& d = device();
  *fx = d.motor_force[0];
  *fy = d.motor_force[1];
  *fz = d.motor_force[2];
  return 0;
}
// Renders the force while forces are enabled; beyond max_force it renders the largest force
// along the same direction and returns DHD_MOTOR_SATURATED.
int dhdSetForce(double fx, double fy, double fz, char id) {
  if (check(id) < 0) return -1;
  auto& d = device();
  conica::fake_sdk::Triple f{fx, fy, fz};
  int rc = 0;
  const double n = std::sqrt(fx * fx + fy * fy + fz * fz);
  if (n > d.max_force * (1 + 1e-12)) {
    for (double& c : f) c *= d.max_force / n;
    ++d.saturated;
    rc = DHD_MOTOR_SATURATED;
  }
  d.motor_force = d.force_enabled ? f : conica::fake_sdk::Triple{};
  d.motor_log.push_back(d.motor_force);
  return rc;
}
double dhdGetTime() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // extern "C"
