// The integrators against analytic values: static deflection of a mass on a conical spring, the
// energy behaviour of each integrator, implicit stability far past the explicit limit, and the
// standard linear solid's time constants (Maxwell branches).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/body.h"
#include "core/step.h"

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

TEST(IntegrateTest, MassOnConicalSpringSettlesAtTheLawsStaticDeflection) {
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

TEST(IntegrateTest, SymplecticEulerKeepsEnergyBoundedOnLinearSprings) {
  const Oscillation o = Release(Integrator::kSymplecticEuler, 2e-4, 20000);
  EXPECT_EQ(o.rollbacks, 0u);
  EXPECT_LT(o.e_max, 1.05 * o.e0);
  EXPECT_GT(o.e_min, 0.95 * o.e0);
}

TEST(IntegrateTest, ExplicitEulerGainsEnergyAndTheGuardSeesIt) {
  const Oscillation o = Release(Integrator::kExplicitEuler, 2e-4, 20000);
  EXPECT_TRUE(o.e_max > 2 * o.e0 || o.rollbacks > 0) << "e_max/e0 = " << o.e_max / o.e0;
}

TEST(IntegrateTest, ImplicitEulerStableAtHundredTimesTheExplicitLimit) {
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

// A damped oscillator released from rest, m x'' + mu m x' + k x = 0 (a mass on a Hooke spring,
// the scene's mass damping mu), integrated over two periods, against the analytic
// x(t) = x0 exp(-mu t / 2) (cos w t + mu / (2 w) sin w t), w = sqrt(k / m - mu^2 / 4): the largest
// error over the steps falls with the step as h for backward Euler and as h^2 for BDF2 (whose
// first step is backward Euler's: an O(h^2) error that leaves the order as it is).
TEST(IntegrateTest, Bdf2ConvergesAtSecondOrderBackwardEulerAtFirst) {
  const double mass = 1e-3, omega0 = 100, mu = 20, l0 = 0.01, x0 = 1e-3;  // kg, 1/s, 1/s, m, m
  const double w = std::sqrt(omega0 * omega0 - 0.25 * mu * mu);
  const double T = 2 * 2 * M_PI / w;
  auto exact = [&](double t) {
    return x0 * std::exp(-0.5 * mu * t) * (std::cos(w * t) + 0.5 * mu / w * std::sin(w * t));
  };
  auto error = [&](bool bdf2, int n) {
    const double h = T / n;
    Model m = OneSpring(HookeCard(mass * omega0 * omega0), l0, mass, Integrator::kImplicitEuler, h);
    m.options.bdf2 = bdf2;
    m.options.mass_damping = mu;
    m.options.newton_iterations = 1;  // linear: one Newton step solves the step
    State s = make_state(m);
    s.x[1].z() = l0 + x0;
    Workspace ws(m);
    double worst = 0;
    for (int t = 1; t <= n; ++t) {
      step(m, s, ws);
      worst = std::max(worst, std::abs(s.x[1].z() - l0 - exact(t * h)));
    }
    EXPECT_EQ(s.counters.rollbacks, 0u);
    return worst;
  };
  for (bool bdf2 : {false, true}) {
    const double e1 = error(bdf2, 200), e2 = error(bdf2, 400), e3 = error(bdf2, 800);
    std::printf("%s: largest errors %.3g %.3g %.3g m in 200, 400, 800 steps (ratios %.2f, %.2f)\n",
                bdf2 ? "BDF2" : "backward Euler", e1, e2, e3, e1 / e2, e2 / e3);
    const double order = bdf2 ? 4 : 2;
    EXPECT_NEAR(e1 / e2, order, 0.1 * order) << bdf2;
    EXPECT_NEAR(e2 / e3, order, 0.1 * order) << bdf2;
  }
  EXPECT_LT(error(true, 400), 0.05 * error(false, 400));
}

// Standard linear solid on one spring: k_e (Hooke) parallel to a Maxwell branch (k_m, tau).
SpringCard Sls(double ke, double km, double tau) {
  SpringCard c = HookeCard(ke);
  c.maxwell_k = km;
  c.maxwell_tau = tau;
  return c;
}

TEST(IntegrateTest, ForceRelaxationFollowsTheMaxwellTimeConstant) {
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
      EXPECT_NEAR(ws.springs.load[0], expect, 2e-3 * expect) << "t = " << t * dt;
    }
  }
}

TEST(IntegrateTest, CreepUnderConstantLoadFollowsTheRetardationTime) {
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

TEST(IntegrateTest, HysteresisLoopDissipatesTheAnalyticEnergy) {
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
    if (t > 5 * period) work += 0.5 * (ws.springs.load[0] + last_p) * (d - last_d);  // last cycle
    last_d = d;
    last_p = ws.springs.load[0];
  }
  const double expect = M_PI * d0 * d0 * km * (w * tau) / (1 + w * tau * w * tau);
  EXPECT_NEAR(work, expect, 0.03 * expect);
}

}  // namespace
}  // namespace conica
