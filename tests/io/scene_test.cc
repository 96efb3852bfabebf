// Scene files: every config in configs/ loads and builds; wrong scenes are refused saying where.
#include "io/scene.h"

#include <gtest/gtest.h>

#include <filesystem>

namespace conica::io {
namespace {

const std::string kConfigs = CONICA_SOURCE_DIR "/configs";

const char* kGood = R"(
name: "t"
lattice { size { x: 0.02 y: 0.02 z: 0.01 } cells: [2, 2, 1] }
density: 1000
group { name: "g" card { conical { G: 2e8 d: 1e-3 D1: 2e-3 D2: 8e-3 L0: 10e-3 n_a: 3 } } }
fixed { plane { normal { z: 1 } offset: 0 } }
)";

std::string ErrorOf(const std::string& text) {
  auto r = parse_scene(text, "s.pbtxt", kConfigs);
  return r ? std::string() : r.error();
}

TEST(SceneTest, EveryConfigLoadsAndBuilds) {
  int count = 0;
  for (const auto& e : std::filesystem::directory_iterator(kConfigs)) {
    if (e.path().extension() != ".pbtxt") continue;
    auto m = load_model(e.path().string());
    ASSERT_TRUE(m) << m.error();
    EXPECT_GT(m.value().num_springs(), 0) << e.path();
    ++count;
  }
  EXPECT_GE(count, 4);
}

TEST(SceneTest, ConfigsMatchThePaperAndTheData) {
  auto cube = load_model(kConfigs + "/paper-cube.pbtxt");
  ASSERT_TRUE(cube) << cube.error();
  EXPECT_EQ(cube.value().num_nodes(), 320);
  auto liver = load_model(kConfigs + "/liver.pbtxt");
  ASSERT_TRUE(liver) << liver.error();
  EXPECT_EQ(liver.value().num_nodes(), 507);
  EXPECT_EQ(liver.value().num_springs(), 2429);  // unique tetrahedron edges
  EXPECT_NEAR(liver.value().total_mass(), 1060 * 1.12509e-3, 1e-3);
  auto cyl = load_model(kConfigs + "/phantom-cylinder.pbtxt");
  ASSERT_TRUE(cyl) << cyl.error();
  // The mapped disc is exact at the boundary: volume pi r^2 h within the lattice's chord error.
  EXPECT_NEAR(cyl.value().total_mass() / 1070, M_PI * 0.025 * 0.025 * 0.03, 0.03 * 5.9e-5);
  auto aniso = load_model(kConfigs + "/anisotropic-block.pbtxt");
  ASSERT_TRUE(aniso) << aniso.error();
  ASSERT_EQ(aniso.value().groups.size(), 2u);
  EXPECT_EQ(aniso.value().groups[0].end - aniso.value().groups[0].begin, 6 * 7 * 4);  // x edges
}

TEST(SceneTest, GoodInlineSceneParses) { EXPECT_EQ(ErrorOf(kGood), ""); }

TEST(SceneTest, WrongScenesAreRefusedWithLineAndReason) {
  auto with = [](const std::string& find, const std::string& replace) {
    std::string s = kGood;
    s.replace(s.find(find), find.size(), replace);
    return ErrorOf(s);
  };
  // Unknown field: the text parser's line:column.
  EXPECT_NE(with("density: 1000", "densty: 1000").find("s.pbtxt:4:"), std::string::npos)
      << with("density: 1000", "densty: 1000");
  EXPECT_NE(with("density: 1000", "densty: 1000").find("densty"), std::string::npos);
  // Negative density at its line.
  const std::string neg = with("density: 1000", "density: -3");
  EXPECT_NE(neg.find("s.pbtxt:4:1: density must be > 0"), std::string::npos) << neg;
  // A negative or non-finite bulk modulus at its line.
  for (const char* field : {"bulk_modulus", "spread_modulus", "shear_modulus"})
    for (const char* k : {"-1", "nan", "inf"}) {
      const std::string before = std::string(field) == "bulk_modulus" ? "" : " bulk_modulus: 1";
      const std::string e =
          with("density: 1000", "density: 1000" + before + "\n" + field + ": " + k);
      EXPECT_NE(e.find("s.pbtxt:5:"), std::string::npos) << e;
      EXPECT_NE(e.find(std::string(field) + " must be >= 0 Pa"), std::string::npos) << e;
    }
  const std::string lone = with("density: 1000", "density: 1000 spread_modulus: 5");
  EXPECT_NE(lone.find("spread_modulus needs bulk_modulus > 0"), std::string::npos) << lone;
  // Invalid card at its group's line, naming the parameter.
  const std::string card = with("d: 1e-3", "d: 0");
  EXPECT_NE(card.find("s.pbtxt:5:1: group 0 (\"g\"): d must be > 0"), std::string::npos) << card;
  // Missing mesh file.
  const std::string mesh = with("lattice { size { x: 0.02 y: 0.02 z: 0.01 } cells: [2, 2, 1] }",
                                "mesh { path: \"nowhere.msh\" }");
  EXPECT_NE(mesh.find("s.pbtxt:3:1: cannot load mesh"), std::string::npos) << mesh;
  EXPECT_NE(mesh.find("nowhere.msh"), std::string::npos);
  // A spring group that matches nothing, at its line.
  const std::string none = with("fixed {",
                                "group { name: \"none\" card { hooke { k: 1 length: 1 } } "
                                "regions: [\"nope\"] }\nfixed {");
  EXPECT_NE(none.find("s.pbtxt:6:1:"), std::string::npos) << none;
  EXPECT_NE(none.find("\"none\" matches no spring"), std::string::npos) << none;
  // A fixed selector that matches nothing.
  const std::string fixed = with("offset: 0", "offset: 5");
  EXPECT_NE(fixed.find("s.pbtxt:6:1: fixed selector 0 matches no node"), std::string::npos)
      << fixed;
  // A lattice within the per-axis bound but too large in total (400^3 would need ~100 GB).
  const std::string huge = with("cells: [2, 2, 1]", "cells: [400, 400, 400]");
  EXPECT_NE(huge.find("s.pbtxt:3:1: lattice of 64000000 cells is over the limit of 100000"),
            std::string::npos)
      << huge;
  EXPECT_NE(with("cells: [2, 2, 1]", "cells: [47, 47, 46]").find("over the limit"),
            std::string::npos);
  // Wrong type and garbage.
  EXPECT_NE(with("density: 1000", "density: \"heavy\"").find("s.pbtxt:4:"), std::string::npos);
  EXPECT_NE(ErrorOf("\x01\x02 garbage {{{").find("s.pbtxt:"), std::string::npos);
  EXPECT_NE(ErrorOf("").find("needs geometry"), std::string::npos);
  // A missing scene file.
  EXPECT_NE(load_model("/nonexistent/scene.pbtxt").error().find("cannot open scene file"),
            std::string::npos);
}

TEST(SceneTest, PrecompressionIsReadInMetresAndCheckedAgainstTheStroke) {
  // kGood's card: Ls = sqrt((n_a d)^2 - (r2 - r1)^2) = 0, so the stroke is L0 = 10 mm.
  auto with = [](const std::string& field) {
    std::string s = kGood;
    const std::string at = "n_a: 3 }";
    s.replace(s.find(at), at.size(), "n_a: 3 " + field + " }");
    return s;
  };
  auto ok = parse_scene(with("precompression: 0.004"), "s.pbtxt", kConfigs);
  ASSERT_TRUE(ok) << ok.error();
  EXPECT_EQ(ok.value().spec.groups.at(0).card.conical.precompression, 0.004);
  auto plain = parse_scene(kGood, "s.pbtxt", kConfigs);
  ASSERT_TRUE(plain) << plain.error();
  EXPECT_EQ(plain.value().spec.groups.at(0).card.conical.precompression, 0.0);
  for (const char* bad : {"precompression: -1e-3", "precompression: 0.01", "precompression: 0.02",
                          "precompression: nan"}) {
    const std::string e = ErrorOf(with(bad));
    EXPECT_NE(e.find("s.pbtxt:5:1: group 0 (\"g\"): precompression must be"), std::string::npos)
        << bad << ": " << e;
  }
  // The message quotes the stroke; Ls is 0 up to rounding (about 1e-11 m, depending on how the
  // compiler contracts the arithmetic), so S reads as 0.01 m to six digits.
  const std::string e = ErrorOf(with("precompression: 0.02"));
  const std::string key = "< stroke S = L0 - Ls = ";
  const size_t at = e.find(key);
  ASSERT_NE(at, std::string::npos) << e;
  EXPECT_NEAR(std::stod(e.substr(at + key.size())), 0.01, 1e-8) << e;
}

TEST(SceneTest, ActiveRegionIsReadAndCheckedInTheSolver) {
  auto with = [](const std::string& solver) {
    return std::string(kGood) + "solver { " + solver + " }\n";
  };
  auto ok =
      parse_scene(with("active_region { tolerance: 3e-4 far_every: 4 }"), "s.pbtxt", kConfigs);
  ASSERT_TRUE(ok) << ok.error();
  const SolverOptions& o = ok.value().spec.options;
  EXPECT_TRUE(o.active_region);
  EXPECT_EQ(o.active_tolerance, 3e-4);
  EXPECT_EQ(o.active_far_every, 4);
  auto plain = parse_scene(kGood, "s.pbtxt", kConfigs);
  ASSERT_TRUE(plain) << plain.error();
  EXPECT_FALSE(plain.value().spec.options.active_region);
  auto automatic = parse_scene(with("active_region { tolerance: 1e-4 }"), "s.pbtxt", kConfigs);
  ASSERT_TRUE(automatic) << automatic.error();
  EXPECT_EQ(automatic.value().spec.options.active_far_every, 0);
  const std::pair<const char*, const char*> bad[] = {
      {"active_region { tolerance: 0 }", "tolerance must be a positive length in m (got 0)"},
      {"active_region { tolerance: -1e-3 }", "tolerance must be a positive length"},
      {"active_region { tolerance: inf }", "tolerance must be a positive length"},
      {"active_region { tolerance: 1e-4 far_every: -2 }", "far_every must be -1 (frozen)"},
      {"integrator: IMPLICIT_EULER active_region { tolerance: 1e-4 }",
       "needs SYMPLECTIC_EULER or EXPLICIT_EULER"},
  };
  for (const auto& [solver, why] : bad) {
    const std::string e = ErrorOf(with(solver));
    EXPECT_NE(e.find("s.pbtxt:7:1: solver.active_region: "), std::string::npos)
        << solver << ": " << e;
    EXPECT_NE(e.find(why), std::string::npos) << solver << ": " << e;
  }
  // The region's lists hold springs only: no volume stiffness with it.
  std::string vol = with("active_region { tolerance: 1e-4 }");
  vol.replace(vol.find("density: 1000"), 13, "density: 1000 bulk_modulus: 1e5");
  const std::string e = ErrorOf(vol);
  EXPECT_NE(e.find("s.pbtxt:7:1: solver.active_region: not with bulk_modulus"), std::string::npos)
      << e;
}

}  // namespace
}  // namespace conica::io
