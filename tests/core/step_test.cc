// step() as a whole: a probe teleported into the body, the guard's rollback, and the stage timers
// that cover a step.
#include "core/step.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "core/body.h"
#include "probed_block.h"

namespace conica {
namespace {

using testing_meshes::ProbedBlock;

TEST(StepTest, ProbeTeleportingIntoTheBodyGivesBoundedForcesAndRecovers) {
  Model m;
  ASSERT_EQ(build_model(ProbedBlock(Integrator::kSymplecticEuler), &m), "");
  State s = make_state(m);
  Workspace ws(m);
  set_probe(s, 0, Vec3(0.02, 0.02, 0.01));  // appears inside, at the centre of the block
  const double bound = m.probes[0].stiffness * m.probes[0].radius * m.num_nodes();
  for (int t = 0; t < 500; ++t) {
    step(m, s, ws);
    ASSERT_TRUE(s.probes[0].force.allFinite());
    ASSERT_LE(s.probes[0].force.norm(), bound);
  }
  set_probe(s, 0, Vec3(0.02, 0.02, 0.5), false);  // gone
  for (int t = 0; t < 5000; ++t) step(m, s, ws);
  double worst = 0;
  for (int i = 0; i < m.num_nodes(); ++i) worst = std::max(worst, (s.x[i] - m.rest[i]).norm());
  EXPECT_LT(worst, 1e-3);  // back near rest, no blow-up
}

TEST(StepTest, GuardRollsBackNaNAndKeepsRunning) {
  Model m;
  ASSERT_EQ(build_model(ProbedBlock(Integrator::kSymplecticEuler), &m), "");
  State s = make_state(m);
  Workspace ws(m);
  set_probe(s, 0, Vec3(0.02, 0.02, 0.023));
  for (int t = 0; t < 10; ++t) step(m, s, ws);
  const State before = s;
  s.v[40].x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(step(m, s, ws), StepStatus::kRolledBack);
  EXPECT_EQ(s.counters.rollbacks, 1u);
  EXPECT_EQ(s.counters.nan_events, 1u);
  for (int i = 0; i < m.num_nodes(); ++i) EXPECT_EQ(s.x[i], before.x[i]);
  EXPECT_EQ(s.tick, before.tick + 1);
  EXPECT_EQ(step(m, s, ws), StepStatus::kOk);
}

// The stage timers cover a step without gaps or overlap: their sum over a run equals the steady
// clock's time around the step calls, less only the calls' own entry and exit.
TEST(StepTest, StageTimersAddUpToTheTimeOfTheSteps) {
  BodySpec b;
  b.mesh = make_box_lattice(Vec3(0.04, 0.04, 0.02), {8, 8, 4});
  SpringCard c;
  c.conical = ConicalCard{5e7, 1e-3, 2e-3, 8e-3, 10e-3, 3};
  b.groups.push_back({"tissue", c, kAllFamilies, {}, Vec3::Zero(), 10});
  FixedSelector base;
  base.kind = FixedSelector::Kind::kPlane;
  b.fixed.push_back(base);
  b.options.mass_damping = 30;
  b.probes.push_back(ProbeSpec{});
  Model m;
  ASSERT_EQ(build_model(b, &m), "");
  State s = make_state(m);
  Workspace ws(m);
  auto stages = [&] {
    std::uint64_t sum = 0;
    for (std::uint64_t ns : s.counters.stage_ns) sum += ns;
    return sum;
  };
  std::uint64_t wall = 0;
  std::vector<std::int64_t> gap;  // ns, each step's time outside every stage
  for (int t = 0; t < 300; ++t) {
    set_probe(s, 0, Vec3(0.02, 0.02, 0.025 - 2e-5 * t));
    const std::uint64_t before = stages();
    const auto t0 = std::chrono::steady_clock::now();
    step(m, s, ws);
    const std::uint64_t ns =
        std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - t0)
            .count();
    wall += ns;
    gap.push_back(static_cast<std::int64_t>(ns) - static_cast<std::int64_t>(stages() - before));
  }
  EXPECT_LE(stages(), wall);
  EXPECT_GE(*std::min_element(gap.begin(), gap.end()), 0) << "a stage timed beyond its step";
  // The median step: a gap in the timers shows in every step, a preemption of the test between
  // the step's entry and its first stage (a loaded machine) in a few.
  std::nth_element(gap.begin(), gap.begin() + gap.size() / 2, gap.end());
  EXPECT_LE(gap[gap.size() / 2], 2000) << "more than 2 us of the median step outside every stage";
  EXPECT_GT(s.counters.stage_ns[static_cast<int>(Stage::kSprings)], 0u);
  EXPECT_GT(s.counters.stage_ns[static_cast<int>(Stage::kContact)], 0u);
  EXPECT_GT(s.counters.stage_ns[static_cast<int>(Stage::kIntegrate)], 0u);
  EXPECT_STREQ(stage_name(Stage::kHardStop), "hard_stop");
}

}  // namespace
}  // namespace conica
