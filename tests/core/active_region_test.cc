// The active region: a probe far from a sleeping region does not wake it, a press near its edge
// does, and forces with and without it agree within the tolerance's reach.
#include <gtest/gtest.h>

#include "core/body.h"
#include "core/step.h"

namespace conica {
namespace {

// A bar 16 x 4 x 2 cells of 1 cm, clamped base, conical tissue springs, one 6 mm probe.
Model Bar(bool active, double tolerance) {
  BodySpec b;
  b.mesh = make_box_lattice(Vec3(0.16, 0.04, 0.02), {16, 4, 2});
  b.density = 1000;
  SpringCard c;
  c.conical = ConicalCard{2e8, 1e-3, 2e-3, 8e-3, 10e-3, 3};
  c.stiffness_cap = 20;
  c.damping = 0.01;
  b.groups.push_back({"tissue", c, kAllFamilies, {}, Vec3::Zero(), 10});
  FixedSelector base;
  base.kind = FixedSelector::Kind::kPlane;
  b.fixed.push_back(base);
  b.options.mass_damping = 5;
  b.options.active_region = active;
  b.options.active_tolerance = tolerance;
  b.probes.push_back(ProbeSpec{0.006, 0});
  Model m;
  EXPECT_EQ(build_model(b, &m), "");
  return m;
}

Vec3 Press(double x, double depth) { return Vec3(x, 0.02, 0.02 + 0.006 - depth); }

TEST(ActiveRegionTest, FarProbeLeavesTheRegionAsleepAndANearPressWakesIt) {
  const Model m = Bar(true, 2e-4);
  State s = make_state(m);
  Workspace ws(m);
  for (int t = 0; t < 400; ++t) {
    set_probe(s, 0, Press(0.02, 0.003 * std::min(1.0, t / 200.0)));
    step(m, s, ws);
  }
  ASSERT_GT(s.probes[0].contacts, 0);
  int far_awake = 0, near_awake = 0, far = 0;
  double far_moved = 0;
  for (int i = 0; i < m.num_nodes(); ++i) {
    if (m.rest[i].x() >= 0.12) {
      ++far;
      far_awake += ws.awake[i];
      far_moved = std::max(far_moved, (s.x[i] - m.rest[i]).norm());
    }
    if ((m.rest[i] - Press(0.02, 0)).norm() < 0.012) near_awake += ws.awake[i];
  }
  EXPECT_GT(near_awake, 0);
  EXPECT_EQ(far_awake, 0) << "of " << far;
  EXPECT_EQ(far_moved, 0.0);  // asleep at rest, bit for bit
  EXPECT_LT(s.counters.awake_nodes, static_cast<std::uint64_t>(m.num_nodes()) / 2);
  // Now press near the far end: its nodes wake and move.
  for (int t = 0; t < 400; ++t) {
    set_probe(s, 0, Press(0.14, 0.003 * std::min(1.0, t / 200.0)));
    step(m, s, ws);
  }
  far_awake = 0;
  far_moved = 0;
  for (int i = 0; i < m.num_nodes(); ++i)
    if (m.rest[i].x() >= 0.12) {
      far_awake += ws.awake[i];
      far_moved = std::max(far_moved, (s.x[i] - m.rest[i]).norm());
    }
  EXPECT_GT(far_awake, 0);
  EXPECT_GT(far_moved, 1e-3);
  EXPECT_EQ(s.counters.rollbacks, 0u);
}

TEST(ActiveRegionTest, ForcesAgreeWithTheFullSimulation) {
  // Press 3 mm at the middle of the bar and hold; compare the probe force tick by tick.
  for (double tol : {2e-5, 2e-4}) {
    const Model full = Bar(false, tol), part = Bar(true, tol);
    State a = make_state(full), b = make_state(part);
    Workspace wa(full), wb(part);
    double fmax = 0, err = 0;
    std::uint64_t awake = 0;
    const int ticks = 600;
    for (int t = 0; t < ticks; ++t) {
      const Vec3 c = Press(0.08, 0.003 * std::min(1.0, t / 300.0));
      set_probe(a, 0, c);
      set_probe(b, 0, c);
      step(full, a, wa);
      step(part, b, wb);
      fmax = std::max(fmax, a.probes[0].force.norm());
      err = std::max(err, (a.probes[0].force - b.probes[0].force).norm());
      awake += b.counters.awake_nodes;
    }
    const double fraction = double(awake) / (double(ticks) * full.num_nodes());
    ASSERT_GT(fmax, 0);
    std::printf("tolerance %g m: awake fraction %.3f, force error %.3g %%\n", tol, fraction,
                100 * err / fmax);
    // The smaller tolerance wakes more and agrees to 1 %; the larger stays small and within 10 %.
    if (tol < 1e-4) {
      EXPECT_LT(err / fmax, 0.01) << "awake fraction " << fraction;
    } else {
      EXPECT_LT(err / fmax, 0.10) << "awake fraction " << fraction;
      EXPECT_LT(fraction, 0.5);
    }
  }
}

}  // namespace
}  // namespace conica
