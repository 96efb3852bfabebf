// The physics core allocates nothing inside a step: global operator new is counted while steps
// run, for every integrator, with dampers, Maxwell branches, probes in contact and plates.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <limits>
#include <new>

#include "../counting_new.h"
#include "core/body.h"
#include "core/step.h"
#include "probed_block.h"
#include "tissue_bar.h"

namespace conica {
namespace {

// Operator new calls made while f runs.
template <class F>
long AllocationsDuring(F&& f) {
  return counting_new::during(f);
}

TEST(AllocationTest, StepAllocatesNothing) {
  for (Integrator integ :
       {Integrator::kSymplecticEuler, Integrator::kExplicitEuler, Integrator::kImplicitEuler})
    for (double kappa : {0.0, 2e4})  // Pa: without and with volume, spread and shear stiffness
      for (bool bdf2 : {false, true}) {
        if (bdf2 && integ != Integrator::kImplicitEuler) continue;
        BodySpec b;
        b.bulk_modulus = kappa;
        b.spread_modulus = kappa;
        b.shear_modulus = kappa / 4;
        b.mesh = make_box_lattice(Vec3(0.04, 0.04, 0.02), {4, 4, 2});
        SpringCard conical;
        conical.conical = ConicalCard{2e8, 1e-3, 2e-3, 8e-3, 10e-3, 3};
        conical.stiffness_cap = 20;
        conical.damping = 0.01;
        conical.maxwell_k = 20;
        conical.maxwell_tau = 0.1;
        SpringCard hooke;
        hooke.law = LawKind::kHooke;
        hooke.hooke_k = 40;
        hooke.hooke_length = 0.01;
        b.groups.push_back({"edges", hooke, kEdge, {}, Vec3::Zero(), 10});
        b.groups.push_back({"rest", conical, kAllFamilies, {}, Vec3::Zero(), 10});
        FixedSelector base;
        base.kind = FixedSelector::Kind::kPlane;
        b.fixed.push_back(base);
        b.options.integrator = integ;
        b.options.bdf2 = bdf2;
        b.options.substeps = 2;
        b.options.mass_damping = 5;
        b.probes.push_back(ProbeSpec{0.006, 0, ContactModel::kNodes});
        PlaneSpec side;
        side.normal = Vec3::UnitX();
        side.offset = 0.001;  // touches the x = 0 face
        b.planes.push_back(side);
        Model m;
        ASSERT_EQ(build_model(b, &m), "");
        State s = make_state(m);
        Workspace ws(m);
        set_probe(s, 0, Vec3(0.02, 0.02, 0.023));
        for (int i = 0; i < 20; ++i) step(m, s, ws);  // warm up
        int contact_steps = 0;
        const long allocations = AllocationsDuring([&] {
          for (int i = 0; i < 100; ++i) {
            set_probe(s, 0, Vec3(0.02, 0.02, 0.023 - 1e-5 * i));
            step(m, s, ws);
            contact_steps += s.probes[0].contacts > 0;
          }
          compute_forces(m, s, ws);
        });
        EXPECT_EQ(allocations, 0) << integrator_name(integ) << ", bulk modulus " << kappa
                                  << (bdf2 ? ", BDF2" : "");
        EXPECT_GT(contact_steps, 0) << integrator_name(integ);  // the contact stage did run
        EXPECT_GT(s.planes[0].contacts, 0);
        // The check itself works: a vector growing while counting is seen.
        EXPECT_GT(AllocationsDuring([] { std::vector<double> grow(100); }), 0);
      }
}

// Surface tools: a bonded punch pressed and lifted, a plane pressed, every integrator: the proxy
// stage, the bonds (growing while the tool presses) and the layer allocate nothing.
TEST(AllocationTest, SurfaceToolStepAllocatesNothing) {
  for (Integrator integ :
       {Integrator::kSymplecticEuler, Integrator::kExplicitEuler, Integrator::kImplicitEuler})
    for (ToolShape shape : {ToolShape::kPunch, ToolShape::kPlane}) {
      BodySpec b = testing_meshes::ProbedBlock(integ);  // 40 x 40 x 20 mm, top at z = 20 mm
      ProbeSpec& p = b.probes[0];
      p.radius = 0.012;
      p.contact = ContactModel::kSurface;
      p.shape = shape;
      p.bonded = shape == ToolShape::kPunch;
      Model m;
      ASSERT_EQ(build_model(b, &m), "");
      State s = make_state(m);
      Workspace ws(m);
      set_probe(s, 0, Vec3(0.02, 0.02, 0.0201));
      for (int i = 0; i < 5; ++i) step(m, s, ws);  // warm up: placed, first touch
      int contact_steps = 0;
      const long allocations = AllocationsDuring([&] {
        for (int i = 0; i < 200; ++i) {
          const double d = 2e-6 * (i < 100 ? i : 200 - 2 * (i - 100));  // press, then lift
          set_probe(s, 0, Vec3(0.02, 0.02, 0.0201 - d));
          step(m, s, ws);
          contact_steps += s.probes[0].contacts > 0;
        }
      });
      EXPECT_EQ(allocations, 0) << integrator_name(integ) << " shape " << static_cast<int>(shape);
      EXPECT_GT(contact_steps, 0) << integrator_name(integ);
      if (p.bonded) {
        EXPECT_GT(s.probes[0].bonded.size(), 1u) << integrator_name(integ);
      }
    }
}

TEST(AllocationTest, ActiveRegionStepAllocatesNothing) {
  // Multi-rate far field: far steps, region rebuilds as the probe moves and presses, frozen too.
  // The region itself (the whole-body switch off; on, a region this large on so small a bar is
  // stepped whole), then the switch between the two while counting.
  for (int far_every : {0, 3, -1}) {
    BodySpec b = TissueBar({12, 3, 2}, true, 2e-4, far_every);
    b.options.active_whole_body_cost = std::numeric_limits<double>::infinity();
    Model m;
    ASSERT_EQ(build_model(b, &m), "");
    State s = make_state(m);
    Workspace ws(m);
    set_probe(s, 0, Vec3(0.02, 0.015, 0.025));
    for (int i = 0; i < 5; ++i) step(m, s, ws);  // warm up
    std::uint64_t awake_min = ~0ull, awake_max = 0;
    const long allocations = AllocationsDuring([&] {
      for (int i = 0; i < 400; ++i) {
        set_probe(s, 0, Vec3(0.02 + 2e-4 * i, 0.015, 0.025 - 1e-5 * std::min(i, 200)));
        step(m, s, ws);
        awake_min = std::min(awake_min, s.counters.awake_nodes);
        awake_max = std::max(awake_max, s.counters.awake_nodes);
      }
    });
    EXPECT_EQ(allocations, 0) << "far_every " << far_every;
    EXPECT_LT(awake_max, static_cast<std::uint64_t>(m.num_nodes()));
    EXPECT_NE(awake_min, awake_max);  // the region did change while counting
    EXPECT_EQ(s.counters.rollbacks, 0u);
  }
  const BodySpec b = TissueBar({12, 3, 2}, true, 1e-7, 0);  // 0.1 um: wakes nearly everything
  Model m;
  ASSERT_EQ(build_model(b, &m), "");
  State s = make_state(m);
  Workspace ws(m);
  for (int i = 0; i < 5; ++i) step(m, s, ws);  // warm up, probe away
  int whole = 0, region = 0;
  const long allocations = AllocationsDuring([&] {
    for (int i = 0; i < 600; ++i) {
      // Press and hold, then withdraw: the region grows past the switch and empties again.
      const bool on = i < 400;
      set_probe(s, 0, Vec3(0.02, 0.015, 0.025 - 1e-5 * std::min(i, 200)), on);
      step(m, s, ws);
      whole += s.region.whole_body;
      region += !s.region.whole_body;
    }
  });
  EXPECT_EQ(allocations, 0);
  EXPECT_GT(whole, 0);
  EXPECT_GT(region, 0);
  EXPECT_FALSE(s.region.whole_body);
}

}  // namespace
}  // namespace conica
