#include "haptics/profile.h"

namespace conica::haptics {

std::vector<DeviceProfile> device_profiles() {
  auto p = [](const char* name, double f, double k, double b, double m) {
    return DeviceProfile{name, f, k, f / 0.01, b, m};
  };
  return {
      p("touch", 3.3, 400, 2.0, 0.045),
      p("omni", 3.3, 700, 2.5, 0.045),
      p("falcon", 8.0, 3000, 10.0, 0.15),
      p("omega", 12.0, 5000, 20.0, 0.2),
  };
}

std::optional<DeviceProfile> find_profile(const std::string& name) {
  for (const auto& p : device_profiles())
    if (p.name == name) return p;
  return std::nullopt;
}

DeviceFrame openhaptics_frame() {
  DeviceFrame f;
  f.to_metres = 1e-3;
  // Columns are the native axes in scene coordinates: x -> x, y (up) -> z, z (toward user) -> -y.
  f.rotation << 1, 0, 0, 0, 0, -1, 0, 1, 0;
  return f;
}

DeviceFrame si_frame() { return DeviceFrame{}; }

Vec3 to_scene_position(const DeviceFrame& f, const Vec3& native) {
  return f.offset + f.scale * (f.rotation * (f.to_metres * native));
}
Vec3 to_scene_velocity(const DeviceFrame& f, const Vec3& native) {
  return f.scale * (f.rotation * (f.to_metres * native));
}
Vec3 to_native_position(const DeviceFrame& f, const Vec3& scene) {
  return f.rotation.transpose() * ((scene - f.offset) / f.scale) / f.to_metres;
}
Vec3 to_native_force(const DeviceFrame& f, const Vec3& scene_force) {
  return f.rotation.transpose() * scene_force;
}
Vec3 to_scene_force(const DeviceFrame& f, const Vec3& native_force) {
  return f.rotation * native_force;
}

}  // namespace conica::haptics
