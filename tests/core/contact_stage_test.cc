// The node contact stage: the per-node law on its own (step.h: node_contact) and a probe on a
// clamped block (its reaction against the supports, its stiffness against finite differences).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/body.h"
#include "core/step.h"
#include "probed_block.h"

namespace conica {
namespace {

using testing_meshes::ProbedBlock;

TEST(ContactStageTest, ProbeReactionBalancesTheSupportsAtEquilibrium) {
  for (Integrator integ : {Integrator::kSymplecticEuler, Integrator::kImplicitEuler}) {
    Model m;
    ASSERT_EQ(build_model(ProbedBlock(integ), &m), "");
    State s = make_state(m);
    Workspace ws(m);
    // Press 2 mm into the top face at its centre.
    set_probe(s, 0, Vec3(0.02, 0.02, 0.02 + 5e-3 - 2e-3));
    for (int t = 0; t < 3000; ++t) step(m, s, ws);
    compute_forces(m, s, ws);
    Vec3 support = Vec3::Zero();  // force of the supports on the body
    for (int i = 0; i < m.num_nodes(); ++i)
      if (m.fixed[i] == 7) support -= ws.force[i];
    const Vec3 f = s.probes[0].force;
    EXPECT_GT(f.z(), 0) << integrator_name(integ);  // pushed back up, out of the body
    EXPECT_GT(s.probes[0].contacts, 0);
    // Body at rest: the probe pushes it down with -f, the supports hold it with +f.
    EXPECT_NEAR((f - support).norm(), 0.0, 1e-3 * f.norm())
        << integrator_name(integ) << " probe " << f.transpose() << " support "
        << support.transpose() << " kinetic " << kinetic_energy(m, s);
    EXPECT_LT(std::abs(f.x()) + std::abs(f.y()), 1e-3 * f.z());  // symmetric press
    EXPECT_EQ(s.counters.rollbacks, 0u);
  }
}

TEST(ContactStageTest, ContactStiffnessMatchesFiniteDifferences) {
  Model m;
  ASSERT_EQ(build_model(ProbedBlock(Integrator::kSymplecticEuler), &m), "");
  State s = make_state(m);
  Workspace ws(m);
  const Vec3 c(0.0213, 0.0187, 0.02 + 5e-3 - 2.2e-3);  // off-lattice, several nodes in contact
  set_probe(s, 0, c);
  compute_forces(m, s, ws);
  const Mat3 K = s.probes[0].stiffness;
  ASSERT_GT(s.probes[0].contacts, 1);
  const double h = 1e-7;
  for (int a = 0; a < 3; ++a) {
    State sp = s, sm = s;
    set_probe(sp, 0, c + h * Vec3::Unit(a));
    set_probe(sm, 0, c - h * Vec3::Unit(a));
    compute_forces(m, sp, ws);
    compute_forces(m, sm, ws);
    const Vec3 fd = (sp.probes[0].force - sm.probes[0].force) / (2 * h);
    EXPECT_NEAR((K.col(a) - fd).norm(), 0.0, 1e-5 * K.norm()) << "column " << a;
  }
}

// The per-node contact law on its own (step.h): a surface node with outward normal n against a
// sphere of radius R around c. Random geometry from a fixed seed.
struct ContactSample {
  Vec3 n, c;
};

Vec3 RandomUnit(std::mt19937& rng) {
  std::normal_distribution<double> g;
  Vec3 w(g(rng), g(rng), g(rng));
  return w.normalized();
}

// Force on the probe from one node at x (zero when the node is outside the sphere).
Vec3 ProbeForceFromNode(const Vec3& x, const Vec3& n, const Vec3& c, double R, double kc) {
  Vec3 f, dir;
  Mat3 dfdc;
  return node_contact(x, n, c, R, kc, &f, &dfdc, &dir) ? Vec3(-f) : Vec3::Zero();
}

TEST(ContactStageTest, ShallowPressOnAFlatSurfaceIsTheNormalPenetration) {
  // Sphere pressed to depth D into the plane z = 0 (n = +z): a node at lateral distance rho is
  // inside by sqrt(R^2 - rho^2) - (R - D) along z, the geometric penetration, for D up to R / 2.
  const double R = 5e-3, kc = 300;
  const Vec3 n = Vec3::UnitZ();
  for (double D : {0.05 * R, 0.2 * R, 0.45 * R}) {
    const Vec3 c(0, 0, R - D);
    const double rim = std::sqrt(R * R - (R - D) * (R - D));
    for (int k = 0; k < 50; ++k) {
      const double rho = rim * (k + 0.5) / 50;
      const Vec3 x(rho * std::cos(k), rho * std::sin(k), 0);
      const double expect = std::sqrt(R * R - rho * rho) - (R - D);
      const Vec3 f = ProbeForceFromNode(x, n, c, R, kc);
      EXPECT_NEAR(f.z(), kc * expect, 1e-12 * kc * R) << "D " << D << " rho " << rho;
      EXPECT_NEAR(f.x() * f.x() + f.y() * f.y(), 0.0, 1e-30);
    }
  }
}

TEST(ContactStageTest, ForceVanishesOnTheSphereFromEverySide) {
  // A node just inside the sphere, at any angle to its normal (the far side, a = u.n > 0,
  // included): the force goes to zero with the radial depth R - r, at most 2 k_c (R - r).
  std::mt19937 rng(7);
  const double R = 4e-3, kc = 500;
  for (int k = 0; k < 2000; ++k) {
    const Vec3 n = RandomUnit(rng), w = RandomUnit(rng), c(1e-3, -2e-3, 3e-3);
    for (double eps : {1e-2, 1e-5, 1e-9}) {
      const Vec3 x = c + R * (1 - eps) * w;
      const double depth = R - (x - c).norm();
      const Vec3 f = ProbeForceFromNode(x, n, c, R, kc);
      ASSERT_LE(f.norm(), 2 * kc * depth * (1 + 1e-9)) << "u.n/r " << w.dot(n) << " eps " << eps;
      ASSERT_GE(f.dot(n), 0.0);  // the probe is pushed out of the body, never into it
    }
  }
}

TEST(ContactStageTest, ForceIsLipschitzInTheProbePosition) {
  // |f(c1) - f(c2)| <= (1 + sqrt(3)) k_c |c1 - c2| for a surface node (bound derived in step.h),
  // for probe moves that cross the sphere's surface as well as ones inside it. The uncapped law
  // fails this: a node entering on the far side jumps from 0 to 2 k_c a.
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> unit(0, 1);
  const double R = 5e-3, kc = 200, L = (1 + std::sqrt(3.0)) * kc;
  double worst = 0;
  for (int k = 0; k < 20000; ++k) {
    const Vec3 n = RandomUnit(rng);
    const Vec3 c1 = R * (0.2 + 0.85 * unit(rng)) * RandomUnit(rng);  // node at the origin
    const Vec3 c2 = c1 + R * 1e-3 * unit(rng) * RandomUnit(rng);
    const Vec3 f1 = ProbeForceFromNode(Vec3::Zero(), n, c1, R, kc);
    const Vec3 f2 = ProbeForceFromNode(Vec3::Zero(), n, c2, R, kc);
    worst = std::max(worst, (f1 - f2).norm() / (L * (c1 - c2).norm()));
  }
  EXPECT_LE(worst, 1 + 1e-6);
  EXPECT_GT(worst, 0.5);  // the samples reach the steep parts of the law
}

TEST(ContactStageTest, StiffnessMatchesFiniteDifferencesOnEveryBranch) {
  // d(probe force)/dc against central differences, surface and interior nodes, capped and not.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> unit(0, 1);
  const double R = 5e-3, kc = 200, h = 1e-9;
  int capped = 0, uncapped = 0;
  for (int k = 0; k < 3000; ++k) {
    const bool surface = k % 3 != 0;
    const Vec3 n = surface ? RandomUnit(rng) : Vec3::Zero();
    const Vec3 c = R * (0.05 + 0.9 * unit(rng)) * RandomUnit(rng);
    Vec3 f, dir;
    Mat3 K;
    ASSERT_TRUE(node_contact(Vec3::Zero(), n, c, R, kc, &f, &K, &dir));
    if (surface) {
      const Vec3 u = -c;
      const double a = u.dot(n), e = a + std::sqrt(a * a - u.squaredNorm() + R * R);
      const double cap = kContactDepthCap * (R - u.norm());
      if (std::abs(e - cap) < 1e-6 * R) continue;  // at the kink: no derivative
      ++(e < cap ? uncapped : capped);
    }
    for (int j = 0; j < 3; ++j) {
      const Vec3 fd = (ProbeForceFromNode(Vec3::Zero(), n, c + h * Vec3::Unit(j), R, kc) -
                       ProbeForceFromNode(Vec3::Zero(), n, c - h * Vec3::Unit(j), R, kc)) /
                      (2 * h);
      ASSERT_NEAR((K.col(j) - fd).norm(), 0.0, 1e-5 * kc) << "sample " << k << " column " << j;
    }
  }
  EXPECT_GT(capped, 100);
  EXPECT_GT(uncapped, 100);
}

}  // namespace
}  // namespace conica
