#include "haptics/device.h"

#include <cmath>

namespace conica::haptics {

VirtualDevice::VirtualDevice(VirtualDeviceOptions options) : o_(std::move(options)) {
  if (!o_.hand) o_.hand = [](double) { return Vec3::Zero(); };
  x_ = o_.hand(0);
}

bool VirtualDevice::read(double t, DeviceSample* out) {
  const int n = std::max(1, o_.substeps);
  const double span = t - t_;
  if (span > 0) {
    const double h = span / n;
    for (int i = 0; i < n; ++i) {
      const double ts = t_ + (i + 1) * h;
      const double e = 1e-4;
      const Vec3 hp = o_.hand(ts);
      const Vec3 hv = (o_.hand(ts + e) - o_.hand(ts - e)) / (2 * e);
      const Vec3 a = (o_.hand_stiffness * (hp - x_) + o_.hand_damping * (hv - v_) -
                      o_.friction * v_ + force_) /
                     o_.mass;
      v_ += h * a;
      const Vec3 dx = h * v_;
      work_ += force_.dot(dx);
      x_ += dx;
    }
    t_ = t;
  }
  out->position = x_;
  out->velocity = v_;
  out->button = false;
  return true;
}

std::function<Vec3(double)> hand_press(const Vec3& start, const Vec3& axis, double depth,
                                       double period) {
  const Vec3 a = axis.normalized();
  return [=](double t) {
    const double d = period > 0 ? 0.5 * depth * (1 - std::cos(2 * M_PI * t / period)) : 0.0;
    return Vec3(start + d * a);
  };
}

}  // namespace conica::haptics
