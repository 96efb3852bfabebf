// Scene fields of the boundary conditions (bonded plates, prescribed paths): they load, they do
// what they say in a step, and wrong values are refused naming the file, line and field.
#include <gtest/gtest.h>

#include <filesystem>

#include "core/boundary.h"
#include "core/step.h"
#include "io/scene.h"

namespace conica::io {
namespace {

const std::string kConfigs = CONICA_SOURCE_DIR "/configs";

const std::string kBody = R"(name: "t"
lattice { size { x: 0.02 y: 0.02 z: 0.01 } cells: [2, 2, 1] }
density: 1000
group { name: "g" card { conical { G: 2e8 d: 1e-3 D1: 2e-3 D2: 8e-3 L0: 10e-3 n_a: 3 } } }
)";

std::string ErrorOf(const std::string& text) {
  auto r = parse_scene(text, "s.pbtxt", kConfigs);
  return r ? std::string() : r.error();
}

TEST(SceneBoundaryTest, ValidationScenesLoadAndBuild) {
  int count = 0;
  for (const char* f : {"cylinder-ef30", "cube-ef30", "punch-block-ef30"}) {
    auto m = load_model(kConfigs + "/validation/" + f + ".pbtxt");
    ASSERT_TRUE(m) << m.error();
    EXPECT_GT(m.value().num_springs(), 0) << f;
    ++count;
  }
  EXPECT_EQ(count, 3);
  auto block = load_model(kConfigs + "/validation/punch-block-ef30.pbtxt");
  ASSERT_TRUE(block) << block.error();
  EXPECT_EQ(block.value().num_nodes(), 25 * 25 * 13);
}

TEST(SceneBoundaryTest, BondedPlateCarriesItsNodes) {
  auto r = parse_scene(kBody + R"(fixed { plane { normal { z: 1 } offset: 0 } }
plate { normal { z: -1 } offset: -0.01 bonded: true })",
                       "s.pbtxt", kConfigs);
  ASSERT_TRUE(r) << r.error();
  Model m;
  ASSERT_EQ(build_model(r.value().spec, &m), "");
  ASSERT_EQ(m.planes[0].bonded_nodes.size(), 9u);  // the 3 x 3 top nodes
  for (int i : m.planes[0].bonded_nodes) {
    EXPECT_NEAR(m.rest[i].z(), 0.01, 1e-12);
    EXPECT_EQ(m.inv_mass[i], 0.0);
  }
  State s = make_state(m);
  Workspace ws(m);
  s.planes[0].offset = -0.01 + 1e-3;  // 1 mm down
  step(m, s, ws);
  for (int i : m.planes[0].bonded_nodes) {
    EXPECT_NEAR(s.x[i].z(), 0.009, 1e-15);
    EXPECT_EQ(s.x[i].x(), m.rest[i].x());
    EXPECT_EQ(s.x[i].y(), m.rest[i].y());
  }
  // The plate's force is the body's force on its nodes: the body pushes it back up.
  compute_forces(m, s, ws);
  Vec3 sum = Vec3::Zero();
  for (int i : m.planes[0].bonded_nodes) sum += ws.force[i];
  EXPECT_GT(sum.z(), 0);
  EXPECT_NEAR((s.planes[0].force - sum).norm(), 0, 1e-12 * sum.norm());
}

TEST(SceneBoundaryTest, PathMovesNodesPiecewiseLinearly) {
  auto r = parse_scene(kBody + R"(fixed { plane { normal { z: 1 } offset: 0 } }
fixed {
  plane { normal { z: 1 } offset: 0.01 }
  axes: [Z]
  path { time: 0 }
  path { time: 0.1 displacement { z: -0.002 } }
  path { time: 0.3 displacement { z: -0.001 } }
})",
                       "s.pbtxt", kConfigs);
  ASSERT_TRUE(r) << r.error();
  Model m;
  ASSERT_EQ(build_model(r.value().spec, &m), "");
  ASSERT_EQ(m.motions.size(), 1u);
  EXPECT_EQ(m.motions[0].nodes.size(), 9u);
  EXPECT_NEAR(motion_displacement(m.motions[0], 0.05).z(), -0.001, 1e-15);
  EXPECT_NEAR(motion_displacement(m.motions[0], 0.2).z(), -0.0015, 1e-15);
  EXPECT_NEAR(motion_displacement(m.motions[0], 9).z(), -0.001, 1e-15);
  EXPECT_NEAR(motion_displacement(m.motions[0], -1).z(), 0, 1e-15);
  m.options.dt = 0.05;
  State s = make_state(m);
  Workspace ws(m);
  step(m, s, ws);  // ends at t = 0.05
  for (int i : m.motions[0].nodes) EXPECT_NEAR(s.x[i].z(), 0.01 - 0.001, 1e-12);
  for (int k = 0; k < 3; ++k) step(m, s, ws);  // t = 0.2
  for (int i : m.motions[0].nodes) EXPECT_NEAR(s.x[i].z(), 0.01 - 0.0015, 1e-12);
}

TEST(SceneBoundaryTest, WrongBoundaryFieldsSayWhere) {
  const std::string fixed = "fixed { plane { normal { z: 1 } offset: 0 } }\n";
  // kBody has 4 lines, so the first field after it is on line 5.
  EXPECT_EQ(ErrorOf(kBody + fixed + "plate { normal { z: -1 } offset: -0.02 bonded: true }"),
            "s.pbtxt:6:1: plate 0 is bonded but touches no node at rest (its face must lie on "
            "the body)");
  EXPECT_EQ(ErrorOf(kBody + fixed +
                    "plate { normal { z: -1 } offset: -0.01 bonded: true bond_tolerance: -1 }"),
            "s.pbtxt:6:1: plate 0: bond_tolerance must be >= 0 m");
  EXPECT_EQ(ErrorOf(kBody + fixed + "plate { normal { z: -1 } offset: -0.01 friction: -0.2 }"),
            "s.pbtxt:6:1: plate 0: friction must be >= 0 (a Coulomb coefficient)");
  EXPECT_EQ(ErrorOf(kBody + fixed + "plate { normal { z: -1 } offset: -0.01 friction: nan }"),
            "s.pbtxt:6:1: plate 0: friction must be >= 0 (a Coulomb coefficient)");
  EXPECT_EQ(ErrorOf(kBody + fixed +
                    "fixed { plane { normal { z: 1 } offset: 0.01 } path { time: 1 } path { "
                    "time: 0.5 } }"),
            "s.pbtxt:6:1: fixed 1: path 1: time must be greater than the previous waypoint's (s)");
  EXPECT_EQ(ErrorOf(kBody + fixed +
                    "fixed { plane { normal { z: 1 } offset: 0.01 } path { time: inf } }"),
            "s.pbtxt:6:1: fixed 1: path 0: time must be finite (s)");
}

}  // namespace
}  // namespace conica::io
