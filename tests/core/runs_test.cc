// The runs path of the step (lattice springs read and written as contiguous streams, chunk by
// chunk) against a per-spring evaluation written out here from the law, and the hard stop on a
// lattice when a spring is crossed within one step (the pass it may skip must not be skipped).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/body.h"
#include "core/step.h"

namespace conica {
namespace {

Model Lattice(const SpringCard& card, std::array<int, 3> cells, double cell) {
  BodySpec b;
  b.mesh = make_box_lattice(Vec3(cell * cells[0], cell * cells[1], cell * cells[2]), cells);
  b.density = 1000;
  b.groups.push_back({"tissue", card, kAllFamilies, {}, Vec3::Zero(), 10});
  b.options.mass_damping = 3;
  b.options.gravity = Vec3(0, 0, -9.81);
  Model m;
  EXPECT_EQ(build_model(b, &m), "");
  return m;
}

SpringCard DampedConical() {
  SpringCard c;
  c.conical = ConicalCard{2e8, 1e-3, 2e-3, 8e-3, 10e-3, 3};
  c.stiffness_cap = 20;
  c.damping = 0.05;
  return c;
}

TEST(RunsTest, LatticeForcesMatchThePerSpringLaw) {
  // 7 x 6 x 5 cells: runs of 7, 42 and 210 springs, several 256-spring chunks, both scatter forms.
  const Model m = Lattice(DampedConical(), {7, 6, 5}, 0.01);
  State s = make_state(m);
  Workspace ws(m);
  ASSERT_FALSE(ws.runs.empty()) << "a lattice numbered row by row is expected to be in runs";
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int i = 0; i < m.num_nodes(); ++i) {
    s.x[i] += 2.5e-3 * Vec3(u(rng), u(rng), u(rng));  // up to 25 % strain: nonlinear phase too
    s.v[i] = 0.05 * Vec3(u(rng), u(rng), u(rng));
  }
  compute_forces(m, s, ws);

  std::vector<Vec3> f(m.num_nodes());
  for (int i = 0; i < m.num_nodes(); ++i)
    f[i] = m.mass[i] * (m.options.gravity - m.options.mass_damping * s.v[i]);
  int nonlinear = 0;
  for (const SpringGroup& g : m.groups) {
    for (int k = g.begin; k < g.end; ++k) {
      const int i = m.spring_i[k], j = m.spring_j[k];
      const Vec3 w = s.x[j] - s.x[i];
      const Vec3 d = w.normalized();
      const double b = m.deflection_scale[k];
      const double delta = b * (m.rest_length[k] - w.norm());
      nonlinear += delta > g.law->transition_deflection();
      const double load =
          g.law->evaluate(delta).force + g.card.damping * (-b * d.dot(s.v[j] - s.v[i]));
      f[i] -= m.force_scale[k] * load * d;
      f[j] += m.force_scale[k] * load * d;
    }
  }
  EXPECT_GT(nonlinear, 0);
  double err = 0, scale = 0;
  for (int i = 0; i < m.num_nodes(); ++i) {
    err = std::max(err, (ws.force[i] - f[i]).norm());
    scale = std::max(scale, f[i].norm());
  }
  EXPECT_LT(err, 1e-12 * scale) << "largest node force " << scale << " N";
}

TEST(RunsTest, HardStopCatchesASpringCrossedWithinOneStep) {
  SpringCard c;
  c.law = LawKind::kHooke;
  c.hooke_k = 50;
  c.hooke_length = 0.01;
  Model m = Lattice(c, {4, 4, 4}, 0.01);
  m.options.gravity = Vec3::Zero();
  State s = make_state(m);
  Workspace ws(m);
  ASSERT_FALSE(ws.runs.empty());
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
