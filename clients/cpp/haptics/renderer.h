// The haptic renderer: from device motion and the server's (possibly late, lost or bad) replies
// to a force that is bounded, smooth and passive. Pure: no I/O, no clock, no allocation after
// construction; time comes in as arguments.
//
// Per servo tick (period dt) with device position x and velocity v (m, m/s, scene frame):
//  1. Local model from the latest reply (force F0 at probe position x0, stiffness K = dF/dx):
//       F_env(p) = F0 + Ks (p - x0)
//     Ks is K made symmetric with eigenvalues clamped to [-k_lim, 0] (an anti-spring, eigenvalue
//     > 0, is never rendered). Without coupling k_lim = k_max, the profile's stiffness, so the
//     device never feels more. With coupling the device feels at most kc <= k_max (below), and
//     the simulated probe uses the reply's stiffness up to k_lim = 100 k_max: an exact local
//     model makes the probe land on the equilibrium instead of oscillating around it.
//     interpolate = false renders F0 alone (zero-order hold). Replies with NaN / Inf are
//     rejected. With no reply for reply_timeout, the target force is zero (reached at the slew
//     limit, never as a step).
//  2. Virtual coupling: a massless simulated probe p joined to the device by a spring kc and a
//     damper bc, in static equilibrium with the local model:
//       kc (x - p) + F_env(p) = 0   =>   (kc I - Ks) p = kc x + F0 - Ks x0
//       F_target = kc (p - x) + bc (v_p - v),   v_p = (p - p_prev) / dt
//     The device feels the series stiffness kc k / (kc + k) < min(kc, k); kc defaults to k_max.
//     `probe_position()` is p: the position to send to the server. Without coupling p = x and
//     F_target = F_env(x).
//  3. Passivity observer / controller (Ryu and Hannaford, impedance form): the work the rendered
//     force has done on the device, booked exactly for a force held over each period,
//       W = sum_k F_{k-1} . (x_k - x_{k-1})        (J; W > 0: energy created by the renderer)
//     When W > 0, a damper alpha = min(b_max, W / (|v|^2 dt)) is added, F_target -= alpha v, to
//     dissipate it over the next period.
//  4. Rate (slew) clamp: |F_k - F_{k-1}| <= max_force_rate dt, then magnitude clamp
//     |F_k| <= max_force. Projection on the ball keeps the slew bound.
#pragma once

#include <cstdint>

#include "haptics/profile.h"

namespace conica::haptics {

// One server reply as the renderer needs it, SI, scene frame.
struct LocalModel {
  double t = 0;            // s, renderer clock when it arrived
  Vec3 x0 = Vec3::Zero();  // m, probe position the force belongs to
  Vec3 f0 = Vec3::Zero();  // N, force on the probe at x0
  Mat3 k = Mat3::Zero();   // N/m, d force / d position at x0
  bool contact = false;
};

struct RendererOptions {
  double dt = 1e-3;         // s, servo period
  bool interpolate = true;  // F0 + Ks (x - x0) between replies; false: hold F0
  bool coupling = true;
  double coupling_stiffness = 0;  // N/m; 0: the profile's max stiffness
  double coupling_damping = 0;    // N s/m
  bool passivity = true;          // observer + controller
  double max_pc_damping = 0;      // N s/m; 0: the profile's max damping
  double reply_timeout = 0.1;     // s without a reply before the force fades to zero
};

struct RendererStats {
  std::uint64_t ticks = 0;
  std::uint64_t replies = 0, rejected_replies = 0;  // rejected: non-finite values
  std::uint64_t stale_ticks = 0;                    // ticks rendered with no recent reply
  std::uint64_t force_clamped = 0, rate_clamped = 0;
  std::uint64_t stiffness_clamped = 0;  // replies stiffer than the profile's k_max
  std::uint64_t pc_active_ticks = 0;
  std::uint64_t bad_device_samples = 0;
  double device_work = 0;    // J, W above (after the controller)
  double pc_dissipated = 0;  // J, energy the controller's damping was asked to remove
};

class Renderer {
 public:
  Renderer(const DeviceProfile& profile, const RendererOptions& options);

  // Takes a reply; false (and counted) when it holds NaN / Inf.
  bool on_reply(const LocalModel& reply);
  // One servo tick at time t (s): returns the force to render (N, scene frame).
  Vec3 update(double t, const Vec3& x, const Vec3& v);

  // The simulated probe's position (m): what the server should be told.
  const Vec3& probe_position() const { return probe_; }
  const Vec3& last_force() const { return force_; }
  const RendererStats& stats() const { return stats_; }
  const DeviceProfile& profile() const { return profile_; }
  const RendererOptions& options() const { return options_; }
  double coupling_stiffness() const { return kc_; }
  // Ks of the current model (clamped, N/m): what the probe (coupling) or the device uses.
  const Mat3& model_stiffness() const { return options_.coupling ? ks_probe_ : ks_; }

  // Symmetric part of k with eigenvalues clamped to [-k_max, 0]; sets *clamped when it changed
  // anything beyond rounding.
  static Mat3 clamp_stiffness(const Mat3& k, double k_max, bool* clamped);

 private:
  DeviceProfile profile_;
  RendererOptions options_;
  double kc_, bc_, b_max_;
  LocalModel model_;
  Mat3 ks_ = Mat3::Zero(), ks_probe_ = Mat3::Zero();
  bool have_model_ = false, started_ = false;
  Vec3 x_prev_ = Vec3::Zero(), probe_ = Vec3::Zero(), force_ = Vec3::Zero();
  RendererStats stats_;
};

}  // namespace conica::haptics
