// State is the whole dynamic state: a copy taken mid-run and stepped again with the same inputs,
// with a fresh Workspace or with the one that has already stepped past it, gives bit-identical
// states, with every option on (active region, multi-rate or frozen far field, Maxwell branches,
// surface contact with friction and node contact, volume and shear terms, each integrator, BDF2).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <vector>

#include "core/body.h"
#include "core/step.h"
#include "lattice_meshes.h"

namespace conica {
namespace {

SpringCard ViscousCard() {
  SpringCard c;
  c.conical = ConicalCard{5e7, 1e-3, 2e-3, 8e-3, 10e-3, 3};
  c.stiffness_cap = 1e3;
  c.damping = 2e-3;
  c.maxwell_k = 400;
  c.maxwell_tau = 0.02;
  return c;
}

using testing_meshes::Tetrahedralised;

struct Config {
  const char* name;
  bool tetrahedra;
  Integrator integrator;
  bool region;
  int far_every;      // options.active_far_every
  bool elements;      // bulk and shear terms
  bool bdf2 = false;  // options.bdf2 (implicit)
};

Model Build(const Config& c) {
  BodySpec b;
  // The active region needs room to leave part of the body asleep.
  b.mesh = c.region ? make_box_lattice(Vec3(0.08, 0.08, 0.02), {16, 16, 4})
                    : make_box_lattice(Vec3(0.04, 0.04, 0.02), {8, 8, 4});
  if (c.tetrahedra) b.mesh = Tetrahedralised(b.mesh);
  b.groups.push_back({"tissue", ViscousCard(), kAllFamilies, {}, Vec3::Zero(), 10});
  FixedSelector base;
  base.kind = FixedSelector::Kind::kPlane;
  b.fixed.push_back(base);
  b.options.integrator = c.integrator;
  b.options.mass_damping = 20;
  b.options.active_region = c.region;
  b.options.active_tolerance = 3e-3;  // m: a soft card, a coarse tolerance
  b.options.active_far_every = c.far_every;
  b.options.bdf2 = c.bdf2;
  if (c.integrator == Integrator::kImplicitEuler) {
    b.options.newton_iterations = 1;
    b.options.cg_iterations = 20;
  } else if (c.elements || c.integrator == Integrator::kExplicitEuler) {
    b.options.substeps = 4;
  }
  if (c.elements) {
    b.bulk_modulus = 2e4;
    b.shear_modulus = 3e3;
  }
  ProbeSpec surface;  // a sphere through a proxy, with friction
  surface.radius = 4e-3;
  surface.contact = ContactModel::kSurface;
  surface.friction = 0.4;
  ProbeSpec nodes;  // the node penalty
  nodes.contact = ContactModel::kNodes;
  nodes.radius = 6e-3;
  nodes.stiffness = 50;
  b.probes = {surface, nodes};
  PlaneSpec plate;  // a side plate the body touches when pressed
  plate.normal = Vec3(-1, 0, 0);
  plate.offset = c.region ? -0.0805 : -0.0405;
  b.planes = {plate};
  Model m;
  EXPECT_EQ(build_model(b, &m), "") << c.name;
  return m;
}

// Press, slide and lift for the sliding probe; a slow press for the node probe.
void Drive(State& s, int tick) {
  const double t = tick * 1e-3;
  const double depth = 3e-3 * std::min(1.0, t / 0.06);
  const Vec3 a(0.015 + 0.1 * std::max(0.0, t - 0.06), 0.02, 0.02 + 4e-3 - depth);
  set_probe(s, 0, a, true);
  set_probe(s, 1, Vec3(0.03, 0.012, 0.02 + 6e-3 - 1.5e-3 * std::min(1.0, t / 0.08)), tick > 10);
}

template <class T>
bool Same(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

// Bitwise equality of everything the step reads back.
void ExpectIdentical(const State& a, const State& b, const char* what) {
  EXPECT_EQ(a.tick, b.tick) << what;
  EXPECT_TRUE(Same(a.x, b.x)) << what << ": positions differ";
  EXPECT_TRUE(Same(a.v, b.v)) << what << ": velocities differ";
  EXPECT_TRUE(Same(a.maxwell, b.maxwell)) << what << ": Maxwell branches differ";
  EXPECT_TRUE(Same(a.x_prev, b.x_prev) && Same(a.v_prev, b.v_prev) && a.has_prev == b.has_prev)
      << what << ": BDF2's previous step differs";
  for (size_t k = 0; k < a.probes.size(); ++k) {
    EXPECT_EQ(std::memcmp(a.probes[k].force.data(), b.probes[k].force.data(), sizeof(Vec3)), 0)
        << what << ": probe " << k << " force";
    EXPECT_EQ(std::memcmp(a.probes[k].proxy.data(), b.probes[k].proxy.data(), sizeof(Vec3)), 0)
        << what << ": probe " << k << " proxy";
  }
  EXPECT_TRUE(Same(a.region.awake, b.region.awake)) << what << ": awake sets differ";
  EXPECT_EQ(a.region.far_phase, b.region.far_phase) << what;
  EXPECT_EQ(a.counters.rollbacks, b.counters.rollbacks) << what;
  EXPECT_EQ(a.counters.hard_stops, b.counters.hard_stops) << what;
  EXPECT_EQ(a.counters.cg_iterations, b.counters.cg_iterations) << what;
}

class SnapshotTest : public ::testing::TestWithParam<Config> {};

TEST_P(SnapshotTest, ReplayFromACopyIsBitIdentical) {
  const Config c = GetParam();
  const Model m = Build(c);
  ASSERT_GT(m.num_nodes(), 0);
  State s = make_state(m);
  Workspace ws(m);
  constexpr int kBefore = 90, kAfter = 60;
  for (int t = 0; t < kBefore; ++t) {
    Drive(s, t);
    step(m, s, ws);
  }
  const State snapshot = s;
  double f0 = 0, f1 = 0;
  int fewest_awake = m.num_nodes();
  for (int t = kBefore; t < kBefore + kAfter; ++t) {
    Drive(s, t);
    step(m, s, ws);
    f0 = std::max(f0, s.probes[0].force.norm());
    f1 = std::max(f1, s.probes[1].force.norm());
    int awake = 0;
    for (auto a : s.region.awake) awake += a;
    fewest_awake = std::min(fewest_awake, awake);
  }
  // The run did something worth replaying: both tools press, and the region (when on) leaves
  // part of the body asleep. Explicit Euler is the integrator that fails first: its guard trips
  // and rolls back, which the replay must reproduce too.
  if (c.integrator != Integrator::kExplicitEuler) {
    EXPECT_GT(f0, 1e-3) << c.name;
    EXPECT_GT(f1, 1e-3) << c.name;
    EXPECT_EQ(s.counters.rollbacks, 0u) << c.name;
  } else {
    EXPECT_GT(s.counters.rollbacks, 0u) << c.name << ": explicit Euler was expected to fail here";
  }
  if (c.region) {
    EXPECT_LT(fewest_awake, m.num_nodes() / 2) << c.name;
  }

  State fresh = snapshot;  // a new Workspace
  Workspace ws_fresh(m);
  State reused = snapshot;  // the Workspace that already stepped past the snapshot
  for (int t = kBefore; t < kBefore + kAfter; ++t) {
    Drive(fresh, t);
    step(m, fresh, ws_fresh);
    Drive(reused, t);
    step(m, reused, ws);
  }
  ExpectIdentical(s, fresh, "fresh workspace");
  ExpectIdentical(s, reused, "reused workspace");
}

INSTANTIATE_TEST_SUITE_P(
    EveryOption, SnapshotTest,
    ::testing::Values(
        Config{"lattice_symplectic_multirate", false, Integrator::kSymplecticEuler, true, 0, false},
        Config{"lattice_symplectic_frozen", false, Integrator::kSymplecticEuler, true, -1, false},
        Config{"lattice_explicit_whole", false, Integrator::kExplicitEuler, false, 0, false},
        Config{"tets_symplectic_multirate", true, Integrator::kSymplecticEuler, true, 0, false},
        Config{"tets_symplectic_elements", true, Integrator::kSymplecticEuler, false, 0, true},
        Config{"tets_implicit_elements", true, Integrator::kImplicitEuler, false, 0, true},
        Config{"lattice_implicit", false, Integrator::kImplicitEuler, false, 0, false},
        Config{"tets_bdf2_elements", true, Integrator::kImplicitEuler, false, 0, true, true}),
    [](const auto& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace conica
