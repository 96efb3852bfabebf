// The servo loop's tick, independent of the transport: read the device, take the replies that
// have arrived, render, command the force, send the simulated probe's position.
// The network link is a ForceLink (the ZeroMQ one lives in the program; WallLink below is an
// in-process environment for tests and offline runs).
#pragma once

#include <cstddef>
#include <vector>

#include "haptics/device.h"
#include "haptics/renderer.h"

namespace conica::haptics {

class ForceLink {
 public:
  virtual ~ForceLink() = default;
  // Sends the simulated probe position (m, scene frame) at servo time t (s).
  virtual void send(double t, const Vec3& probe_position) = 0;
  // The next reply that has arrived by time t (its .t is the arrival time); false when none.
  virtual bool poll(double t, LocalModel* out) = 0;
};

// A stiff wall: the half-space (p - point) . normal < 0 pushes a probe centre p out with
//   F = k pen normal,  pen = max(0, -(p - point) . normal),  dF/dp = -k normal normal^T (in
//   contact)
// Each send is answered `latency_ticks` servo periods later; replies to sends in the window
// [drop_from, drop_to) (s) are lost. Capacity is fixed at construction.
class WallLink : public ForceLink {
 public:
  WallLink(const Vec3& point, const Vec3& normal, double stiffness, int latency_ticks, double dt);
  void send(double t, const Vec3& probe_position) override;
  bool poll(double t, LocalModel* out) override;
  void set_drop(double from, double to) {
    drop_from_ = from;
    drop_to_ = to;
  }
  std::size_t lost() const { return lost_; }

 private:
  Vec3 point_, normal_;
  double k_, delay_, drop_from_ = 0, drop_to_ = 0;
  std::vector<LocalModel> ring_;
  std::size_t head_ = 0, count_ = 0, lost_ = 0;
};

struct ServoTick {
  DeviceSample device;
  Vec3 force = Vec3::Zero();  // N, commanded
  Vec3 probe = Vec3::Zero();  // m, sent to the server
  int replies = 0;            // taken this tick
  bool device_ok = true;
};

// One tick at servo time t (s).
ServoTick servo_tick(double t, Device& device, Renderer& renderer, ForceLink& link);

}  // namespace conica::haptics
