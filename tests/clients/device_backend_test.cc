// The hardware backends of conica-haptic (haptics/backends.cc) built against the stub SDK headers
// and driven through the fake devices (haptics/sdk_stubs): device units and frames in, SI scene
// values out; scene forces in, native forces at the fake motors out; profile clamps; the servo
// loop against a wall, checked against the coupling law worked out by hand.
#include <HD/hd.h>
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "fake_devices.h"
#include "haptics/device.h"
#include "haptics/servo.h"

namespace conica::haptics {
namespace {

namespace fake = conica::fake_sdk;

Vec3 v3(const fake::Triple& t) { return Vec3(t[0], t[1], t[2]); }

// The Falcon's frame: metres, x right, y up, z toward the user (the OpenHaptics axes).
DeviceFrame falcon_frame() {
  DeviceFrame f = si_frame();
  f.rotation = openhaptics_frame().rotation;
  return f;
}

class Backends : public ::testing::Test {
 protected:
  void SetUp() override {
    fake::hd::reset();
    fake::dhd::reset();
    fake::falcon::reset();
  }
};

// ---- OpenHaptics HD --------------------------------------------------------------------------

TEST_F(Backends, OpenHapticsReportsTheSdkErrorWhenNoDeviceAnswers) {
  fake::hd::device().present = false;
  std::string error;
  EXPECT_EQ(open_hardware("openhaptics", openhaptics_frame(), &error), nullptr);
  EXPECT_NE(error.find("hdInitDevice"), std::string::npos) << error;
  EXPECT_NE(error.find("communication error"), std::string::npos) << error;
}

TEST_F(Backends, OpenHapticsMillimetresYUpToSceneMetresZUp) {
  DeviceFrame frame = openhaptics_frame();
  frame.offset = Vec3(0.02, 0.02, 0.045);
  std::string error;
  auto dev = open_hardware("openhaptics", frame, &error);
  ASSERT_NE(dev, nullptr) << error;
  EXPECT_TRUE(fake::hd::device().force_output);
  EXPECT_TRUE(fake::hd::device().scheduler_running);
  EXPECT_EQ(fake::hd::scheduled(), 1);

  DeviceSample s;
  EXPECT_FALSE(dev->read(0, &s)) << "no servo frame has run yet";
  // 10 mm right, 20 mm up, 30 mm toward the user; moving up at 100 mm/s; button 1 down.
  fake::hd::device().position_mm = {10, 20, 30};
  fake::hd::device().velocity_mm_s = {0, 100, 0};
  fake::hd::device().buttons = HD_DEVICE_BUTTON_1;
  fake::hd::run_servo_ticks(1);
  ASSERT_TRUE(dev->read(1e-3, &s));
  // Scene: x right, y away from the user, z up, metres, from the offset.
  EXPECT_LT((s.position - Vec3(0.02 + 0.010, 0.02 - 0.030, 0.045 + 0.020)).norm(), 1e-15);
  EXPECT_LT((s.velocity - Vec3(0, 0, 0.1)).norm(), 1e-15);
  EXPECT_TRUE(s.button);

  // Scene force (0.5 right, 1.0 toward the user, 2.5 up) N -> native (x 0.5, y up 2.5, z 1.0).
  dev->write_force(Vec3(0.5, -1.0, 2.5));
  EXPECT_LT(v3(fake::hd::device().motor_force).norm(), 1e-15) << "sent only by the next frame";
  fake::hd::run_servo_ticks(1);
  EXPECT_LT((v3(fake::hd::device().motor_force) - Vec3(0.5, 2.5, 1.0)).norm(), 1e-15);
  EXPECT_EQ(fake::hd::device().frame_errors, 0);
  EXPECT_EQ(dev->fault(), "");

  dev->close();
  EXPECT_LT(v3(fake::hd::device().motor_force).norm(), 1e-15);
  EXPECT_LT(v3(fake::hd::device().motor_log.back()).norm(), 1e-15) << "a zero frame was sent";
  EXPECT_FALSE(fake::hd::device().scheduler_running);
  EXPECT_FALSE(fake::hd::device().initialised);
  EXPECT_EQ(fake::hd::scheduled(), 0);
}

TEST_F(Backends, OpenHapticsDeviceFaultStopsTheServoCallbackAndSaysWhy) {
  std::string error;
  auto dev = open_hardware("openhaptics", openhaptics_frame(), &error);
  ASSERT_NE(dev, nullptr) << error;
  fake::hd::run_servo_ticks(1);
  DeviceSample s;
  ASSERT_TRUE(dev->read(0, &s));
  fake::hd::device().inject_error = HD_COMM_ERROR;
  EXPECT_EQ(fake::hd::run_servo_ticks(1), 0) << "the callback ended itself";
  EXPECT_FALSE(dev->read(1e-3, &s));
  EXPECT_NE(dev->fault().find("communication error"), std::string::npos) << dev->fault();
}

// ---- Force Dimension DHD ---------------------------------------------------------------------

TEST_F(Backends, DhdReportsTheSdkErrorWhenNoDeviceIsFound) {
  fake::dhd::device().count = 0;
  std::string error;
  EXPECT_EQ(open_hardware("dhd", si_frame(), &error), nullptr);
  EXPECT_EQ(error, "dhdOpen: no compatible Force Dimension device found");
}

TEST_F(Backends, DhdMetresWithWorkspaceOffsetAndScale) {
  DeviceFrame frame = si_frame();
  frame.offset = Vec3(0.02, 0.02, 0.045);
  frame.scale = 0.5;
  std::string error;
  auto dev = open_hardware("dhd", frame, &error);
  ASSERT_NE(dev, nullptr) << error;
  EXPECT_TRUE(fake::dhd::device().force_enabled);
  fake::dhd::device().position_m = {0.1, -0.04, 0.06};
  fake::dhd::device().velocity_m_s = {0.2, 0, -0.1};
  fake::dhd::device().timeguard = true;  // DHD_TIMEGUARD is a success, not an error
  DeviceSample s;
  ASSERT_TRUE(dev->read(0, &s)) << dev->fault();
  EXPECT_LT((s.position - Vec3(0.02 + 0.05, 0.02 - 0.02, 0.045 + 0.03)).norm(), 1e-15);
  EXPECT_LT((s.velocity - Vec3(0.1, 0, -0.05)).norm(), 1e-15);
  // Forces are not scaled (rendered work is not altered by the workspace scale).
  dev->write_force(Vec3(1.5, -2.0, 3.0));
  EXPECT_LT((v3(fake::dhd::device().motor_force) - Vec3(1.5, -2.0, 3.0)).norm(), 1e-15);
  EXPECT_EQ(fake::dhd::device().saturated, 0);

  fake::dhd::device().comm_error = true;
  EXPECT_FALSE(dev->read(1e-3, &s));
  EXPECT_EQ(dev->fault(), "dhdGetPosition: communication error between the host and the device");
  fake::dhd::device().comm_error = false;
  dev->close();
  EXPECT_FALSE(fake::dhd::device().open);
  EXPECT_LT(v3(fake::dhd::device().motor_force).norm(), 1e-15);
}

// ---- libnifalcon -----------------------------------------------------------------------------

TEST_F(Backends, FalconLoadsTheNventFirmwareWhenTheDeviceHasNone) {
  std::string error;
  auto dev = open_hardware("nifalcon", falcon_frame(), &error);
  ASSERT_NE(dev, nullptr) << error;
  EXPECT_EQ(fake::falcon::device().firmware_uploads, 1);
  EXPECT_EQ(fake::falcon::device().firmware_rejected, 0);
  dev->close();
  dev.reset();
  // Still loaded: the second open does not upload again.
  dev = open_hardware("nifalcon", falcon_frame(), &error);
  ASSERT_NE(dev, nullptr) << error;
  EXPECT_EQ(fake::falcon::device().firmware_uploads, 1);
}

TEST_F(Backends, FalconNoDevice) {
  fake::falcon::device().count = 0;
  std::string error;
  EXPECT_EQ(open_hardware("nifalcon", falcon_frame(), &error), nullptr);
  EXPECT_EQ(error, "libnifalcon: no Novint Falcon found");
}

TEST_F(Backends, FalconWaitsForHomingThenConvertsItsFrame) {
  fake::falcon::device().homing_loops = 3;
  std::string error;
  auto dev = open_hardware("nifalcon", falcon_frame(), &error);
  ASSERT_NE(dev, nullptr) << error;
  fake::falcon::device().position_m = {0.01, 0.02, 0.03};
  DeviceSample s;
  EXPECT_FALSE(dev->read(0.000, &s));
  EXPECT_NE(dev->fault().find("not homed"), std::string::npos) << dev->fault();
  EXPECT_FALSE(dev->read(0.001, &s));
  ASSERT_TRUE(dev->read(0.002, &s)) << dev->fault();  // third packet with homing mode on
  EXPECT_LT((s.position - Vec3(0.01, -0.03, 0.02)).norm(), 1e-15);
  EXPECT_LT(s.velocity.norm(), 1e-15);
  fake::falcon::device().position_m = {0.01, 0.02, 0.031};  // 1 mm toward the user in 1 ms
  ASSERT_TRUE(dev->read(0.003, &s));
  EXPECT_LT((s.velocity - Vec3(0, -1.0, 0)).norm(), 1e-9);
  // 2 N up in the scene is +y for the Falcon, sent with the next I/O loop.
  dev->write_force(Vec3(0, 0, 2));
  EXPECT_LT(v3(fake::falcon::device().motor_force).norm(), 1e-15);
  ASSERT_TRUE(dev->read(0.004, &s));
  EXPECT_LT((v3(fake::falcon::device().motor_force) - Vec3(0, 2, 0)).norm(), 1e-15);
  dev->close();
  EXPECT_FALSE(fake::falcon::device().open);
  EXPECT_LT(v3(fake::falcon::device().motor_force).norm(), 1e-15);
}

// ---- The servo loop through each fake SDK ----------------------------------------------------

struct Rig {
  std::string backend, profile;
  DeviceFrame frame;
  // Native units per metre of scene length along the frame's axes (1000 for HD's mm).
  double native_per_m;
};

Rig rig(const std::string& backend) {
  if (backend == "openhaptics") return {backend, "touch", openhaptics_frame(), 1e3};
  if (backend == "dhd") return {backend, "omega", si_frame(), 1};
  return {backend, "falcon", falcon_frame(), 1};
}

// Puts the fake device's tip at scene height z (m) above the wall, x = y = 0, moving at vz.
void place(const std::string& backend, double z, double vz) {
  if (backend == "openhaptics") {  // native y is up, mm
    fake::hd::device().position_mm = {0, z * 1e3, 0};
    fake::hd::device().velocity_mm_s = {0, vz * 1e3, 0};
  } else if (backend == "dhd") {  // native z is up, m
    fake::dhd::device().position_m = {0, 0, z};
    fake::dhd::device().velocity_m_s = {0, 0, vz};
  } else {  // Falcon: native y is up, m
    fake::falcon::device().position_m = {0, z, 0};
  }
}
// The force at the fake device's motors, native frame, N.
Vec3 motor_force(const std::string& backend) {
  if (backend == "openhaptics") return v3(fake::hd::device().motor_force);
  if (backend == "dhd") return v3(fake::dhd::device().motor_force);
  return v3(fake::falcon::device().motor_force);
}
const std::vector<fake::Triple>& motor_log(const std::string& backend) {
  if (backend == "openhaptics") return fake::hd::device().motor_log;
  if (backend == "dhd") return fake::dhd::device().motor_log;
  return fake::falcon::device().motor_log;
}
// The native direction of scene +z (up): +y for HD and the Falcon, +z for DHD.
Vec3 native_up(const std::string& backend) {
  return backend == "dhd" ? Vec3(0, 0, 1) : Vec3(0, 1, 0);
}

struct PressResult {
  Vec3 motor_force, probe;
  double max_step = 0;  // N, largest change of the motor force from one tick to the next
  std::string fault;
};

// The tip descends from 5 mm above a wall (scene z = 0, normal +z, stiffness k_wall N/m,
// replies 2 ticks late) to `depth` below it in `descend` ticks (0: it starts there), then is
// held; 1000 ticks of 1 ms in all.
PressResult press(const Rig& r, double k_wall, double depth, int descend = 300) {
  const double dt = 1e-3;
  std::string error;
  auto dev = open_hardware(r.backend, r.frame, &error);
  EXPECT_NE(dev, nullptr) << error;
  if (!dev) return {};
  RendererOptions ro;
  ro.dt = dt;
  Renderer renderer(*find_profile(r.profile), ro);
  WallLink wall(Vec3::Zero(), Vec3(0, 0, 1), k_wall, 2, dt);
  PressResult out;
  const int total = 1000;
  for (int k = 0; k < total; ++k) {
    const double s = descend > 0 ? std::min(1.0, double(k) / descend) : 1.0;
    const double z = 0.005 - s * (0.005 + depth);
    place(r.backend, z, k < descend ? -(0.005 + depth) / (descend * dt) : 0.0);
    if (r.backend == "openhaptics") fake::hd::run_servo_ticks(1);
    if (r.backend == "nifalcon" && k == 0)
      for (int i = 0; i < 3; ++i) {  // homing: three packets with homing mode on
        DeviceSample ignored;
        dev->read(0, &ignored);
      }
    const ServoTick t = servo_tick(k * dt, *dev, renderer, wall);
    EXPECT_TRUE(t.device_ok) << r.backend << " tick " << k << ": " << dev->fault();
    out.probe = t.probe;
  }
  // One more device cycle sends the last force to the motors (HD frame, Falcon I/O loop).
  if (r.backend == "openhaptics") fake::hd::run_servo_ticks(1);
  if (r.backend == "nifalcon") {
    DeviceSample ignored;
    dev->read(total * dt, &ignored);
  }
  out.motor_force = motor_force(r.backend);
  const auto& log = motor_log(r.backend);
  for (std::size_t i = 1; i < log.size(); ++i)
    out.max_step = std::max(out.max_step, (v3(log[i]) - v3(log[i - 1])).norm());
  out.fault = dev->fault();
  dev->close();
  return out;
}

class ServoThroughSdk : public Backends, public ::testing::WithParamInterface<const char*> {};

// Held `d` inside a wall of stiffness k_w through a coupling spring kc (the profile's max
// stiffness), the probe settles where kc (x - p) + k_w (0 - p) = 0 along the normal:
//   p = kc x / (kc + k_w),   F = kc (p - x) = kc k_w d / (kc + k_w)  (up, out of the wall).
TEST_P(ServoThroughSdk, HeldPressRendersTheSeriesCouplingForce) {
  const Rig r = rig(GetParam());
  const double kc = find_profile(r.profile)->max_stiffness;
  const double k_wall = 3 * kc, depth = 0.002;
  const PressResult p = press(r, k_wall, depth);
  const double f_expected = kc * k_wall * depth / (kc + k_wall);
  ASSERT_LT(f_expected, find_profile(r.profile)->max_force) << "the test must not clamp";
  EXPECT_LT((p.motor_force - f_expected * native_up(r.backend)).norm(), 1e-9 * f_expected)
      << r.backend << ": " << p.motor_force.transpose() << " vs " << f_expected;
  const double probe_z = kc * -depth / (kc + k_wall);
  EXPECT_LT((p.probe - Vec3(0, 0, probe_z)).norm(), 1e-12) << p.probe.transpose();
  EXPECT_EQ(p.fault, "");
  if (r.backend == "openhaptics") {
    EXPECT_EQ(fake::hd::device().exceeded_max_force, 0);
  }
  if (r.backend == "dhd") {
    EXPECT_EQ(fake::dhd::device().saturated, 0);
  }
}

// Pressed far in, the force reaches the profile's limit and no more; the device's own limit is
// never hit (touch 3.3 N on a 3.3 N Touch, omega 12 N on a 12 N omega.3).
TEST_P(ServoThroughSdk, DeepPressIsClampedToTheProfile) {
  const Rig r = rig(GetParam());
  const DeviceProfile prof = *find_profile(r.profile);
  const double kc = prof.max_stiffness, k_wall = 10 * kc, depth = 0.03;
  ASSERT_GT(kc * k_wall * depth / (kc + k_wall), 2 * prof.max_force);
  const PressResult p = press(r, k_wall, depth);
  EXPECT_NEAR(p.motor_force.norm(), prof.max_force, 1e-9) << r.backend;
  EXPECT_LT((p.motor_force.normalized() - native_up(r.backend)).norm(), 1e-9);
  EXPECT_LE(p.max_step, prof.max_force * 1e-3 / 0.01 * (1 + 1e-9)) << r.backend;
  if (r.backend == "openhaptics") {
    EXPECT_EQ(fake::hd::device().exceeded_max_force, 0);
  }
  if (r.backend == "dhd") {
    EXPECT_EQ(fake::dhd::device().saturated, 0);
  }
}

// Started 3 cm inside a stiff wall, the force rises at the profile's slew limit, the full force
// in 10 ms: steps of max_force / 10 per 1 ms tick at the motors, reaching max_force.
TEST_P(ServoThroughSdk, StepIntoTheWallRisesAtTheProfileSlewRate) {
  const Rig r = rig(GetParam());
  const DeviceProfile prof = *find_profile(r.profile);
  const PressResult p = press(r, 10 * prof.max_stiffness, 0.03, 0);
  EXPECT_NEAR(p.max_step, prof.max_force / 10, 1e-9 * prof.max_force) << r.backend;
  EXPECT_NEAR(p.motor_force.norm(), prof.max_force, 1e-9) << r.backend;
  const auto& log = motor_log(r.backend);
  int ramp = 0;  // frames with a force strictly between zero and the limit
  for (const auto& f : log)
    if (v3(f).norm() > 1e-9 && v3(f).norm() < prof.max_force * (1 - 1e-9)) ++ramp;
  EXPECT_EQ(ramp, 9) << r.backend << ": 0.1, 0.2, ..., 0.9 of the limit, then the limit";
}

INSTANTIATE_TEST_SUITE_P(EveryBackend, ServoThroughSdk,
                         ::testing::Values("openhaptics", "dhd", "nifalcon"));

// The profile is what keeps the device inside its limits: the omega profile (12 N) on a Touch
// (3.3 N) makes the HD device refuse frames, and the backend says so.
TEST_F(Backends, WrongProfileExceedsTheTouchAndTheBackendReportsIt) {
  Rig r = rig("openhaptics");
  r.profile = "omega";
  const PressResult p = press(r, 50000, 0.03);
  EXPECT_GT(fake::hd::device().exceeded_max_force, 0);
  EXPECT_NE(p.fault.find("exceeded"), std::string::npos) << p.fault;
}

TEST_F(Backends, StubBuildListsEveryBackendAsAvailable) {
  for (const auto& b : device_backends()) {
    EXPECT_TRUE(b.available) << b.name;
    if (b.name != "virtual") {
      EXPECT_NE(b.devices.find("stub SDK"), std::string::npos) << b.name;
    }
  }
}

}  // namespace
}  // namespace conica::haptics
