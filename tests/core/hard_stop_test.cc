// The hard-stop stage: a spring crossed within one step on a lattice is caught (the pass that the
// slack test may skip must not be skipped) and left at its hard-stop length, its approach removed.
#include <gtest/gtest.h>

#include <cmath>

#include "core/body.h"
#include "core/step.h"
#include "lattice_meshes.h"

namespace conica {
namespace {

using testing_meshes::Lattice;

TEST(HardStopTest, HardStopCatchesASpringCrossedWithinOneStep) {
  SpringCard c;
  c.law = LawKind::kHooke;
  c.hooke_k = 50;
  c.hooke_length = 0.01;
  Model m = Lattice(c, {4, 4, 4}, 0.01);
  m.options.gravity = Vec3::Zero();
  State s = make_state(m);
  Workspace ws(m);
  ASSERT_FALSE(ws.layout.runs.empty());
  for (int t = 0; t < 3; ++t) step(m, s, ws);  // at rest: nothing to stop
  EXPECT_EQ(s.counters.hard_stops, 0u);
  // An interior node thrown at its -x neighbour fast enough to pass it within one 1 ms step.
  int node = -1, neighbour = -1;
  for (int i = 0; i < m.num_nodes() && node < 0; ++i) {
    const Vec3 r = m.rest[i];
    if (std::abs(r.x() - 0.02) < 1e-9 && std::abs(r.y() - 0.02) < 1e-9 &&
        std::abs(r.z() - 0.02) < 1e-9)
      node = i;
  }
  ASSERT_GE(node, 0);
  for (int i = 0; i < m.num_nodes(); ++i)
    if ((m.rest[i] - (m.rest[node] - Vec3(0.01, 0, 0))).norm() < 1e-9) neighbour = i;
  ASSERT_GE(neighbour, 0);
  s.v[node] = Vec3(-15, 0, 0);  // 15 mm per step against a 10 mm spring
  step(m, s, ws);
  EXPECT_GT(s.counters.hard_stops, 0u);
  EXPECT_EQ(s.counters.rollbacks, 0u);
  const double l0 = 0.01, lmin = m.options.min_length_fraction * l0;
  // Along the spring's direction before the step (+x from the neighbour), the node stays at least
  // the hard-stop length ahead of its neighbour: it never passed it.
  EXPECT_GE(s.x[node].x() - s.x[neighbour].x(), lmin * (1 - 1e-9));
  EXPECT_GE(s.v[node].x() - s.v[neighbour].x(), -1e-12) << "approach velocity removed";
}

}  // namespace
}  // namespace conica
