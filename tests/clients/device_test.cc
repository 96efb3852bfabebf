// Device frames and units at the edge, and the virtual device's mechanics.
#include "haptics/device.h"

#include <gtest/gtest.h>

#include <Eigen/LU>

namespace conica::haptics {
namespace {

TEST(DeviceFrame, OpenHapticsMillimetresYUpToMetresZUp) {
  const DeviceFrame f = openhaptics_frame();
  // Native (mm): 10 right, 20 up, 30 toward the user -> scene (m): x right, z up, y away.
  const Vec3 s = to_scene_position(f, Vec3(10, 20, 30));
  EXPECT_NEAR(s.x(), 0.010, 1e-15);
  EXPECT_NEAR(s.y(), -0.030, 1e-15);
  EXPECT_NEAR(s.z(), 0.020, 1e-15);
  // Force up in the scene is +Y for the device, newtons unchanged.
  const Vec3 fn = to_native_force(f, Vec3(0, 0, 2.5));
  EXPECT_NEAR((fn - Vec3(0, 2.5, 0)).norm(), 0, 1e-15);
  EXPECT_NEAR(f.rotation.determinant(), 1.0, 1e-15);  // a rotation, not a mirror
  // Velocity: mm/s -> m/s.
  EXPECT_NEAR((to_scene_velocity(f, Vec3(0, 100, 0)) - Vec3(0, 0, 0.1)).norm(), 0, 1e-15);
}

TEST(DeviceFrame, RoundTripsWithOffsetAndScale) {
  DeviceFrame f = openhaptics_frame();
  f.offset = Vec3(0.02, 0.02, 0.045);
  f.scale = 0.5;
  for (const Vec3& native : {Vec3(0, 0, 0), Vec3(-120.5, 33.25, 88), Vec3(1e-3, -2e-3, 3e-3)}) {
    const Vec3 back = to_native_position(f, to_scene_position(f, native));
    EXPECT_LT((back - native).norm(), 1e-12 * (1 + native.norm()));
  }
  const Vec3 force(0.3, -1.2, 2.0);
  EXPECT_LT((to_scene_force(f, to_native_force(f, force)) - force).norm(), 1e-15);
  // The device origin lands on the offset; 100 mm up lands 50 mm above it.
  EXPECT_LT((to_scene_position(f, Vec3(0, 100, 0)) - Vec3(0.02, 0.02, 0.095)).norm(), 1e-15);
}

TEST(DeviceFrame, SiFrameIsIdentity) {
  const DeviceFrame f = si_frame();
  EXPECT_LT((to_scene_position(f, Vec3(0.1, 0.2, 0.3)) - Vec3(0.1, 0.2, 0.3)).norm(), 1e-15);
}

TEST(VirtualDevice, FollowsTheHandAndRespondsToForce) {
  VirtualDeviceOptions o;
  o.mass = 0.1;
  o.hand_stiffness = 300;
  o.hand_damping = 5;
  o.hand = [](double) { return Vec3(0, 0, 0.01); };
  VirtualDevice d(o);
  DeviceSample s;
  d.write_force(Vec3(0, 0, -1.5));  // pushes down against the hand spring
  for (int i = 1; i <= 3000; ++i) d.read(i * 1e-3, &s);
  // Static equilibrium: k_h (h - x) = 1.5 N  ->  x = h - 5 mm.
  EXPECT_NEAR(s.position.z(), 0.01 - 1.5 / 300, 1e-6);
  EXPECT_NEAR(s.velocity.norm(), 0, 1e-6);
  // Work of a constant force over the displacement: F . dx = 1.5 N * 5 mm.
  EXPECT_NEAR(d.work_received(), 1.5 * 0.005, 1e-6);
}

TEST(Backends, VirtualAlwaysExistsAndHardwareSaysHowToEnable) {
  const auto b = device_backends();
  ASSERT_GE(b.size(), 4u);
  EXPECT_EQ(b[0].name, "virtual");
  EXPECT_TRUE(b[0].available);
  for (const auto& x : b)
    if (!x.available) {
      EXPECT_FALSE(x.enable.empty()) << x.name;
    }
  std::string error;
  EXPECT_EQ(open_hardware("nonesuch", si_frame(), &error), nullptr);
  EXPECT_NE(error.find("unknown"), std::string::npos);
}

}  // namespace
}  // namespace conica::haptics
