// The simulated hardware behind the stub SDK headers (sdk_stubs/include): one device per SDK,
// scripted by tests. Positions go in and committed forces come out in each SDK's native units
// and frame; the test side sees nothing of the conica backend. No threads: the OpenHaptics
// servo tick runs when a test calls hd::run_servo_ticks.
#pragma once

#include <array>
#include <string>
#include <vector>

namespace conica::fake_sdk {

using Triple = std::array<double, 3>;

// OpenHaptics HD (mm, mm/s, N; Y up, Z toward the user).
namespace hd {
struct Device {
  bool present = true;       // false: hdInitDevice fails with HD_COMM_ERROR
  bool initialised = false;  // between hdInitDevice and hdDisableDevice
  bool scheduler_running = false;
  bool force_output = false;        // HD_FORCE_OUTPUT
  bool max_force_clamping = false;  // HD_MAX_FORCE_CLAMPING
  double nominal_max_force = 3.3;   // N (a Touch)
  Triple position_mm{}, velocity_mm_s{};
  int buttons = 0;
  // The force hdEndFrame last sent to the motors (N, native frame); zero while force output
  // is off or the scheduler is stopped.
  Triple motor_force{};
  std::vector<Triple> motor_log;  // motor_force after every frame
  int frames = 0;
  int exceeded_max_force = 0;     // frames that asked for more than nominal_max_force
  int frame_errors = 0;           // begin/end out of order, state set outside a frame
  unsigned int inject_error = 0;  // an HD error code the next hdEndFrame reports (then cleared)
};
void reset();  // a fresh device, scheduler and error stack
Device& device();
// n ticks of the servo thread: each scheduled asynchronous callback runs once per tick, highest
// priority first; those returning HD_CALLBACK_DONE are removed. Returns the callbacks still
// scheduled.
int run_servo_ticks(int n = 1);
int scheduled();
}  // namespace hd

// Force Dimension DHD (m, m/s, N).
namespace dhd {
struct Device {
  int count = 1;  // devices on the bus; 0: dhdOpen fails with DHD_ERROR_NO_DEVICE_FOUND
  bool open = false;
  bool force_enabled = false;  // dhdEnableForce
  double max_force = 12.0;     // N (an omega.3); dhdSetForce saturates beyond
  Triple position_m{}, velocity_m_s{};
  bool button = false;
  bool timeguard = false;   // dhdGetPosition returns DHD_TIMEGUARD (a non-error) when set
  bool comm_error = false;  // position / force calls fail with DHD_ERROR_COM
  Triple motor_force{};     // N, what the device renders
  std::vector<Triple> motor_log;
  int saturated = 0;  // dhdSetForce calls beyond max_force
};
void reset();
Device& device();
}  // namespace dhd

// libnifalcon (m, N; x right, y up, z toward the user).
namespace falcon {
struct Device {
  int count = 1;
  bool open = false;
  bool firmware_loaded = false;  // survives close, as on the hardware until unplugged
  int firmware_uploads = 0, firmware_rejected = 0;
  int homing_loops = 3;  // I/O loops with homing mode on before all encoders report homed
  int homing_seen = 0;
  Triple position_m{};
  Triple motor_force{};  // N, applied only while homed
  std::vector<Triple> motor_log;
  int io_loops = 0;
};
void reset();
Device& device();
}  // namespace falcon

}  // namespace conica::fake_sdk
