// Dynamics against analytic values: static deflection of a mass on a conical spring, energy
// behaviour of each integrator, implicit stability far past the explicit limit, probe contact
// equilibrium and stiffness, the standard linear solid's time constants, and the guard.
#include "core/step.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <random>

#include "core/body.h"

namespace conica {
namespace {

constexpr double kG = 9.81;

Model OneSpring(const SpringCard& card, double l0, double mass, Integrator integ, double dt) {
  SolverOptions o;
  o.integrator = integ;
  o.dt = dt;
  return make_spring_pair(card, l0, mass, o);
}

SpringCard ConicalSI() {
  SpringCard c;
  c.conical = ConicalCard{1e6, 2e-3, 4e-3, 16e-3, 20e-3, 3};  // K0 ~ 0.49 N/m, Pt ~ 3.3 mN
  c.stiffness_cap = 1e3;
  return c;
}

SpringCard HookeCard(double k) {
  SpringCard c;
  c.law = LawKind::kHooke;
  c.hooke_k = k;
  c.hooke_length = 1;
  return c;
}

TEST(StepTest, MassOnConicalSpringSettlesAtTheLawsStaticDeflection) {
  const SpringCard card = ConicalSI();
  const ConicalLaw law(card.conical);
  for (double load_ratio : {0.5, 3.0, 20.0}) {  // linear phase, early and deep nonlinear phase
    const double P = load_ratio * law.transition_load();
    const double mass = P / kG;
    for (Integrator integ : {Integrator::kSymplecticEuler, Integrator::kImplicitEuler}) {
      Model m = OneSpring(card, card.conical.L0, mass, integ, 1e-3);
      m.options.gravity = Vec3(0, 0, -kG);
      m.options.mass_damping = 20;  // 1/s: settles in a few seconds
      m.options.newton_iterations = 4;
      State s = make_state(m);
      Workspace ws(m);
      for (int t = 0; t < 8000; ++t) step(m, s, ws);
      const double delta = card.conical.L0 - s.x[1].z();
      EXPECT_NEAR(delta, law.deflection(P), 1e-6 * law.stroke())
          << integrator_name(integ) << " load " << load_ratio << " Pt";
      EXPECT_EQ(s.counters.rollbacks, 0u);
    }
  }
}

// A 4x4x4 Hooke lattice clamped at its base, released from a stretched state, no damping.
struct Oscillation {
  double e0, e_min, e_max;
  std::uint64_t rollbacks;
};
Oscillation Release(Integrator integ, double dt, int steps) {
  BodySpec b;
  b.mesh = make_box_lattice(Vec3(0.04, 0.04, 0.04), {4, 4, 4});
  b.density = 1000;
  SpringCard c = HookeCard(500);
  c.hooke_length = 0.01;
  b.groups.push_back({"all", c, kAllFamilies, {}, Vec3::Zero(), 10});
  FixedSelector base;
  base.kind = FixedSelector::Kind::kPlane;
  b.fixed.push_back(base);
  b.options.integrator = integ;
  b.options.dt = dt;
  b.options.max_speed = 1e3;
  Model m;
  EXPECT_EQ(build_model(b, &m), "");
  State s = make_state(m);
  for (int i = 0; i < m.num_nodes(); ++i)
    if (m.fixed[i] == 0) s.x[i].z() *= 1.05;  // 5 % stretch
  Workspace ws(m);
  Oscillation o;
  o.e0 = o.e_min = o.e_max = potential_energy(m, s) + kinetic_energy(m, s);
  for (int t = 0; t < steps; ++t) {
    step(m, s, ws);
    const double e = potential_energy(m, s) + kinetic_energy(m, s);
    o.e_min = std::min(o.e_min, e);
    o.e_max = std::max(o.e_max, e);
  }
  o.rollbacks = s.counters.rollbacks;
  return o;
}

TEST(StepTest, SymplecticEulerKeepsEnergyBoundedOnLinearSprings) {
  const Oscillation o = Release(Integrator::kSymplecticEuler, 2e-4, 20000);
  EXPECT_EQ(o.rollbacks, 0u);
  EXPECT_LT(o.e_max, 1.05 * o.e0);
  EXPECT_GT(o.e_min, 0.95 * o.e0);
}

TEST(StepTest, ExplicitEulerGainsEnergyAndTheGuardSeesIt) {
  const Oscillation o = Release(Integrator::kExplicitEuler, 2e-4, 20000);
  EXPECT_TRUE(o.e_max > 2 * o.e0 || o.rollbacks > 0) << "e_max/e0 = " << o.e_max / o.e0;
}

TEST(StepTest, ImplicitEulerStableAtHundredTimesTheExplicitLimit) {
  // Symplectic Euler is stable while h omega < 2. Choose k so that h omega = 200.
  const double mass = 1e-3, dt = 1e-3;
  const double omega = 200 / dt;
  const double k = mass * omega * omega;
  for (Integrator integ : {Integrator::kSymplecticEuler, Integrator::kImplicitEuler}) {
    Model m = OneSpring(HookeCard(k), 0.01, mass, integ, dt);
    m.options.newton_iterations = 1;  // linear spring: one Newton step is exact
    State s = make_state(m);
    s.x[1].z() = 0.011;  // 1 mm stretch
    Workspace ws(m);
    const double e0 = potential_energy(m, s);
    double e_max = e0;
    for (int t = 0; t < 1000; ++t) {
      step(m, s, ws);
      e_max = std::max(e_max, potential_energy(m, s) + kinetic_energy(m, s));
      ASSERT_TRUE(s.x[1].allFinite());
    }
    if (integ == Integrator::kSymplecticEuler) {
      EXPECT_GT(s.counters.rollbacks, 0u);  // blows up, detected and rolled back every time
    } else {
      EXPECT_EQ(s.counters.rollbacks, 0u);
      EXPECT_LE(e_max, e0 * (1 + 1e-9));    // backward Euler only dissipates
      EXPECT_NEAR(s.x[1].z(), 0.01, 1e-6);  // and comes to rest at the rest length
    }
  }
}

BodySpec Block(Integrator integ) {
  BodySpec b;
  b.mesh = make_box_lattice(Vec3(0.04, 0.04, 0.02), {8, 8, 4});
  b.density = 1000;
  SpringCard c = ConicalSI();
  // Strain mapping: a column of side L0 = 10 mm, so E ~ K0 / L0 ~ 1.2 kPa: soft tissue.
  c.conical = ConicalCard{5e7, 1e-3, 2e-3, 8e-3, 10e-3, 3};
  c.damping = 0;
  b.groups.push_back({"tissue", c, kAllFamilies, {}, Vec3::Zero(), 10});
  FixedSelector base;
  base.kind = FixedSelector::Kind::kPlane;
  b.fixed.push_back(base);
  b.options.integrator = integ;
  b.options.mass_damping = 30;
  b.probes.push_back(ProbeSpec{5e-3, 0});
  return b;
}

TEST(StepTest, ProbeReactionBalancesTheSupportsAtEquilibrium) {
  for (Integrator integ : {Integrator::kSymplecticEuler, Integrator::kImplicitEuler}) {
    Model m;
    ASSERT_EQ(build_model(Block(integ), &m), "");
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

TEST(StepTest, ContactStiffnessMatchesFiniteDifferences) {
  Model m;
  ASSERT_EQ(build_model(Block(Integrator::kSymplecticEuler), &m), "");
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

TEST(ContactLawTest, ShallowPressOnAFlatSurfaceIsTheNormalPenetration) {
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

TEST(ContactLawTest, ForceVanishesOnTheSphereFromEverySide) {
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

TEST(ContactLawTest, ForceIsLipschitzInTheProbePosition) {
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

TEST(ContactLawTest, StiffnessMatchesFiniteDifferencesOnEveryBranch) {
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

TEST(StepTest, ProbeTeleportingIntoTheBodyGivesBoundedForcesAndRecovers) {
  Model m;
  ASSERT_EQ(build_model(Block(Integrator::kSymplecticEuler), &m), "");
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
  ASSERT_EQ(build_model(Block(Integrator::kSymplecticEuler), &m), "");
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

// Standard linear solid on one spring: k_e (Hooke) parallel to a Maxwell branch (k_m, tau).
SpringCard Sls(double ke, double km, double tau) {
  SpringCard c = HookeCard(ke);
  c.maxwell_k = km;
  c.maxwell_tau = tau;
  return c;
}

TEST(StepTest, ForceRelaxationFollowsTheMaxwellTimeConstant) {
  const double ke = 100, km = 300, tau = 0.2, d0 = 1e-3, dt = 1e-4;
  Model m = OneSpring(Sls(ke, km, tau), 0.01, 1e-3, Integrator::kSymplecticEuler, dt);
  m.fixed[1] = 7;  // held at the step displacement
  m.free_axes[1] = Vec3::Zero();
  m.inv_mass[1] = 0;
  State s = make_state(m);
  s.x[1].z() = 0.01 - d0;
  Workspace ws(m);
  for (int t = 1; t <= 6000; ++t) {
    step(m, s, ws);
    if (t % 1000 == 0) {
      compute_forces(m, s, ws);
      const double expect = ke * d0 + km * d0 * std::exp(-t * dt / tau);
      EXPECT_NEAR(ws.load[0], expect, 2e-3 * expect) << "t = " << t * dt;
    }
  }
}

TEST(StepTest, CreepUnderConstantLoadFollowsTheRetardationTime) {
  const double ke = 100, km = 300, tau = 0.2, F = 0.1, dt = 1e-4;
  Model m = OneSpring(Sls(ke, km, tau), 0.01, 1e-5, Integrator::kSymplecticEuler, dt);
  m.options.gravity = Vec3(0, 0, -F / 1e-5);  // constant load F on node 1
  m.options.mass_damping = 5e3;               // 1/s: mu h = 0.5, inertia settles in ~1e-4 s << tau
  State s = make_state(m);
  Workspace ws(m);
  const double tau_c = tau * (ke + km) / ke;
  const int steps = static_cast<int>(std::round(tau_c / dt));
  for (int t = 0; t < steps; ++t) step(m, s, ws);
  const double d = 0.01 - s.x[1].z();
  const double expect = F / ke - (F / ke - F / (ke + km)) * std::exp(-1.0);
  EXPECT_NEAR(d, expect, 0.02 * expect);
}

TEST(StepTest, HysteresisLoopDissipatesTheAnalyticEnergy) {
  const double ke = 100, km = 300, tau = 0.05, d0 = 1e-3, dt = 1e-4;
  const double w = 1 / tau;  // omega tau = 1: the largest loop
  Model m = OneSpring(Sls(ke, km, tau), 0.01, 1e-3, Integrator::kSymplecticEuler, dt);
  m.fixed[1] = 7;
  m.free_axes[1] = Vec3::Zero();
  m.inv_mass[1] = 0;
  State s = make_state(m);
  Workspace ws(m);
  const int period = static_cast<int>(std::round(2 * M_PI / w / dt));
  double work = 0, last_d = 0, last_p = 0;
  for (int t = 1; t <= 6 * period; ++t) {
    const double d = d0 * std::sin(w * t * dt);
    s.x[1].z() = 0.01 - d;
    step(m, s, ws);
    compute_forces(m, s, ws);
    if (t > 5 * period) work += 0.5 * (ws.load[0] + last_p) * (d - last_d);  // last cycle
    last_d = d;
    last_p = ws.load[0];
  }
  const double expect = M_PI * d0 * d0 * km * (w * tau) / (1 + w * tau * w * tau);
  EXPECT_NEAR(work, expect, 0.03 * expect);
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
  std::uint64_t wall = 0;
  for (int t = 0; t < 300; ++t) {
    set_probe(s, 0, Vec3(0.02, 0.02, 0.025 - 2e-5 * t));
    const auto t0 = std::chrono::steady_clock::now();
    step(m, s, ws);
    wall +=
        std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - t0)
            .count();
  }
  std::uint64_t sum = 0;
  for (std::uint64_t ns : s.counters.stage_ns) sum += ns;
  EXPECT_LE(sum, wall);
  EXPECT_GE(sum, wall - 300 * 2000) << "more than 2 us per step outside every stage";
  EXPECT_GT(s.counters.stage_ns[static_cast<int>(Stage::kSprings)], 0u);
  EXPECT_GT(s.counters.stage_ns[static_cast<int>(Stage::kContact)], 0u);
  EXPECT_GT(s.counters.stage_ns[static_cast<int>(Stage::kIntegrate)], 0u);
  EXPECT_STREQ(stage_name(Stage::kHardStop), "hard_stop");
}

}  // namespace
}  // namespace conica
