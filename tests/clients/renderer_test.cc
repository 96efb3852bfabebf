// The haptic renderer on its own: force and rate bounds, stiffness clamping, interpolation,
// coupling, continuity through lost replies, and passivity on the virtual device.
#include "haptics/renderer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "haptics/device.h"
#include "haptics/servo.h"

namespace conica::haptics {
namespace {

constexpr double kDt = 1e-3;

DeviceProfile profile(const char* name) {
  auto p = find_profile(name);
  EXPECT_TRUE(p.has_value()) << name;
  return *p;
}

LocalModel reply(double t, const Vec3& x0, const Vec3& f0, const Mat3& k) {
  LocalModel r;
  r.t = t;
  r.x0 = x0;
  r.f0 = f0;
  r.k = k;
  r.contact = f0.norm() > 0;
  return r;
}

TEST(Profiles, MatchTheDeviceTable) {
  EXPECT_DOUBLE_EQ(profile("touch").max_force, 3.3);
  EXPECT_DOUBLE_EQ(profile("touch").max_stiffness, 400);
  EXPECT_DOUBLE_EQ(profile("omni").max_stiffness, 700);
  EXPECT_DOUBLE_EQ(profile("falcon").max_force, 8);
  EXPECT_DOUBLE_EQ(profile("falcon").max_stiffness, 3000);
  EXPECT_DOUBLE_EQ(profile("omega").max_force, 12);
  EXPECT_DOUBLE_EQ(profile("omega").max_stiffness, 5000);
  EXPECT_FALSE(find_profile("nonesuch").has_value());
}

TEST(Renderer, NeverExceedsTheProfileForceOnRandomInput) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  std::uniform_real_distribution<double> logk(0, 9);  // stiffness up to 1e9 N/m
  for (const auto& prof : device_profiles()) {
    for (bool coupling : {true, false}) {
      RendererOptions o;
      o.coupling = coupling;
      Renderer r(prof, o);
      double worst = 0, worst_step = 0;
      Vec3 prev = Vec3::Zero();
      for (int i = 0; i < 20000; ++i) {
        const double t = i * kDt;
        if (i % 3 == 0) {
          Mat3 k;
          for (int j = 0; j < 9; ++j) k(j / 3, j % 3) = u(rng) * std::pow(10.0, logk(rng));
          r.on_reply(
              reply(t, 0.05 * Vec3(u(rng), u(rng), u(rng)), 1e4 * Vec3(u(rng), u(rng), u(rng)), k));
        }
        const Vec3 f =
            r.update(t, 0.1 * Vec3(u(rng), u(rng), u(rng)), 10 * Vec3(u(rng), u(rng), u(rng)));
        ASSERT_TRUE(f.allFinite());
        worst = std::max(worst, f.norm());
        worst_step = std::max(worst_step, (f - prev).norm());
        prev = f;
      }
      EXPECT_LE(worst, prof.max_force * (1 + 1e-12)) << prof.name;
      EXPECT_GT(worst, 0.99 * prof.max_force) << prof.name << ": the clamp was never reached";
      EXPECT_LE(worst_step, prof.max_force_rate * kDt * (1 + 1e-9)) << prof.name;
      EXPECT_GT(r.stats().force_clamped, 0u);
      EXPECT_GT(r.stats().stiffness_clamped, 0u);
    }
  }
}

TEST(Renderer, RejectsNonFiniteReplies) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  RendererOptions o;
  o.coupling = false;
  o.passivity = false;
  Renderer r(profile("falcon"), o);
  const Vec3 x(0, 0, 0.01);
  ASSERT_TRUE(r.on_reply(reply(0, x, Vec3(0, 0, 1), Mat3::Zero())));
  EXPECT_FALSE(r.on_reply(reply(0, x, Vec3(0, 0, nan), Mat3::Zero())));
  EXPECT_FALSE(r.on_reply(reply(0, Vec3(inf, 0, 0), Vec3(0, 0, 1), Mat3::Zero())));
  Mat3 k = Mat3::Zero();
  k(1, 2) = nan;
  EXPECT_FALSE(r.on_reply(reply(0, x, Vec3(0, 0, 1), k)));
  EXPECT_EQ(r.stats().rejected_replies, 3u);
  Vec3 f;
  for (int i = 0; i < 100; ++i) f = r.update(i * kDt, x, Vec3::Zero());
  // The good reply (1 N up) is what is rendered.
  EXPECT_NEAR(f.z(), 1.0, 1e-12);
  EXPECT_NEAR(f.head<2>().norm(), 0.0, 1e-12);
  // NaN device input: no NaN out, and the force falls (at the slew limit) instead of jumping.
  const Vec3 g = r.update(0.1, Vec3::Constant(nan), Vec3::Zero());
  EXPECT_TRUE(g.allFinite());
  EXPECT_NEAR((g - f).norm(), profile("falcon").max_force_rate * kDt, 1e-12);
}

TEST(Renderer, ClampsStiffnessEigenvaluesToTheProfile) {
  bool clamped = false;
  // Independent value: a diagonal matrix's eigenvalues are its diagonal.
  const Mat3 k = Eigen::Vector3d(-1e6, 500, -100).asDiagonal();
  const Mat3 ks = Renderer::clamp_stiffness(k, 400, &clamped);
  EXPECT_TRUE(clamped);
  const Mat3 want = Eigen::Vector3d(-400, 0, -100).asDiagonal();
  EXPECT_LT((ks - want).norm(), 1e-9);
  // A rotated wall normal: -k n n^T stays -k_max n n^T.
  const Vec3 n = Vec3(1, 2, 2) / 3;
  const Mat3 wall = -1e5 * n * n.transpose();
  EXPECT_LT((Renderer::clamp_stiffness(wall, 700, &clamped) - (-700 * n * n.transpose())).norm(),
            1e-9);
  // Inside the limits: unchanged (only symmetrised).
  Mat3 soft = -50 * Mat3::Identity();
  soft(0, 1) = -10;
  soft(1, 0) = -10;
  EXPECT_LT((Renderer::clamp_stiffness(soft, 400, &clamped) - soft).norm(), 1e-9);
  EXPECT_FALSE(clamped);
}

TEST(Renderer, InterpolatesWithTheReplyStiffnessBetweenReplies) {
  RendererOptions o;
  o.coupling = false;
  o.passivity = false;
  Renderer r(profile("omega"), o);
  const Vec3 x0(0.01, 0.02, 0.03), f0(0.1, -0.2, 1.5);
  const Mat3 k = Eigen::Vector3d(-1000, -2000, -3000).asDiagonal();
  r.on_reply(reply(0, x0, f0, k));
  const Vec3 x = x0 + Vec3(0.001, -0.0005, -0.0008);
  Vec3 f;
  for (int i = 0; i < 50; ++i) f = r.update(i * kDt, x, Vec3::Zero());  // within the timeout
  // F0 + K (x - x0) by hand: (0.1 - 1, -0.2 + 1, 1.5 + 2.4)
  EXPECT_NEAR(f.x(), -0.9, 1e-12);
  EXPECT_NEAR(f.y(), 0.8, 1e-12);
  EXPECT_NEAR(f.z(), 3.9, 1e-12);

  o.interpolate = false;  // hold F0
  Renderer hold(profile("omega"), o);
  hold.on_reply(reply(0, x0, f0, k));
  for (int i = 0; i < 50; ++i) f = hold.update(i * kDt, x, Vec3::Zero());
  EXPECT_LT((f - f0).norm(), 1e-12);
}

TEST(Renderer, CouplingRendersTheSeriesStiffness) {
  // A wall along z of stiffness k = 1e5 N/m (far above the Falcon's 3000 N/m), device 3 mm in.
  // The coupled probe settles where kc (x - p) + F_wall(p) = 0, so the device feels the series
  // stiffness kc k / (kc + k) < kc times 3 mm.
  const DeviceProfile prof = profile("falcon");
  RendererOptions o;
  o.passivity = false;
  o.coupling_stiffness = 2000;
  Renderer r(prof, o);
  const Vec3 ez(0, 0, 1);
  const double k = 1e5, d = 0.003, kc = 2000;
  const Vec3 x(0, 0, -d);
  // The "server" answers at whatever probe position it was sent, like a wall at z = 0.
  Vec3 f;
  for (int i = 0; i < 100; ++i) {
    const Vec3 p = r.probe_position();
    const double pen = std::max(0.0, -p.z());
    r.on_reply(reply(i * kDt, p, k * pen * ez, -k * ez * ez.transpose()));
    f = r.update(i * kDt, x, Vec3::Zero());
  }
  EXPECT_NEAR(f.z(), kc * k / (kc + k) * d, 1e-9);
  EXPECT_LT(f.z(), prof.max_stiffness * d);
  EXPECT_NEAR(r.probe_position().z(), -d + f.z() / kc, 1e-12);
  EXPECT_GT(r.stats().stiffness_clamped, 0u);

  // Default coupling (kc = k_max): the force the device feels grows by at most k_max per metre.
  Renderer def(prof, RendererOptions{});
  double prev_f = 0, prev_d = 0, worst_k = 0;
  for (int i = 0; i < 400; ++i) {
    const double depth = 1e-5 * i;  // 0 .. 4 mm, slowly
    const Vec3 p = def.probe_position();
    def.on_reply(reply(i * kDt, p, k * std::max(0.0, -p.z()) * ez, -k * ez * ez.transpose()));
    for (int j = 0; j < 20; ++j) def.update(i * kDt, Vec3(0, 0, -depth), Vec3::Zero());
    const double fz = def.last_force().z();
    if (i > 0) worst_k = std::max(worst_k, (fz - prev_f) / (depth - prev_d));
    prev_f = fz;
    prev_d = depth;
  }
  EXPECT_LE(worst_k, prof.max_stiffness * (1 + 1e-6));
  EXPECT_GT(worst_k, 0.9 * prof.max_stiffness);
}

// Replies stop (lost), the force fades at no more than the slew rate, replies resume with a
// very different force: no tick changes the force by more than the slew limit.
TEST(Renderer, ForceIsContinuousWhenRepliesStopAndResume) {
  const DeviceProfile prof = profile("touch");
  RendererOptions o;
  o.coupling = false;
  o.passivity = false;
  o.reply_timeout = 0.05;
  Renderer r(prof, o);
  const Vec3 x(0, 0, -0.002);
  const Mat3 k = -400 * Vec3(0, 0, 1) * Vec3(0, 0, 1).transpose();
  const double limit = prof.max_force_rate * kDt * (1 + 1e-9);
  Vec3 prev = Vec3::Zero();
  double worst = 0;
  Vec3 at_stop = Vec3::Zero(), at_resume = Vec3::Constant(1);
  for (int i = 0; i < 1000; ++i) {
    const double t = i * kDt;
    if (i < 300) r.on_reply(reply(t, x, Vec3(0, 0, 3.0), k));    // 3 N
    if (i >= 600) r.on_reply(reply(t, x, Vec3(-3.3, 0, 0), k));  // resumes, other force
    if (i == 300) at_stop = prev;
    const Vec3 f = r.update(t, x, Vec3::Zero());
    if (i == 330) {  // lost replies inside the timeout: the last model is still rendered
      EXPECT_NEAR(f.z(), 3.0, 1e-9);
    }
    if (i == 599) at_resume = f;
    worst = std::max(worst, (f - prev).norm());
    prev = f;
  }
  EXPECT_NEAR(at_stop.z(), 3.0, 1e-9);
  EXPECT_LT(at_resume.norm(), 1e-9);  // faded to zero after the timeout
  EXPECT_NEAR(prev.x(), -3.3, 1e-9);  // and reached the new force
  EXPECT_LE(worst, limit);
  EXPECT_GT(worst, 0.99 * limit);  // the limiter was what shaped the transitions
  EXPECT_GT(r.stats().stale_ticks, 200u);
}

// The same through the whole loop: virtual device pressing a wall, a burst of lost replies.
TEST(Renderer, ServoLoopStaysWithinSlewThroughLostReplies) {
  const DeviceProfile prof = profile("falcon");
  VirtualDeviceOptions vo;
  vo.mass = prof.mass;
  vo.hand = hand_press(Vec3(0, 0, 0.005), Vec3(0, 0, -1), 0.012, 1.0);
  VirtualDevice dev(vo);
  Renderer r(prof, RendererOptions{});
  WallLink wall(Vec3::Zero(), Vec3(0, 0, 1), 2000, 2, kDt);
  wall.set_drop(0.40, 0.70);  // around the deepest point (t = 0.5 s)
  double worst = 0, peak = 0;
  Vec3 prev = Vec3::Zero();
  for (int i = 0; i < 2000; ++i) {
    const ServoTick s = servo_tick(i * kDt, dev, r, wall);
    worst = std::max(worst, (s.force - prev).norm());
    peak = std::max(peak, s.force.norm());
    prev = s.force;
  }
  EXPECT_GT(wall.lost(), 250u);
  EXPECT_GT(peak, 1.0);  // it really pressed
  EXPECT_LE(worst, prof.max_force_rate * kDt * (1 + 1e-9));
}

struct PassivityRun {
  double device_work;  // J, from the virtual device's own bookkeeping
  double peak_force;   // N
};

// A hand pushes a Falcon tip 10 mm into a 3000 N/m wall and back, every second, for 20 s;
// replies come back 3 ticks late.
PassivityRun run_wall(const RendererOptions& o, double wall_k) {
  const DeviceProfile prof = profile("falcon");
  VirtualDeviceOptions vo;
  vo.mass = prof.mass;
  vo.hand_stiffness = 200;
  vo.hand_damping = 0.5;
  vo.friction = 0.0;
  vo.hand = hand_press(Vec3(0, 0, 0.005), Vec3(0, 0, -1), 0.015, 1.0);
  VirtualDevice dev(vo);
  Renderer r(prof, o);
  WallLink wall(Vec3::Zero(), Vec3(0, 0, 1), wall_k, 3, kDt);
  double peak = 0;
  for (int i = 0; i < 20000; ++i)
    peak = std::max(peak, servo_tick(i * kDt, dev, r, wall).force.norm());
  // Both accounts of the same work agree (renderer: held force times device displacement).
  EXPECT_NEAR(r.stats().device_work, dev.work_received(),
              1e-3 + 0.05 * std::abs(dev.work_received()));
  return {dev.work_received(), peak};
}

TEST(Passivity, UnstableSettingInjectsEnergyWithoutTheObserver) {
  RendererOptions o;
  o.interpolate = false;  // zero-order hold of late replies: the classic energy leak
  o.coupling = false;
  o.passivity = false;
  const PassivityRun run = run_wall(o, 3000);
  EXPECT_GT(run.device_work, 0.05) << "expected the held, delayed wall to create energy";
}

TEST(Passivity, ObserverKeepsTheSameSettingPassive) {
  RendererOptions o;
  o.interpolate = false;
  o.coupling = false;
  o.passivity = true;
  const PassivityRun run = run_wall(o, 3000);
  EXPECT_LE(run.device_work, 2e-3);
  EXPECT_GT(run.peak_force, 2.0);  // still renders the wall
}

TEST(Passivity, DefaultRendererIsPassiveOnAStiffWall) {
  const PassivityRun run = run_wall(RendererOptions{}, 1e5);
  EXPECT_LE(run.device_work, 2e-3);
  EXPECT_GT(run.peak_force, 2.0);
}

}  // namespace
}  // namespace conica::haptics
