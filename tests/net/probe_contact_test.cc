// The server's contact-only evaluation agrees with the step's contact stage, and the built-in
// scenes build, hold the rate on this machine's budget and stay stable under a pressed probe.
#include "net/probe_contact.h"

#include <gtest/gtest.h>

#include "core/body.h"
#include "core/step.h"
#include "net/builtin_scenes.h"

namespace conica::net {
namespace {

Model Cube() {
  BodySpec spec;
  EXPECT_EQ(builtin_scene("cube", 1e-3, &spec), "");
  Model m;
  EXPECT_EQ(build_model(spec, &m), "");
  return m;
}

// Both contact models: the surface proxy (the built-in cube's probe) and the node penalty. Both
// sides start from the same probe state, so the surface proxy moves from the same place.
TEST(ProbeContactTest, MatchesTheStepContactStage) {
  for (ContactModel model : {ContactModel::kSurface, ContactModel::kNodes}) {
    Model m = Cube();
    m.probes[0].contact = model;
    State s = make_state(m);
    Workspace ws(m);
    const double x0 = 3 * 0.04 / 7;
    // Deform the body a little first, so nodes are off the lattice.
    set_probe(s, 0, Vec3(x0, x0, 0.04 + 5e-3 - 2e-3));
    for (int k = 0; k < 100; ++k) step(m, s, ws);
    for (const Vec3& c :
         {Vec3(x0, x0, 0.0435), Vec3(x0 + 1e-3, x0 - 0.5e-3, 0.042), Vec3(0.02, 0.02, 0.2)}) {
      set_probe(s, 0, c);
      ProbeState mine = s.probes[0];
      compute_forces(m, s, ws);  // the step's proxy and contact stages fill s.probes[0]
      probe_contact(m, s, 0, c, 0, &mine);
      const char* name = model == ContactModel::kSurface ? "surface" : "nodes";
      if (c.z() < 0.0425) {  // deeper than the press: touches
        EXPECT_GT(mine.contacts, 0) << name;
      }
      EXPECT_EQ(mine.contacts, s.probes[0].contacts) << name;
      EXPECT_TRUE(mine.force.isApprox(s.probes[0].force, 1e-12) ||
                  (mine.force.norm() == 0 && s.probes[0].force.norm() == 0))
          << name << ": " << mine.force.transpose() << " vs " << s.probes[0].force.transpose();
      EXPECT_LT((mine.stiffness - s.probes[0].stiffness).norm(),
                1e-9 * (1 + s.probes[0].stiffness.norm()))
          << name;
    }
  }
}

// A probe 10 mm above the built-in cube moved to 0.05 mm into its top face in one update (the
// server's reply to it held past its budget, so the tick's proxy stage makes the jump): the proxy
// is put down on the surface, and the layer's damping must not take the 10 mm jump for the tool's
// velocity (10 m/s, which dragged the top face 14 mm down in 20 ticks and left the probe inside
// the body with no force).
TEST(ProbeContactTest, ProbeThatJumpsOntoTheSurfaceDoesNotDragTheTissueAlong) {
  const Model m = Cube();
  State s = make_state(m);
  Workspace ws(m);
  const double x0 = 3 * 0.04 / 7, top = 0.04, R = m.probes[0].radius;
  set_probe(s, 0, Vec3(x0, x0, top + R + 0.01));
  step(m, s, ws);
  EXPECT_EQ(s.probes[0].contacts, 0);
  set_probe(s, 0, Vec3(x0, x0, top + R - 5e-5));
  step(m, s, ws);
  EXPECT_EQ(s.probes[0].proxy_velocity, Vec3::Zero());  // a jump, not a motion
  for (int k = 1; k < 20; ++k) step(m, s, ws);
  double column_top = 0;  // of the lattice column under the probe
  for (int i = 0; i < m.num_nodes(); ++i)
    if ((m.rest[i].head<2>() - Vec3(x0, x0, 0).head<2>()).norm() < 1e-9)
      column_top = std::max(column_top, s.x[i].z());
  // Pressed 0.05 mm: the surface under it moves by no more than that.
  EXPECT_GT(column_top, top - 5e-5) << "the top face was dragged down";
  EXPECT_GT(s.probes[0].contacts, 0);
  EXPECT_GT(s.probes[0].force.z(), 0);
}

TEST(ProbeContactTest, NodeAtTheExactCentreIsBounded) {
  const Model m = Cube();
  State s = make_state(m);
  ProbeState p;
  probe_contact(m, s, 0, m.rest[319], 0, &p);
  EXPECT_TRUE(p.force.allFinite());
  EXPECT_TRUE(p.stiffness.allFinite());
  EXPECT_GE(p.contacts, 1);
}

TEST(BuiltinScenesTest, AllBuildAndStayStableUnderAPressedProbe) {
  for (const std::string& name : builtin_scene_names()) {
    BodySpec spec;
    ASSERT_EQ(builtin_scene(name, 1e-3, &spec), "") << name;
    Model m;
    ASSERT_EQ(build_model(spec, &m), "") << name;
    ASSERT_EQ(m.probes.size(), 1u);
    EXPECT_GT(m.num_nodes(), 100) << name;
    State s = make_state(m);
    Workspace ws(m);
    // Press the probe 2 mm into the top of the body above its highest node.
    int top = 0;
    for (int i = 0; i < m.num_nodes(); ++i)
      if (m.rest[i].z() > m.rest[top].z()) top = i;
    set_probe(s, 0, m.rest[top] + Vec3(0, 0, 5e-3 - 2e-3));
    for (int k = 0; k < 1000; ++k) step(m, s, ws);
    EXPECT_EQ(s.counters.rollbacks, 0u) << name;
    EXPECT_GT(s.probes[0].force.z(), 0) << name;  // pushed up, away from the body
  }
  BodySpec spec;
  EXPECT_NE(builtin_scene("kidney", 1e-3, &spec), "");
}

}  // namespace
}  // namespace conica::net
