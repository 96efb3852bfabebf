// A haptic device as the servo loop sees it: position and velocity in, force out, SI units in
// the scene frame. Backends convert units and frames at this edge (haptics/profile.h).
// Hardware backends are built into conica-haptic when their SDK was found at configure time;
// with CONICA_DEVICE_STUBS they are also built against stub SDK headers and a fake device
// library (haptics/sdk_stubs) for the tests.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "haptics/profile.h"

namespace conica::haptics {

struct DeviceSample {
  Vec3 position = Vec3::Zero();  // m, scene frame
  Vec3 velocity = Vec3::Zero();  // m/s
  bool button = false;
};

class Device {
 public:
  virtual ~Device() = default;
  virtual std::string name() const = 0;
  // Reads the state at servo time t (s since the loop started).
  virtual bool read(double t, DeviceSample* out) = 0;
  // Commands a force (N, scene frame) held until the next call.
  virtual void write_force(const Vec3& force) = 0;
  // Zero force, release the device.
  virtual void close() = 0;
  // Why the last read or write failed (SDK call and its message); empty while all is well.
  virtual std::string fault() const { return {}; }
};

// A scripted hand holding a device tip of mass m (kg) through a spring-damper (the hand's
// impedance); the tip also feels the rendered force and its own viscous friction:
//   m a = k_h (h(t) - x) + b_h (h'(t) - v) - b_d v + F
// integrated with semi-implicit Euler in `substeps` per servo period; F is held between writes.
// It keeps an exact account of the work F does on the tip: sum F . dx over substeps.
struct VirtualDeviceOptions {
  double mass = 0.1;            // kg
  double hand_stiffness = 300;  // N/m
  double hand_damping = 2;      // N s/m
  double friction = 0.01;       // N s/m, device viscous friction
  double dt = 1e-3;             // s, servo period (reads are expected every dt)
  int substeps = 20;
  // Hand target h(t) (m, scene frame); its velocity is taken by central difference.
  std::function<Vec3(double)> hand;
};

class VirtualDevice : public Device {
 public:
  explicit VirtualDevice(VirtualDeviceOptions options);
  std::string name() const override { return "virtual"; }
  bool read(double t, DeviceSample* out) override;
  void write_force(const Vec3& force) override { force_ = force; }
  void close() override { force_.setZero(); }

  double work_received() const { return work_; }  // J, by the rendered force on the tip
  const Vec3& position() const { return x_; }
  const Vec3& velocity() const { return v_; }

 private:
  VirtualDeviceOptions o_;
  Vec3 x_, v_ = Vec3::Zero(), force_ = Vec3::Zero();
  double t_ = 0, work_ = 0;
};

// Hand paths for the virtual device: `press` goes from `start` along `axis` by `depth` and back
// every `period` seconds (raised cosine); `hold` stays at start.
std::function<Vec3(double)> hand_press(const Vec3& start, const Vec3& axis, double depth,
                                       double period);

struct BackendInfo {
  std::string name;
  bool available = false;
  std::string devices;  // what it drives
  std::string units;    // native units / frame
  std::string enable;   // how to build it in when unavailable
};
std::vector<BackendInfo> device_backends();

// Opens a hardware backend by name (openhaptics, dhd, nifalcon); null with `error` when it is
// not built in or fails to open. The virtual device is made directly.
std::unique_ptr<Device> open_hardware(const std::string& backend, const DeviceFrame& frame,
                                      std::string* error);

}  // namespace conica::haptics
