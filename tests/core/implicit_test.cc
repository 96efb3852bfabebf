// The backward Euler system against the forces it linearises: A p must equal
// M p - h^2 (f(x + e p, v + e p / h) - f(x - e p, v - e p / h)) / (2 e), a central difference of
// the force evaluation the step uses (mass damping enters through v), wherever the system is exact:
// springs in tension (the compressive geometric term is clamped on purpose, step.h), dampers at
// rest and rigid planes.
#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "core/body.h"
#include "core/step.h"
#include "core/step_detail.h"
#include "lattice_meshes.h"

namespace conica {
namespace {

using testing_meshes::Tetrahedralised;

// A clamped 20 x 20 x 10 mm block, its free nodes stretched 4 % away from the origin so that every
// spring is in tension, pressed on by a side plate; lattice (springs in runs) or tetrahedra
// (gathered).
void Stretched(bool tets, bool damped, Model* m, State* s) {
  BodySpec b;
  b.mesh = make_box_lattice(Vec3(0.02, 0.02, 0.01), {4, 4, 2});
  if (tets) b.mesh = Tetrahedralised(b.mesh);
  SpringCard c;
  c.conical = ConicalCard{5e7, 1e-3, 2e-3, 8e-3, 10e-3, 3};
  c.damping = damped ? 3e-3 : 0.0;
  b.groups.push_back({"tissue", c, kAllFamilies, {}, Vec3::Zero(), 10});
  b.options.integrator = Integrator::kImplicitEuler;
  b.options.mass_damping = 7;
  PlaneSpec plate;  // pushes the x = 20 mm face in by 0.3 mm
  plate.normal = Vec3(-1, 0, 0);
  plate.offset = -0.0197;
  plate.stiffness = 40;
  b.planes = {plate};
  ASSERT_EQ(build_model(b, m), "");
  *s = make_state(*m);
  const Vec3 centre(0.01, 0.01, 0.005);
  for (int i = 0; i < m->num_nodes(); ++i) s->x[i] = centre + 1.04 * (s->x[i] - centre);
}

class ImplicitSystemTest : public ::testing::TestWithParam<std::tuple<bool, bool>> {};

TEST_P(ImplicitSystemTest, ProductIsTheCentralDifferenceOfTheForces) {
  const auto [tets, damped] = GetParam();
  Model m;
  State s;
  Stretched(tets, damped, &m, &s);
  if (HasFatalFailure()) return;
  Workspace ws(m);
  const int nn = m.num_nodes(), n3 = 3 * nn;
  const double h = m.options.dt;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<double> p(n3), y(n3);
  for (int i = 0; i < nn; ++i)
    for (int c = 0; c < 3; ++c) p[c * nn + i] = u(rng) * m.free_axes[i][c];
  detail::system_product(m, s, ws, h, p.data(), y.data());
  for (int k = 0; k < m.num_springs(); ++k)  // the premise: every spring in tension
    ASSERT_LT(ws.springs.load[k], 0) << "spring " << k << " is not in tension";

  // f at x +- e p with v +- e p / h (the implicit step's v = (x - x0) / h), from rest velocity.
  const double e = 1e-7;  // m
  auto forces_at = [&](double sign) {
    State t = s;
    for (int i = 0; i < nn; ++i) {
      const Vec3 pi(p[i], p[nn + i], p[2 * nn + i]);
      t.x[i] += sign * e * pi;
      t.v[i] = sign * (e / h) * pi;
    }
    Workspace w(m);
    compute_forces(m, t, w);
    return w.force;
  };
  const std::vector<Vec3> fp = forces_at(1), fm = forces_at(-1);
  const double mfac = 1 + h * m.options.mass_damping;
  double worst = 0, scale = 0;
  for (int i = 0; i < nn; ++i)
    for (int c = 0; c < 3; ++c) {
      if (m.free_axes[i][c] == 0) continue;
      const double fd = m.mass[i] * p[c * nn + i] - h * h * (fp[i][c] - fm[i][c]) / (2 * e);
      worst = std::max(worst, std::abs(y[c * nn + i] - fd));
      scale = std::max(scale, std::abs(fd));
    }
  ASSERT_GT(scale, 0);
  EXPECT_LT(worst, 1e-6 * scale) << "largest |A p - FD| " << worst << " of " << scale;
  // The springs' and the plate's parts are there: A p differs from M p well beyond round-off.
  double off = 0;
  for (int i = 0; i < nn; ++i)
    for (int c = 0; c < 3; ++c)
      off = std::max(off, std::abs(y[c * nn + i] - m.mass[i] * mfac * p[c * nn + i]));
  EXPECT_GT(off, 1e-3 * scale);
}

INSTANTIATE_TEST_SUITE_P(SpringsDampersPlanes, ImplicitSystemTest,
                         ::testing::Combine(::testing::Bool(), ::testing::Bool()),
                         [](const auto& info) {
                           return std::string(std::get<0>(info.param) ? "tets" : "lattice") +
                                  (std::get<1>(info.param) ? "_damped" : "_elastic");
                         });

}  // namespace
}  // namespace conica
