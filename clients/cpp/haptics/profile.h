// What a haptic device can render, and how its native units and frame map to the scene's SI,
// Z-up frame. Conversions happen only at the device edge; everything inside is SI, scene frame.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "common/types.h"

namespace conica::haptics {

using client::Mat3;
using client::Vec3;

struct DeviceProfile {
  std::string name;
  double max_force = 0;       // N, continuous force the device may render
  double max_stiffness = 0;   // N/m, stable at a 1 kHz servo rate
  double max_force_rate = 0;  // N/s, slew limit (full force in 10 ms)
  double max_damping = 0;     // N s/m, the most damping the passivity controller may add
  double mass = 0;            // kg, apparent tip mass (used by the virtual device)
};

// touch (3D Systems Touch: 3.3 N, 400 N/m), omni (Phantom Omni: 3.3 N, 700 N/m), falcon (Novint
// Falcon: 8 N, 3000 N/m), omega (Force Dimension omega.x: 12 N, 5000 N/m). Force and stiffness
// from the field notes; slew rate, damping limit and tip mass are conservative estimates.
std::vector<DeviceProfile> device_profiles();
std::optional<DeviceProfile> find_profile(const std::string& name);

// A device's native frame and units: scene = offset + scale * R * (to_metres * native).
// Forces: native = R^T * scene (newtons in both; no scaling, so rendered work is not altered).
struct DeviceFrame {
  double to_metres = 1;              // native length unit in m (OpenHaptics: 1e-3)
  Mat3 rotation = Mat3::Identity();  // native axes -> scene axes
  Vec3 offset = Vec3::Zero();        // m, scene point of the device origin
  double scale = 1;                  // workspace scale (scene m per device m)
};

// OpenHaptics (Touch, Omni): mm, Y up, Z toward the user -> m, Z up: (x, y, z) -> (x, -z, y).
DeviceFrame openhaptics_frame();
// Force Dimension, CHAI3D, libnifalcon: already m and N; identity here (each SDK's own frame is
// Z-up or mapped by its backend).
DeviceFrame si_frame();

Vec3 to_scene_position(const DeviceFrame& f, const Vec3& native);
Vec3 to_scene_velocity(const DeviceFrame& f, const Vec3& native);
Vec3 to_native_position(const DeviceFrame& f, const Vec3& scene);
Vec3 to_native_force(const DeviceFrame& f, const Vec3& scene_force);
Vec3 to_scene_force(const DeviceFrame& f, const Vec3& native_force);

}  // namespace conica::haptics
