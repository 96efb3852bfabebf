#include "haptics/renderer.h"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>

namespace conica::haptics {

namespace {
bool finite(const Vec3& v) { return v.allFinite(); }
}  // namespace

Renderer::Renderer(const DeviceProfile& profile, const RendererOptions& options)
    : profile_(profile), options_(options) {
  kc_ = options.coupling_stiffness > 0 ? options.coupling_stiffness : profile.max_stiffness;
  bc_ = std::max(0.0, options.coupling_damping);
  b_max_ = options.max_pc_damping > 0 ? options.max_pc_damping : profile.max_damping;
}

Mat3 Renderer::clamp_stiffness(const Mat3& k, double k_max, bool* clamped) {
  const Mat3 s = 0.5 * (k + k.transpose());
  Eigen::SelfAdjointEigenSolver<Mat3> eig(s);
  Eigen::Vector3d lambda = eig.eigenvalues();
  const Eigen::Vector3d clamped_lambda = lambda.cwiseMax(-k_max).cwiseMin(0.0);
  const double tol = 1e-9 * std::max(1.0, lambda.cwiseAbs().maxCoeff());
  *clamped = (clamped_lambda - lambda).cwiseAbs().maxCoeff() > tol;
  return eig.eigenvectors() * clamped_lambda.asDiagonal() * eig.eigenvectors().transpose();
}

bool Renderer::on_reply(const LocalModel& r) {
  if (!finite(r.x0) || !finite(r.f0) || !r.k.allFinite() || !std::isfinite(r.t)) {
    ++stats_.rejected_replies;
    return false;
  }
  bool clamped = false;
  ks_ = clamp_stiffness(r.k, profile_.max_stiffness, &clamped);
  if (clamped) ++stats_.stiffness_clamped;
  bool probe_clamped = false;
  ks_probe_ = clamp_stiffness(r.k, 100 * profile_.max_stiffness, &probe_clamped);
  model_ = r;
  have_model_ = true;
  ++stats_.replies;
  return true;
}

Vec3 Renderer::update(double t, const Vec3& x, const Vec3& v) {
  const double dt = options_.dt;
  ++stats_.ticks;
  Vec3 target = Vec3::Zero();
  const bool device_ok = finite(x) && finite(v);
  if (!device_ok) {
    ++stats_.bad_device_samples;  // render towards zero; keep the last good pose
  } else {
    if (!started_) {
      x_prev_ = probe_ = x;
      started_ = true;
    }
    // 3 (booking first): work of the force held over the last period on the device.
    stats_.device_work += force_.dot(x - x_prev_);
    x_prev_ = x;

    // 1, 2: local model and virtual coupling.
    const bool fresh = have_model_ && t - model_.t <= options_.reply_timeout;
    if (!fresh) ++stats_.stale_ticks;
    const Mat3 ks = (fresh && options_.interpolate) ? model_stiffness() : Mat3::Zero();
    const Vec3 f0 = fresh ? model_.f0 : Vec3::Zero();
    const Vec3 x0 = fresh ? model_.x0 : x;
    const Vec3 p_prev = probe_;
    if (options_.coupling) {
      const Mat3 a = kc_ * Mat3::Identity() - ks;  // eigenvalues >= kc > 0
      probe_ = a.inverse() * (kc_ * x + f0 - ks * x0);
      const Vec3 vp = (probe_ - p_prev) / dt;
      target = kc_ * (probe_ - x) + bc_ * (vp - v);
    } else {
      probe_ = x;
      target = f0 + ks * (x - x0);
    }

    // 3: passivity controller.
    const double v2 = v.squaredNorm();
    if (options_.passivity && stats_.device_work > 0 && v2 > 1e-12) {
      const double alpha = std::min(b_max_, stats_.device_work / (v2 * dt));
      target -= alpha * v;
      stats_.pc_dissipated += alpha * v2 * dt;
      ++stats_.pc_active_ticks;
    }
  }

  // 4: slew, then magnitude.
  Vec3 step = target - force_;
  const double max_step = profile_.max_force_rate * dt;
  if (step.norm() > max_step) {
    step *= max_step / step.norm();
    ++stats_.rate_clamped;
  }
  Vec3 f = force_ + step;
  const double n = f.norm();
  if (n > profile_.max_force) {
    f *= profile_.max_force / n;
    ++stats_.force_clamped;
  }
  force_ = f;
  return f;
}

}  // namespace conica::haptics
