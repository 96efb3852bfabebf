// The spring stage: the runs path (lattice springs read and written as contiguous streams, chunk
// by chunk) against a per-spring evaluation written out here from the law.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/body.h"
#include "core/step.h"
#include "lattice_meshes.h"

namespace conica {
namespace {

using testing_meshes::Lattice;

SpringCard DampedConical() {
  SpringCard c;
  c.conical = ConicalCard{2e8, 1e-3, 2e-3, 8e-3, 10e-3, 3};
  c.stiffness_cap = 20;
  c.damping = 0.05;
  return c;
}

TEST(SpringsTest, LatticeForcesMatchThePerSpringLaw) {
  // 7 x 6 x 5 cells: runs of 7, 42 and 210 springs, several 256-spring chunks, both scatter forms.
  const Model m = Lattice(DampedConical(), {7, 6, 5}, 0.01);
  State s = make_state(m);
  Workspace ws(m);
  ASSERT_FALSE(ws.layout.runs.empty()) << "a lattice numbered row by row is expected to be in runs";
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

}  // namespace
}  // namespace conica
