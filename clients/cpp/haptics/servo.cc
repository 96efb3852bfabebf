#include "haptics/servo.h"

#include <algorithm>
#include <limits>

namespace conica::haptics {

WallLink::WallLink(const Vec3& point, const Vec3& normal, double stiffness, int latency_ticks,
                   double dt)
    : point_(point),
      normal_(normal.normalized()),
      k_(stiffness),
      delay_(std::max(0, latency_ticks) * dt),
      ring_(static_cast<std::size_t>(latency_ticks) + 16) {}

void WallLink::send(double t, const Vec3& p) {
  if (t >= drop_from_ && t < drop_to_) {
    ++lost_;
    return;
  }
  if (count_ == ring_.size()) {  // full: the oldest reply is lost
    head_ = (head_ + 1) % ring_.size();
    --count_;
    ++lost_;
  }
  LocalModel& r = ring_[(head_ + count_) % ring_.size()];
  const double pen = -(p - point_).dot(normal_);
  r.t = t + delay_;
  r.x0 = p;
  r.contact = pen > 0;
  r.f0 = r.contact ? Vec3(k_ * pen * normal_) : Vec3::Zero();
  r.k = r.contact ? Mat3(-k_ * normal_ * normal_.transpose()) : Mat3::Zero();
  ++count_;
}

bool WallLink::poll(double t, LocalModel* out) {
  if (count_ == 0 || ring_[head_].t > t + 1e-9) return false;
  *out = ring_[head_];
  head_ = (head_ + 1) % ring_.size();
  --count_;
  return true;
}

ServoTick servo_tick(double t, Device& device, Renderer& renderer, ForceLink& link) {
  ServoTick s;
  s.device_ok = device.read(t, &s.device);
  LocalModel r;
  while (link.poll(t, &r)) {
    renderer.on_reply(r);
    ++s.replies;
  }
  const Vec3 nan = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
  s.force = s.device_ok ? renderer.update(t, s.device.position, s.device.velocity)
                        : renderer.update(t, nan, nan);
  device.write_force(s.force);
  s.probe = renderer.probe_position();
  link.send(t, s.probe);
  return s;
}

}  // namespace conica::haptics
