// The active region: a probe far from a sleeping region does not wake it, a press near its edge
// does, and forces with and without it agree within the tolerance's reach; with the multi-rate
// far field they agree to 1 % with a small region, the far field moves as in the full simulation,
// and a long hold stays bounded.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <limits>

#include "core/body.h"
#include "core/step.h"
#include "tissue_bar.h"

namespace conica {
namespace {

// The bar of tissue_bar.h, 16 x 4 x 2 cells. Its regions are a large share of so small a body, so
// the switch to whole-body steps is off unless asked for: these tests are about the region.
Model Bar(bool active, double tolerance, int far_every = -1, bool whole_body_switch = false) {
  BodySpec b = TissueBar({16, 4, 2}, active, tolerance, far_every);
  if (!whole_body_switch)
    b.options.active_whole_body_cost = std::numeric_limits<double>::infinity();
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
      far_awake += s.region.awake[i];
      far_moved = std::max(far_moved, (s.x[i] - m.rest[i]).norm());
    }
    if ((m.rest[i] - Press(0.02, 0)).norm() < 0.012) near_awake += s.region.awake[i];
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
      far_awake += s.region.awake[i];
      far_moved = std::max(far_moved, (s.x[i] - m.rest[i]).norm());
    }
  EXPECT_GT(far_awake, 0);
  EXPECT_GT(far_moved, 1e-3);
  EXPECT_EQ(s.counters.rollbacks, 0u);
}

struct Comparison {
  double peak_force = 0;      // largest |F_full|, N
  double error = 0;           // largest |F_full - F_active| / peak_force
  double awake_fraction = 0;  // mean over ticks
  // Largest displacement of the far end's top nodes, mean over the hold's last 300 ticks, m.
  double far_full = 0, far_active = 0;
  std::uint64_t rollbacks = 0;
};

// The full simulation and a partial one (active region) driven by the same press, tick by tick:
// 3 mm at the middle of the bar in 300 ticks, then held; the probe forces compared every tick.
struct SideBySide {
  const Model& full;
  const Model& part;
  State a, b;
  Workspace wa, wb;
  double fmax = 0;  // N, largest |F_full|
  double err = 0;   // N, largest |F_full - F_part|

  SideBySide(const Model& f, const Model& p)
      : full(f), part(p), a(make_state(f)), b(make_state(p)), wa(f), wb(p) {}
  void tick(int t) {
    const Vec3 p = Press(0.08, 0.003 * std::min(1.0, t / 300.0));
    set_probe(a, 0, p);
    set_probe(b, 0, p);
    step(full, a, wa);
    step(part, b, wb);
    fmax = std::max(fmax, a.probes[0].force.norm());
    err = std::max(err, (a.probes[0].force - b.probes[0].force).norm());
  }
};

Comparison Compare(const Model& full, const Model& part, int ticks) {
  SideBySide run(full, part);
  Comparison c;
  std::uint64_t awake = 0;
  for (int t = 0; t < ticks; ++t) {
    run.tick(t);
    awake += run.b.counters.awake_nodes;
    if (t < ticks - 300) continue;
    double da = 0, db = 0;
    for (int i = 0; i < full.num_nodes(); ++i)
      if (full.rest[i].x() >= 0.15 && full.rest[i].z() >= 0.02) {
        da = std::max(da, (run.a.x[i] - full.rest[i]).norm());
        db = std::max(db, (run.b.x[i] - part.rest[i]).norm());
      }
    c.far_full += da / 300;
    c.far_active += db / 300;
  }
  c.peak_force = run.fmax;
  c.error = run.err / run.fmax;
  c.awake_fraction = double(awake) / (double(ticks) * full.num_nodes());
  c.rollbacks = run.b.counters.rollbacks;
  return c;
}

TEST(ActiveRegionTest, ForcesAgreeWithTheFullSimulation) {
  // Press 3 mm at the middle of the bar and hold; compare the probe force tick by tick.
  for (double tol : {2e-5, 2e-4}) {
    const Comparison c = Compare(Bar(false, tol), Bar(true, tol), 600);
    ASSERT_GT(c.peak_force, 0);
    std::printf("tolerance %g m: awake fraction %.3f, force error %.3g %%\n", tol, c.awake_fraction,
                100 * c.error);
    // The smaller tolerance wakes more and agrees to 1 %; the larger stays small and within 10 %.
    if (tol < 1e-4) {
      EXPECT_LT(c.error, 0.01) << "awake fraction " << c.awake_fraction;
    } else {
      EXPECT_LT(c.error, 0.10) << "awake fraction " << c.awake_fraction;
      EXPECT_LT(c.awake_fraction, 0.5);
    }
  }
}

TEST(ActiveRegionTest, MultiRateFarFieldAgreesToOnePercentWithASmallRegion) {
  // The larger tolerance keeps well under half the bar awake; frozen, the far field stiffens the
  // bar by several per cent, multi-rate it moves and the force agrees to 1 %.
  const double tol = 2e-4;
  const Model full = Bar(false, tol);
  const Comparison frozen = Compare(full, Bar(true, tol, -1), 600);
  const Model multi = Bar(true, tol, 0);
  const Workspace ws(multi);
  ASSERT_GT(ws.bounds.far_every, 1) << "the far field's stability bound allows no interval";
  const Comparison moving = Compare(full, multi, 600);
  std::printf(
      "frozen: error %.3g %%, awake %.3f; multi-rate (every %d ticks): error %.3g %%, "
      "awake %.3f; far end moved %.3g / %.3g / %.3g um (full / frozen / multi-rate)\n",
      100 * frozen.error, frozen.awake_fraction, ws.bounds.far_every, 100 * moving.error,
      moving.awake_fraction, 1e6 * moving.far_full, 1e6 * frozen.far_active,
      1e6 * moving.far_active);
  EXPECT_LT(moving.awake_fraction, 0.5);
  EXPECT_LT(moving.error, 0.01);
  EXPECT_GT(frozen.error, 2 * moving.error);
  EXPECT_EQ(moving.rollbacks, 0u);
  // The far end moves in the full simulation, and the multi-rate far field follows it.
  ASSERT_GT(moving.far_full, 1e-7);
  EXPECT_NEAR(moving.far_active, moving.far_full, 0.2 * moving.far_full);
}

TEST(ActiveRegionTest, FarStepIsSpreadOverItsInterval) {
  // The far field's springs are evaluated in shares, one per tick of the interval: no tick
  // evaluates more than about 1/N of them (one chunk of rounding), every interval evaluates each
  // far spring exactly once, and the probe force still agrees with the full simulation to 1 %.
  const double tol = 2e-4;
  const Model full = Bar(false, tol);
  const Model m = Bar(true, tol, 4);
  SideBySide run(full, m);
  const State& s = run.b;
  const Workspace& ws = run.wb;
  ASSERT_EQ(ws.bounds.far_every, 4);
  const int slack = ws.layout.runs.empty() ? 1 : SpringLayout::kChunkSprings;
  int worst_share = 0, intervals = 0;
  long in_interval = 0, last_far = 0;
  for (int t = 0; t < 600; ++t) {
    run.tick(t);
    // Far springs of this interval (both ends asleep; lattices: springs of chunks holding one).
    long far = 0;
    if (ws.layout.runs.empty()) {
      far = static_cast<long>(s.region.slow.size());
    } else {
      for (size_t c = 0; c < ws.layout.chunks.size(); ++c)
        if (s.region.chunk_slow[c]) far += ws.layout.chunks[c].k1 - ws.layout.chunks[c].k0;
    }
    ASSERT_GT(far, 0);
    // The region's lists, updated incrementally, match a count from scratch.
    int on = 0, mismatched = 0;
    for (int k = 0; k < m.num_springs(); ++k) {
      const bool awake_end = s.region.awake[m.spring_i[k]] || s.region.awake[m.spring_j[k]];
      on += awake_end;
      mismatched += awake_end != (s.region.active_scale[k] != 0) ||
                    awake_end == (s.region.slow_scale[k] != 0);
    }
    ASSERT_EQ(mismatched, 0) << "tick " << t;
    ASSERT_EQ(s.region.num_active, on) << "tick " << t;
    // Shares are equal ranges of chunks (or of the far spring list): at most a quarter of the
    // springs plus one chunk.
    EXPECT_LE(s.region.far_springs_evaluated, m.num_springs() / 4 + slack) << "tick " << t;
    last_far = far;
    worst_share = std::max(worst_share, s.region.far_springs_evaluated);
    in_interval += s.region.far_springs_evaluated;
    if (s.region.far_phase == 0) {  // an interval ended with this tick
      EXPECT_EQ(in_interval, far) << "tick " << t;
      in_interval = 0;
      ++intervals;
    }
  }
  std::printf("far springs %ld of %d, largest share per tick %d, %d intervals, error %.3g %%\n",
              last_far, m.num_springs(), worst_share, intervals, 100 * run.err / run.fmax);
  EXPECT_EQ(intervals, 150);
  EXPECT_EQ(s.counters.rollbacks, 0u);
  ASSERT_GT(run.fmax, 0);
  EXPECT_LT(run.err / run.fmax, 0.01);
}

TEST(ActiveRegionTest, MultiRateHoldStaysBounded) {
  // Press and hold for 10 s: no roll-back, and the energy of the hold decays (mass damping) instead
  // of growing through the coupling of the two rates.
  const Model m = Bar(true, 2e-4, 0);
  State s = make_state(m);
  Workspace ws(m);
  double e_start = 0, e_late = 0, kin_late = 0;
  const int ticks = 10000;
  for (int t = 0; t < ticks; ++t) {
    set_probe(s, 0, Press(0.08, 0.003 * std::min(1.0, t / 300.0)));
    step(m, s, ws);
    const double e = potential_energy(m, s) + kinetic_energy(m, s);
    if (t == 500) e_start = e;
    if (t >= ticks - 1000) {
      e_late = std::max(e_late, e);
      kin_late = std::max(kin_late, kinetic_energy(m, s));
    }
  }
  std::printf("hold: energy %.4g J at 0.5 s, at most %.4g J in the last second, kinetic %.3g J\n",
              e_start, e_late, kin_late);
  EXPECT_EQ(s.counters.rollbacks, 0u);
  EXPECT_LE(e_late, e_start * 1.001);
  EXPECT_LT(kin_late, 1e-3 * e_start);
}

TEST(ActiveRegionTest, FarIntervalBeyondTheStabilityBoundStaysBounded) {
  // Four times the interval the far field's own bound allows: without the raised inertia of the
  // far step this blows up (roll-backs); with it the far field stays bounded.
  const Model probe_model = Bar(true, 2e-4, 0);
  const int bound = Workspace(probe_model).bounds.far_max_every;
  const Model m = Bar(true, 2e-4, 4 * bound);
  State s = make_state(m);
  Workspace ws(m);
  for (int t = 0; t < 2000; ++t) {
    set_probe(s, 0, Press(0.08, 0.003 * std::min(1.0, t / 300.0)));
    step(m, s, ws);
  }
  EXPECT_EQ(s.counters.rollbacks, 0u) << "interval " << 4 * bound;
  EXPECT_GT(s.probes[0].contacts, 0);
}

TEST(ActiveRegionTest, ARegionAsCostlyAsTheWholeBodyStepsTheWholeBodyUntilItShrinks) {
  // A tolerance of 0.1 um wakes nearly the whole bar: the region's cost estimate passes the
  // threshold and the whole body steps every tick, agreeing with the full simulation; once the
  // probe is withdrawn the region falls asleep and the multi-rate region is used again.
  const Model full = Bar(false, 1e-7);
  const Model m = Bar(true, 1e-7, 0, true);
  SideBySide run(full, m);
  State& s = run.b;
  Workspace& ws = run.wb;
  ASSERT_GT(ws.bounds.far_every, 0);
  int whole = 0;
  for (int t = 0; t < 600; ++t) {
    run.tick(t);
    whole += s.region.whole_body;
  }
  std::printf("whole body on %d of 600 ticks, last cost estimate %.2f, force error %.3g %%\n",
              whole, s.region.cost, 100 * run.err / run.fmax);
  EXPECT_TRUE(s.region.whole_body);
  EXPECT_GT(s.region.cost, kRegionResumeFraction * m.options.active_whole_body_cost);
  EXPECT_EQ(s.counters.awake_nodes, static_cast<std::uint64_t>(m.num_nodes()));
  ASSERT_GT(run.fmax, 0);
  EXPECT_LT(run.err / run.fmax, 0.01);
  // Withdrawn: nothing is near a probe any more, the region empties and its cost drops.
  for (int t = 0; t < 400; ++t) {
    set_probe(s, 0, Vec3(0.08, 0.02, 0.1), false);
    step(m, s, ws);
  }
  EXPECT_FALSE(s.region.whole_body);
  EXPECT_LT(s.region.cost, kRegionResumeFraction * m.options.active_whole_body_cost);
  EXPECT_LT(s.counters.awake_nodes, static_cast<std::uint64_t>(m.num_nodes()) / 2);
  EXPECT_EQ(s.counters.rollbacks, 0u);
}

TEST(ActiveRegionTest, SpectralBoundIsTheLargestEigenvalueOfTheStiffnessOverTheMass) {
  // far_spectral_bound (Lanczos on the assembled linear-phase K) against an independent value: the
  // largest eigenvalue of M^-1/2 K M^-1/2 with K from central differences of compute_forces at
  // rest (every free axis of every node), solved densely.
  const Model m = Bar(false, 2e-4);
  std::vector<int> dof;  // node * 3 + axis of the free axes
  for (int i = 0; i < m.num_nodes(); ++i)
    for (int a = 0; a < 3; ++a)
      if (m.free_axes[i][a] != 0 && m.inv_mass[i] > 0) dof.push_back(3 * i + a);
  const int n = static_cast<int>(dof.size());
  ASSERT_GT(n, 100);
  Eigen::MatrixXd A(n, n);
  State s = make_state(m);
  Workspace ws(m);
  const double h = 1e-7;  // m, well inside the linear phase (delta_t is millimetres)
  std::vector<Vec3> plus(m.num_nodes());
  for (int c = 0; c < n; ++c) {
    const int i = dof[c] / 3, a = dof[c] % 3;
    s.x[i][a] += h;
    compute_forces(m, s, ws);
    plus = ws.force;
    s.x[i][a] -= 2 * h;
    compute_forces(m, s, ws);
    s.x[i][a] += h;
    for (int r = 0; r < n; ++r) {
      const int j = dof[r] / 3, b = dof[r] % 3;
      // K = -dF/dx, scaled by the inverse square roots of the two masses.
      A(r, c) = -(plus[j][b] - ws.force[j][b]) / (2 * h) * std::sqrt(m.inv_mass[i] * m.inv_mass[j]);
    }
  }
  const double asym = (A - A.transpose()).norm() / A.norm();
  EXPECT_LT(asym, 1e-6);
  const Eigen::MatrixXd S = 0.5 * (A + A.transpose());
  const double lambda = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(S).eigenvalues().maxCoeff();
  const double bound = far_spectral_bound(m);
  std::printf("largest eigenvalue of M^-1 K: dense %.6g 1/s^2, Lanczos bound %.6g (%d dof)\n",
              lambda, bound, n);
  EXPECT_GE(bound, lambda * (1 - 1e-6));  // an upper bound (Ritz value plus residual)
  EXPECT_LE(bound, lambda * 1.05);        // and a tight one
}

}  // namespace
}  // namespace conica
