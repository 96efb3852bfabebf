// Coulomb friction on rigid plates (PlaneSpec::friction, core/contact_stage.cc): stick and slip
// of a block pressed and dragged by a plate, against the analytic penalty stick law and Coulomb's
// limit; compression with friction between the frictionless and the bonded plate; a block on a
// frictional floor against the rigid-body slide, with every integrator.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

#include "core/step.h"
#include "hooke_block.h"
#include "lab/quasi_static.h"

namespace conica::lab {
namespace {

BodySpec Block(int nx, int nz, double side, double height) {
  return HookeBlock(nx, nz, side, height);
}

FixedSelector BasePlane(int axes) {
  FixedSelector base;
  base.kind = FixedSelector::Kind::kPlane;
  base.offset = 0;
  base.axes = axes;
  return base;
}

// A one-layer block (2 x 2 cells, 20 mm square, 10 mm high) clamped at its base is pressed 1 mm
// by a frictional top plate (mu 0.3) whose penalty is soft against the block (so every top node
// takes the same depth and the same tangential stretch: a uniform contact), then the plate is
// dragged along x by s. The plate's law (core/step_detail.h) for N nodes: while nothing slips
// F_t = mu F_n tanh(s / s*), s* = mu F_n / (N k_p) (the penalty N k_p s for small drags, below
// mu F_n throughout); the nodes slide past s = 4 s*, and from there F_t = mu F_n and the stick
// points travel s - 4 s* through the plate.
TEST(PlateFrictionTest, DraggedPlateSticksBelowMuFnAndSlidesAtMuFn) {
  const double mu = 0.3, press = 1e-3, kp = 0.02;  // -, m, N/m per node
  BodySpec spec = Block(2, 1, 0.02, 0.01);
  spec.fixed = {BasePlane(7)};
  ensure_top_plate(&spec);
  spec.planes[0].friction = mu;
  spec.planes[0].stiffness = kp;
  Model m;
  ASSERT_EQ(build_model(spec, &m), "");
  const double start = m.planes[0].offset;
  const int press_steps = 10, drag_steps = 25;
  const double du = press / press_steps;          // m, travel per increment
  const double ds = 8 * mu * press / drag_steps;  // m, drag per increment
  auto drag = [&](double u) { return std::max(0.0, u - press) * ds / du; };
  LoadFn load = [&](const Model&, State& s, double u) {  // press, then drag along x
    s.planes[0].offset = start + std::min(u, press);
    s.planes[0].slide = Vec3(drag(u), 0, 0);
  };
  ReactionFn magnitude = [](const Model&, const State& s, const Workspace&) {
    return s.planes[0].force.norm();  // what equilibrium is judged against
  };
  struct Sample {
    double s, ft, fn, slip;
    int contacts;
  };
  std::vector<Sample> rec;
  std::vector<Vec3> stick0;
  int j = 0;
  IncrementFn record = [&](const Model&, const State& s) {
    ++j;
    const PlaneState& pl = s.planes[0];
    if (j == press_steps) stick0 = pl.stick;
    if (j <= press_steps) return;
    double slip = 0;  // the largest travel of a stick point through the plate along it (m)
    for (size_t i = 0; i < pl.stick.size(); ++i) {
      if (pl.offset + s.x[i].z() <= 0) continue;  // in front of the plate (normal -z)
      Vec3 d = pl.stick[i] - stick0[i];
      d.z() = 0;
      slip = std::max(slip, d.norm());
    }
    rec.push_back({pl.slide.x(), -pl.force.x(), pl.force.z(), slip, pl.contacts});
  };
  QuasiStaticOptions o;
  o.samples = press_steps + drag_steps;
  o.tolerance = 1e-7;
  QuasiStaticStats st;
  quasi_static_curve(m, load, magnitude, (press_steps + drag_steps) * du, o, &st, record);
  EXPECT_EQ(st.unconverged, 0);
  ASSERT_EQ(rec.size(), static_cast<size_t>(drag_steps));
  const int top_nodes = 9;
  int stuck = 0, sliding = 0;
  for (const Sample& r : rec) {
    ASSERT_EQ(r.contacts, top_nodes);
    const double s_star = mu * r.fn / (top_nodes * kp), onset = 4 * s_star;
    if (r.s < 0.95 * onset) {
      ++stuck;
      EXPECT_LT(r.ft, mu * r.fn) << "drag " << r.s;
      EXPECT_EQ(r.slip, 0.0) << "no slip below mu F_n, drag " << r.s;
      const double law = mu * r.fn * std::tanh(r.s / s_star);
      EXPECT_NEAR(r.ft, law, 0.01 * law) << "drag " << r.s;
    } else if (r.s > 1.1 * onset) {
      ++sliding;
      EXPECT_NEAR(r.ft, mu * r.fn, 0.02 * mu * r.fn) << "|F_t| = mu F_n, drag " << r.s;
      EXPECT_NEAR(r.slip, r.s - onset, 0.05 * s_star) << "drag " << r.s;
    }
  }
  const Sample& last = rec.back();
  std::printf("drag %.3g mm: F_t / (mu F_n) = %.5f, slip %.4g mm\n", last.s * 1e3,
              last.ft / (mu * last.fn), last.slip * 1e3);
  EXPECT_GE(stuck, 5);
  EXPECT_GE(sliding, 5);
}

// A block (3 x 3 x 2 cells, 30 x 30 x 20 mm) on a frictionless base, compressed 10 % by a top
// plate quasi-statically: frictionless, with friction mu, or bonded to the top face. The result
// of build_model and the whole curve (force, and the top face's largest lateral displacement).
struct Compression {
  std::vector<double> force;
  double spread = 0;  // m
};
Compression Compress(double mu, bool bonded) {
  BodySpec spec = Block(3, 2, 0.03, 0.02);
  ensure_top_plate(&spec);
  FixedSelector pin;  // against rigid motion in the base plane
  pin.kind = FixedSelector::Kind::kNodes;
  pin.nodes = {0};
  pin.axes = 3;
  FixedSelector pin2 = pin;
  pin2.nodes = {3};
  pin2.axes = 2;
  spec.fixed = {BasePlane(4), pin, pin2};
  spec.planes[0].friction = mu;
  if (bonded) {
    spec.planes[0].bonded = true;
    spec.planes[0].bond_tolerance = 1e-9;
  }
  Model m;
  EXPECT_EQ(build_model(spec, &m), "");
  m.planes[0].stiffness = 1e5;  // N/m per node: a plate penetration < 1e-6 m, 5e-4 of the travel
  QuasiStaticOptions o;
  o.samples = 5;
  o.tolerance = 1e-6;
  QuasiStaticStats st;
  Compression r;
  for (const CurvePoint& p : quasi_static_curve(m, plate_load(m), plate_reaction(), 2e-3, o, &st))
    r.force.push_back(p.force);
  EXPECT_EQ(st.unconverged, 0) << "mu " << mu;
  for (int i = 0; i < m.num_nodes(); ++i)
    if (m.rest[i].z() > 0.02 - 1e-9)
      r.spread = std::max(r.spread, std::hypot(st.positions[i].x() - m.rest[i].x(),
                                               st.positions[i].y() - m.rest[i].y()));
  return r;
}

TEST(PlateFrictionTest, CompressionWithFrictionLiesBetweenFrictionlessAndBonded) {
  const Compression free = Compress(0, false), glued = Compress(0, true);
  ASSERT_GT(glued.force.back(), free.force.back() * 1.01)
      << "bonding must stiffen the block for the test to mean anything";
  ASSERT_GT(free.spread, 0);
  EXPECT_LT(glued.spread, 1e-12);
  std::vector<Compression> runs;
  const std::vector<double> mus = {0.2, 1.0, 10.0};
  for (double mu : mus) runs.push_back(Compress(mu, false));
  for (size_t k = 0; k < mus.size(); ++k) {
    const Compression& r = runs[k];
    for (size_t j = 1; j < r.force.size(); ++j) {
      EXPECT_GT(r.force[j], free.force[j]) << "mu " << mus[k] << " sample " << j;
      EXPECT_LT(r.force[j], glued.force[j] * (1 + 1e-6)) << "mu " << mus[k] << " sample " << j;
      if (k > 0) {
        EXPECT_GE(r.force[j], runs[k - 1].force[j] * (1 - 1e-6)) << "rises with mu";
      }
    }
    EXPECT_LT(r.spread, free.spread) << "friction holds the face, mu " << mus[k];
    if (k > 0) {
      EXPECT_LE(r.spread, runs[k - 1].spread * (1 + 1e-6)) << "mu " << mus[k];
    }
  }
  std::printf("force at 10 %%: frictionless %.5g N, bonded %.5g N; spread %.3g um, %.3g um\n",
              free.force.back(), glued.force.back(), free.spread * 1e6, glued.spread * 1e6);
  for (size_t k = 0; k < mus.size(); ++k)
    std::printf("mu %.3g: %.5g N (%.3f %% below bonded), spread %.3g um\n", mus[k],
                runs[k].force.back(), 100 * (1 - runs[k].force.back() / glued.force.back()),
                runs[k].spread * 1e6);
  // Sticking everywhere (mu 10) is the bonded face but for the stick penalty's compliance.
  const Compression& stuck = runs.back();
  for (size_t j = 1; j < stuck.force.size(); ++j)
    EXPECT_NEAR(stuck.force[j], glued.force[j], 0.01 * glued.force[j]) << "sample " << j;
  EXPECT_LT(stuck.spread, 0.05 * free.spread);
}

// Coulomb's law itself, with every integrator: a block resting under gravity on a frictional
// floor and pushed sideways by a body force g_x. Below mu g it stays (the floor carries the
// push); above it slides with the floor's tangential force mu times its normal force,
// travelling (g_x - mu g) t^2 / 2 like a rigid block.
class FloorFriction : public ::testing::TestWithParam<Integrator> {};

TEST_P(FloorFriction, BlockSticksBelowMuGAndSlidesAtCoulombsLawAbove) {
  const Integrator integrator = GetParam();
  const bool implicit = integrator == Integrator::kImplicitEuler;
  const double mu = 0.3, g = 9.81, t_push = 0.1;  // -, m/s^2, s
  for (const double push : {0.2, 0.5}) {          // g_x / g
    BodySpec spec = Block(2, 1, 0.02, 0.01);
    spec.fixed.clear();
    PlaneSpec floor;
    floor.normal = Vec3::UnitZ();
    floor.offset = 0;
    floor.friction = mu;
    floor.stiffness = 2e3;  // N/m per node
    spec.planes = {floor};
    spec.options.integrator = integrator;
    spec.options.dt = implicit ? 1e-3 : 1e-5;
    spec.options.newton_iterations = 3;
    spec.options.cg_iterations = 200;
    spec.options.cg_tolerance = 1e-12;
    spec.options.mass_damping = 0;
    spec.options.active_region = false;
    spec.options.gravity = Vec3(0, 0, -g);
    Model m;
    ASSERT_EQ(build_model(spec, &m), "");
    State s = make_state(m);
    Workspace ws(m);
    double total_mass = 0;
    for (double mi : m.mass) total_mass += mi;
    // Settle on the floor with no push, then push.
    const int settle = static_cast<int>(std::lround(0.3 / m.options.dt));
    const double keep = std::exp(-m.options.dt / 3e-3);  // velocity decay, 3 ms
    for (int k = 0; k < settle; ++k) {
      for (Vec3& v : s.v) v *= keep;
      step(m, s, ws);
    }
    for (Vec3& v : s.v) v.setZero();
    m.options.gravity = Vec3(push * g, 0, -g);
    Vec3 x0 = Vec3::Zero();
    for (const Vec3& x : s.x) x0 += x / m.num_nodes();
    const std::vector<Vec3> stick0 = s.planes[0].stick;
    const int n = static_cast<int>(std::lround(t_push / m.options.dt));
    Vec3 impulse = Vec3::Zero();  // N s, of the floor on the body
    for (int k = 0; k < n; ++k) {
      step(m, s, ws);
      impulse -= s.planes[0].force * m.options.dt;
    }
    Vec3 x1 = Vec3::Zero();
    for (const Vec3& x : s.x) x1 += x / m.num_nodes();
    const Vec3 F = impulse / t_push;  // mean force of the floor on the body
    const double W = total_mass * g;
    EXPECT_NEAR(F.z(), W, 0.02 * W) << "push " << push;
    EXPECT_EQ(s.counters.rollbacks, 0u);
    if (push < mu) {
      EXPECT_NEAR(F.x(), -push * W, 0.02 * W) << "sticking, push " << push;
      double slip = 0;  // m, the largest travel of a bottom node's stick point
      for (int i = 0; i < m.num_nodes(); ++i)
        if (m.rest[i].z() < 1e-9) slip = std::max(slip, (s.planes[0].stick[i] - stick0[i]).norm());
      // The block is soft against the floor, so its edge nodes slip a little (partial slip, as
      // in Cattaneo-Mindlin contact): within 1 % of what the push would slide it frictionless.
      EXPECT_LT(slip, 0.01 * 0.5 * push * g * t_push * t_push) << "a stuck block does not slide";
      // Its centre moves by the elastic shear of the block only (G A / H = 80 N/m: 2.5e-5 m).
      EXPECT_LT(std::abs(x1.x() - x0.x()), 5e-5);
    } else {
      EXPECT_NEAR(F.x(), -mu * F.z(), 0.02 * mu * F.z()) << "sliding: |F_t| = mu F_n";
      const double travel = 0.5 * (push - mu) * g * t_push * t_push;
      EXPECT_NEAR(x1.x() - x0.x(), travel, 0.05 * travel) << "Coulomb slide";
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Integrators, FloorFriction,
                         ::testing::Values(Integrator::kImplicitEuler, Integrator::kSymplecticEuler,
                                           Integrator::kExplicitEuler));

}  // namespace
}  // namespace conica::lab
