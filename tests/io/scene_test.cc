// Scene files: every config in configs/ loads and builds; wrong scenes are refused saying where.
#include "io/scene.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "core/body.h"
#include "io/scene_writer.h"

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

// A scene file shipped in configs/: hidden files are scripts' temporary copies
// (scripts/serve_press.sh, scripts/liver-by-hand.sh), not shipped configs.
bool ShippedConfig(const std::filesystem::path& p) {
  return p.extension() == ".pbtxt" && p.filename().string()[0] != '.';
}

TEST(SceneTest, EveryConfigLoadsAndBuilds) {
  int count = 0;
  for (const auto& e : std::filesystem::directory_iterator(kConfigs)) {
    if (!ShippedConfig(e.path())) continue;
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
  // The shear term's stiffening: >= 0 and finite, at its line, and only with a shear term.
  for (const char* k : {"-0.5", "nan", "inf"}) {
    const std::string e = with(
        "density: 1000", "density: 1000 shear_modulus: 100\nshear_stiffening: " + std::string(k));
    EXPECT_NE(e.find("s.pbtxt:5:1: shear_stiffening must be >= 0"), std::string::npos) << e;
  }
  const std::string stiff = with("density: 1000", "density: 1000\nshear_stiffening: 2");
  EXPECT_NE(stiff.find("s.pbtxt:5:1: shear_stiffening needs shear_modulus > 0"), std::string::npos)
      << stiff;
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

// `material: "NAME"` reads materials/NAME.card next to the scene (or on CONICA_MATERIAL_PATH):
// the body gets the card's groups and volume terms, the same as the card pasted in; a missing
// card, a scene that gives groups as well, or a card that is not a material is refused saying
// where.
TEST(SceneTest, MaterialByNameReadsTheCardFromTheLibrary) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::path(testing::TempDir()) / "scene_material";
  fs::create_directories(dir / "materials");
  const std::string card =
      "# a calibrated silicone\nbulk_modulus: 90000\nspread_modulus: 90000\nshear_modulus: 2000\n"
      "group { name: \"silicone\" card { conical { G: 2e8 d: 1e-3 D1: 2e-3 D2: 8e-3 L0: 10e-3 "
      "n_a: 3 precompression: 1e-4 } stiffness_cap: 500 } }\n";
  std::ofstream(dir / "materials" / "EF_TEST.card") << card;
  const std::string head =
      "lattice { size { x: 0.02 y: 0.02 z: 0.01 } cells: [2, 2, 1] }\ndensity: 1000\n"
      "fixed { plane { normal { z: 1 } offset: 0 } }\n";
  auto named = parse_scene(head + "material: \"EF_TEST\"\n", "organ.pbtxt", dir.string());
  ASSERT_TRUE(named) << named.error();
  auto pasted = parse_scene(head + card, "pasted.pbtxt", dir.string());
  ASSERT_TRUE(pasted) << pasted.error();
  const BodySpec &a = named.value().spec, &b = pasted.value().spec;
  EXPECT_EQ(named.value().material, "EF_TEST");
  EXPECT_EQ(named.value().material_path, (dir / "materials" / "EF_TEST.card").string());
  ASSERT_EQ(a.groups.size(), 1u);
  EXPECT_EQ(a.groups[0].name, "silicone");
  EXPECT_EQ(a.groups[0].card.conical.G, 2e8);
  EXPECT_EQ(a.groups[0].card.conical.precompression, 1e-4);
  EXPECT_EQ(a.groups[0].card.stiffness_cap, b.groups[0].card.stiffness_cap);
  EXPECT_EQ(a.bulk_modulus, 90000);
  EXPECT_EQ(a.spread_modulus, b.spread_modulus);
  EXPECT_EQ(a.shear_modulus, 2000);
  // Found on CONICA_MATERIAL_PATH from a scene elsewhere.
  ::setenv("CONICA_MATERIAL_PATH", ("/nonexistent:" + (dir / "materials").string()).c_str(), 1);
  auto far = parse_scene(head + "material: \"EF_TEST\"\n", "far.pbtxt", "/");
  ::unsetenv("CONICA_MATERIAL_PATH");
  ASSERT_TRUE(far) << far.error();
  EXPECT_EQ(far.value().spec.groups[0].card.conical.G, 2e8);
  // Refusals.
  auto missing = parse_scene(head + "material: \"EF_NONE\"\n", "organ.pbtxt", dir.string());
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().find("organ.pbtxt:4:"), std::string::npos) << missing.error();
  EXPECT_NE(missing.error().find("EF_NONE.card"), std::string::npos) << missing.error();
  auto both = parse_scene(head + "material: \"EF_TEST\"\n" + card, "both.pbtxt", dir.string());
  ASSERT_FALSE(both);
  EXPECT_NE(both.error().find("gives no group"), std::string::npos) << both.error();
  auto path_name = parse_scene(head + "material: \"../x\"\n", "p.pbtxt", dir.string());
  ASSERT_FALSE(path_name);
  EXPECT_NE(path_name.error().find("not a plain name"), std::string::npos) << path_name.error();
  std::ofstream(dir / "materials" / "BAD.card") << "density: 1000\nbulk_modulus: 1\n";
  auto bad = parse_scene(head + "material: \"BAD\"\n", "b.pbtxt", dir.string());
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().find("BAD.card: a material card holds groups"), std::string::npos)
      << bad.error();
  std::ofstream(dir / "materials" / "TYPO.card") << "group { nme: \"x\" }\n";
  auto typo = parse_scene(head + "material: \"TYPO\"\n", "t.pbtxt", dir.string());
  ASSERT_FALSE(typo);
  EXPECT_NE(typo.error().find("TYPO.card:1:"), std::string::npos) << typo.error();
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

TEST(SceneTest, MultiRateServingIsReadAndChecked) {
  auto with = [](const std::string& solver) {
    return std::string(kGood) + "probe { radius: 0.004 }\nsolver { " + solver + " }\n";
  };
  auto ok = parse_scene(with("integrator: IMPLICIT_EULER body_rate_hz: 50 body_reach: 0.002 "
                             "newton_tolerance: 1e-6 refactor_every: 10 bdf2: true"),
                        "s.pbtxt", kConfigs);
  ASSERT_TRUE(ok) << ok.error();
  EXPECT_TRUE(ok.value().spec.options.bdf2);
  EXPECT_EQ(ok.value().spec.options.newton_tolerance, 1e-6);
  EXPECT_EQ(ok.value().spec.options.refactor_every, 10);
  EXPECT_EQ(ok.value().spec.options.body_rate_hz, 50);
  EXPECT_EQ(ok.value().spec.options.body_reach, 0.002);
  const std::pair<const char*, const char*> bad[] = {
      {"body_rate_hz: 50", "needs integrator IMPLICIT_EULER"},
      {"bdf2: true", "bdf2 needs integrator IMPLICIT_EULER"},
      {"integrator: IMPLICIT_EULER body_rate_hz: 2000", "body_rate_hz must be in [0, rate_hz]"},
      {"integrator: IMPLICIT_EULER body_rate_hz: -1", "body_rate_hz must be in [0, rate_hz]"},
      {"integrator: IMPLICIT_EULER body_rate_hz: nan", "body_rate_hz must be in [0, rate_hz]"},
      {"integrator: IMPLICIT_EULER body_reach: -1e-3", "body_reach >= 0"},
      {"integrator: IMPLICIT_EULER newton_tolerance: -1e-6", "newton_tolerance must be"},
      {"integrator: IMPLICIT_EULER newton_tolerance: inf", "newton_tolerance must be"},
  };
  for (const auto& [solver, why] : bad) {
    const std::string e = ErrorOf(with(solver));
    EXPECT_NE(e.find("s.pbtxt:8:1: solver: "), std::string::npos) << solver << ": " << e;
    EXPECT_NE(e.find(why), std::string::npos) << solver << ": " << e;
  }
  // The local model leaves friction out: a frictional surface probe is refused.
  auto surface = parse_scene(std::string(kGood) +
                                 "probe { radius: 0.004 contact: SURFACE friction: 0.3 }\n"
                                 "solver { integrator: IMPLICIT_EULER body_rate_hz: 50 }\n",
                             "s.pbtxt", kConfigs);
  const std::string e = surface ? [&] {
    Model m;
    return build_model(surface.value().spec, &m);
  }()
                                 : surface.error();
  EXPECT_NE(e.find("friction is not served multi-rate"), std::string::npos) << e;
}

// A PLANE tool reads back as one; it needs the surface contact, and is refused with an active
// region or multi-rate serving (whose regions are balls about the tool), with the reason; so is
// a bonded tool, and bonded with friction.
TEST(SceneTest, PlaneAndBondedToolsNeedSurfaceContactAndEveryNode) {
  auto ok = parse_scene(
      std::string(kGood) + "probe { radius: 0.01 contact: SURFACE shape: PLANE axis { z: -1 } }\n",
      "s.pbtxt", kConfigs);
  ASSERT_TRUE(ok) << ok.error();
  EXPECT_EQ(ok.value().spec.probes[0].shape, ToolShape::kPlane);
  // A probe without `contact` is a surface probe; NODES is asked for by name.
  for (auto [probe, model] : {std::pair{"probe { radius: 0.01 }\n", ContactModel::kSurface},
                              {"probe { radius: 0.01 contact: NODES }\n", ContactModel::kNodes}}) {
    auto r = parse_scene(std::string(kGood) + probe, "s.pbtxt", kConfigs);
    ASSERT_TRUE(r) << r.error();
    EXPECT_EQ(r.value().spec.probes[0].contact, model) << probe;
  }
  const std::pair<const char*, const char*> bad[] = {
      {"probe { radius: 0.01 contact: NODES shape: PLANE }\n",
       "s.pbtxt:7:1: probe 0: shape PLANE needs contact: SURFACE"},
      {"probe { radius: 0.01 contact: SURFACE shape: PLANE }\n"
       "solver { integrator: IMPLICIT_EULER body_rate_hz: 50 }\n",
       "s.pbtxt:7:1: probe 0: a PLANE tool is not served multi-rate"},
      {"probe { radius: 0.01 contact: SURFACE shape: PLANE }\n"
       "solver { active_region { tolerance: 1e-5 } }\n",
       "a PLANE tool needs every node integrated"},
      {"probe { radius: 0.01 contact: NODES bonded: true }\n",
       "s.pbtxt:7:1: probe 0: bonded needs contact: SURFACE"},
      {"probe { radius: 0.01 contact: SURFACE bonded: true friction: 0.5 }\n",
       "s.pbtxt:7:1: probe 0: bonded and friction exclude each other"},
      {"probe { radius: 0.01 contact: SURFACE bonded: true }\n"
       "solver { integrator: IMPLICIT_EULER body_rate_hz: 50 }\n",
       "s.pbtxt:7:1: probe 0: a bonded tool is not served multi-rate"},
      {"probe { radius: 0.01 contact: SURFACE bonded: true }\n"
       "solver { active_region { tolerance: 1e-5 } }\n",
       "s.pbtxt:7:1: probe 0: a bonded tool needs every node integrated"},
  };
  for (const auto& [probe, why] : bad) {
    const std::string e = ErrorOf(std::string(kGood) + probe);
    EXPECT_NE(e.find(why), std::string::npos) << probe << ": " << e;
  }
}

// Every field of two scenes, exactly (the writer prints numbers that read back bit for bit).
void ExpectSameCard(const SpringCard& a, const SpringCard& b, const std::string& where) {
  EXPECT_EQ(a.law, b.law) << where;
  const ConicalCard &p = a.conical, &q = b.conical;
  EXPECT_EQ(p.G, q.G) << where;
  EXPECT_EQ(p.d, q.d) << where;
  EXPECT_EQ(p.D1, q.D1) << where;
  EXPECT_EQ(p.D2, q.D2) << where;
  EXPECT_EQ(p.L0, q.L0) << where;
  EXPECT_EQ(p.n_a, q.n_a) << where;
  EXPECT_EQ(p.precompression, q.precompression) << where;
  EXPECT_EQ(a.hooke_k, b.hooke_k) << where;
  EXPECT_EQ(a.hooke_length, b.hooke_length) << where;
  EXPECT_EQ(a.stiffness_cap, b.stiffness_cap) << where;
  EXPECT_EQ(a.damping, b.damping) << where;
  EXPECT_EQ(a.maxwell_k, b.maxwell_k) << where;
  EXPECT_EQ(a.maxwell_tau, b.maxwell_tau) << where;
}

void ExpectSameGroups(const std::vector<SpringGroupSpec>& a, const std::vector<SpringGroupSpec>& b,
                      const std::string& where) {
  ASSERT_EQ(a.size(), b.size()) << where;
  for (size_t g = 0; g < a.size(); ++g) {
    const std::string w = where + " group " + std::to_string(g);
    EXPECT_EQ(a[g].name, b[g].name) << w;
    ExpectSameCard(a[g].card, b[g].card, w);
    EXPECT_EQ(a[g].families, b[g].families) << w;
    EXPECT_EQ(a[g].regions, b[g].regions) << w;
    EXPECT_EQ(a[g].axis, b[g].axis) << w;
    EXPECT_EQ(a[g].max_angle_deg, b[g].max_angle_deg) << w;
  }
}

void ExpectSameScene(const SceneFile& a, const SceneFile& b, const std::string& where) {
  EXPECT_EQ(a.name, b.name) << where;
  EXPECT_EQ(a.description, b.description) << where;
  EXPECT_EQ(std::filesystem::weakly_canonical(a.mesh_path),
            std::filesystem::weakly_canonical(b.mesh_path))
      << where;
  const SceneGeometry &g = a.geometry, &h = b.geometry;
  EXPECT_EQ(g.kind, h.kind) << where;
  EXPECT_EQ(g.size, h.size) << where;
  EXPECT_EQ(g.cells, h.cells) << where;
  EXPECT_EQ(g.radius, h.radius) << where;
  EXPECT_EQ(g.height, h.height) << where;
  EXPECT_EQ(g.cells_across, h.cells_across) << where;
  EXPECT_EQ(g.cells_high, h.cells_high) << where;
  EXPECT_EQ(g.origin, h.origin) << where;
  EXPECT_EQ(g.scale, h.scale) << where;
  EXPECT_EQ(g.translate, h.translate) << where;
  EXPECT_EQ(g.repair, h.repair) << where;
  const BodySpec &s = a.spec, &t = b.spec;
  EXPECT_EQ(s.mesh.nodes, t.mesh.nodes) << where;
  EXPECT_EQ(s.mesh.tetrahedra, t.mesh.tetrahedra) << where;
  EXPECT_EQ(s.mesh.hexahedra, t.mesh.hexahedra) << where;
  EXPECT_EQ(s.mesh.triangles, t.mesh.triangles) << where;
  ASSERT_EQ(s.mesh.regions.size(), t.mesh.regions.size()) << where;
  for (size_t r = 0; r < s.mesh.regions.size(); ++r) {
    EXPECT_EQ(s.mesh.regions[r].name, t.mesh.regions[r].name) << where;
    EXPECT_EQ(s.mesh.regions[r].id, t.mesh.regions[r].id) << where;
    EXPECT_EQ(s.mesh.regions[r].tetrahedra, t.mesh.regions[r].tetrahedra) << where;
    EXPECT_EQ(s.mesh.regions[r].hexahedra, t.mesh.regions[r].hexahedra) << where;
  }
  EXPECT_EQ(s.density, t.density) << where;
  EXPECT_EQ(s.mapping, t.mapping) << where;
  EXPECT_EQ(s.bulk_modulus, t.bulk_modulus) << where;
  EXPECT_EQ(s.spread_modulus, t.spread_modulus) << where;
  EXPECT_EQ(s.shear_modulus, t.shear_modulus) << where;
  ExpectSameGroups(s.groups, t.groups, where);
  ASSERT_EQ(s.fixed.size(), t.fixed.size()) << where;
  for (size_t k = 0; k < s.fixed.size(); ++k) {
    const FixedSelector &f = s.fixed[k], &e = t.fixed[k];
    EXPECT_EQ(f.kind, e.kind) << where << " fixed " << k;
    EXPECT_EQ(f.normal, e.normal) << where << " fixed " << k;
    EXPECT_EQ(f.offset, e.offset) << where << " fixed " << k;
    EXPECT_EQ(f.tolerance, e.tolerance) << where << " fixed " << k;
    EXPECT_EQ(f.box_min, e.box_min) << where << " fixed " << k;
    EXPECT_EQ(f.box_max, e.box_max) << where << " fixed " << k;
    EXPECT_EQ(f.region, e.region) << where << " fixed " << k;
    EXPECT_EQ(f.nodes, e.nodes) << where << " fixed " << k;
    EXPECT_EQ(f.axes, e.axes) << where << " fixed " << k;
  }
  ASSERT_EQ(s.probes.size(), t.probes.size()) << where;
  for (size_t k = 0; k < s.probes.size(); ++k) {
    const ProbeSpec &p = s.probes[k], &q = t.probes[k];
    EXPECT_EQ(p.radius, q.radius) << where << " probe " << k;
    EXPECT_EQ(p.stiffness, q.stiffness) << where << " probe " << k;
    EXPECT_EQ(p.contact, q.contact) << where << " probe " << k;
    EXPECT_EQ(p.shape, q.shape) << where << " probe " << k;
    EXPECT_EQ(p.axis, q.axis) << where << " probe " << k;
    EXPECT_EQ(p.coupling, q.coupling) << where << " probe " << k;
    EXPECT_EQ(p.friction, q.friction) << where << " probe " << k;
    EXPECT_EQ(p.bonded, q.bonded) << where << " probe " << k;
  }
  ASSERT_EQ(s.planes.size(), t.planes.size()) << where;
  for (size_t k = 0; k < s.planes.size(); ++k) {
    EXPECT_EQ(s.planes[k].normal, t.planes[k].normal) << where << " plate " << k;
    EXPECT_EQ(s.planes[k].offset, t.planes[k].offset) << where << " plate " << k;
    EXPECT_EQ(s.planes[k].stiffness, t.planes[k].stiffness) << where << " plate " << k;
  }
  const SolverOptions &o = s.options, &u = t.options;
  EXPECT_EQ(o.integrator, u.integrator) << where;
  EXPECT_EQ(o.dt, u.dt) << where;
  EXPECT_EQ(o.substeps, u.substeps) << where;
  EXPECT_EQ(o.newton_iterations, u.newton_iterations) << where;
  EXPECT_EQ(o.cg_iterations, u.cg_iterations) << where;
  EXPECT_EQ(o.cg_tolerance, u.cg_tolerance) << where;
  EXPECT_EQ(o.newton_tolerance, u.newton_tolerance) << where;
  EXPECT_EQ(o.linear_solver, u.linear_solver) << where;
  EXPECT_EQ(o.refactor_every, u.refactor_every) << where;
  EXPECT_EQ(o.refactor_iterations, u.refactor_iterations) << where;
  EXPECT_EQ(o.body_rate_hz, u.body_rate_hz) << where;
  EXPECT_EQ(o.body_reach, u.body_reach) << where;
  if (o.body_rate_hz > 0) {
    EXPECT_EQ(o.exact_compliance, u.exact_compliance) << where;
  }
  if (o.integrator == Integrator::kImplicitEuler) {
    EXPECT_EQ(o.exact_tangent, u.exact_tangent) << where;
  }
  EXPECT_EQ(o.bdf2, u.bdf2) << where;
  EXPECT_EQ(o.mass_damping, u.mass_damping) << where;
  EXPECT_EQ(o.gravity, u.gravity) << where;
  EXPECT_EQ(o.min_length_fraction, u.min_length_fraction) << where;
  EXPECT_EQ(o.max_speed, u.max_speed) << where;
  EXPECT_EQ(o.active_region, u.active_region) << where;
  EXPECT_EQ(o.active_tolerance, u.active_tolerance) << where;
  EXPECT_EQ(o.active_far_every, u.active_far_every) << where;
}

// Writes `scene` as a file in a fresh folder (not the scene's own: the mesh path must follow)
// and reads it back with read_scene.
Result<SceneFile> WriteAndRead(const SceneFile& scene, const std::string& file) {
  const std::filesystem::path dir =
      std::filesystem::path(testing::TempDir()) / "scene_round_trip" / "out";
  std::filesystem::create_directories(dir);
  const std::string path = (dir / file).string();
  const std::string e = write_text_file(path, scene_text(scene, dir.string()));
  if (!e.empty()) return Error{e};
  return read_scene(path);
}

TEST(SceneWriterTest, EveryConfigRoundTrips) {
  int count = 0;
  for (const auto& e : std::filesystem::directory_iterator(kConfigs)) {
    if (!ShippedConfig(e.path())) continue;
    auto a = read_scene(e.path().string());
    ASSERT_TRUE(a) << a.error();
    auto b = WriteAndRead(a.value(), e.path().filename().string());
    ASSERT_TRUE(b) << e.path() << ": " << b.error();
    ExpectSameScene(a.value(), b.value(), e.path().filename().string());
    ++count;
  }
  EXPECT_GE(count, 4);
}

// Every field the reader knows, none at its default; the text is protobuf's own.
TEST(SceneWriterTest, ASceneWithEveryFieldRoundTrips) {
  const char* text = R"(
name: "every field"
description: "round trip"
cylinder { radius: 0.021 height: 0.017 cells_across: 3 cells_high: 2 origin { x: 0.1 y: -0.2 z: 0.3 } }
density: 1234.5
mapping: RAW
bulk_modulus: 1.5e5
spread_modulus: 7e4
shear_modulus: 3.3e3
group {
  name: "edges"
  card {
    conical { G: 2.1e8 d: 1.1e-3 D1: 2.2e-3 D2: 8.1e-3 L0: 9.7e-3 n_a: 3.5 precompression: 1e-3 }
    stiffness_cap: 250 damping: 0.125 maxwell_k: 17 maxwell_tau: 0.75
  }
  families: [EDGE]
  axis { z: 1 }
  max_angle_deg: 20
}
group {
  name: "diagonals"
  card { hooke { k: 1e3 length: 0.013 } damping: 0.5 }
  families: [FACE_DIAGONAL, BODY_DIAGONAL]
}
group {
  name: "rest"
  card { conical { G: 2e8 d: 1e-3 D1: 2e-3 D2: 8e-3 L0: 10e-3 n_a: 3 } }
}
fixed { plane { normal { z: 1 } offset: 0.3 tolerance: 1e-5 } axes: [Z] }
fixed { box { min { x: -1 y: -1 z: 0.29 } max { x: 1 y: 1 z: 0.301 } } axes: [X, Y] }
fixed { nodes { nodes: [0, 3, 5] } }
probe { radius: 0.004 stiffness: 1e6 contact: SURFACE shape: PUNCH axis { x: 1 } coupling: 800 friction: 0.3 }
probe { radius: 0.002 stiffness: 500 }
probe { radius: 0.01 contact: SURFACE shape: PLANE axis { y: -1 } bonded: true }
plate { normal { z: -1 } offset: -0.4 stiffness: 2e4 }
solver {
  integrator: EXPLICIT_EULER rate_hz: 2000 substeps: 3 newton_iterations: 4 cg_iterations: 25
  cg_tolerance: 1e-6 newton_tolerance: 2e-6 mass_damping: 0.5 gravity { z: -9.81 }
  min_length_fraction: 0.1 max_speed: 20
}
)";
  auto a = parse_scene(text, "every.pbtxt", kConfigs);
  ASSERT_TRUE(a) << a.error();
  auto b = WriteAndRead(a.value(), "every.pbtxt");
  ASSERT_TRUE(b) << b.error();
  ExpectSameScene(a.value(), b.value(), "every field");
  // Numbers no short decimal holds come back bit for bit.
  SceneFile odd = a.value();
  odd.spec.groups[0].card.conical.G = 4.76372418e+09 / 3;
  odd.spec.bulk_modulus = 1.0 / 3 * 1e5;
  odd.spec.spread_modulus = odd.spec.bulk_modulus * 0.1;
  auto c = WriteAndRead(odd, "odd.pbtxt");
  ASSERT_TRUE(c) << c.error();
  ExpectSameScene(odd, c.value(), "odd numbers");
  // A lattice away from the origin, with the active region.
  auto region = parse_scene(
      std::string(kGood) + "solver { active_region { tolerance: 2e-4 far_every: -1 } }\n",
      "r.pbtxt", kConfigs);
  ASSERT_TRUE(region) << region.error();
  SceneFile r = region.value();
  r.geometry.origin = Vec3(0.5, 0, 0);
  for (auto& n : r.spec.mesh.nodes) n += r.geometry.origin;
  auto d = WriteAndRead(r, "region.pbtxt");
  ASSERT_TRUE(d) << d.error();
  ExpectSameScene(r, d.value(), "active region");
  // What the writer printed is protobuf's text format of the Scene message.
  const std::string written = scene_text(a.value());
  EXPECT_NE(written.find("families: FACE_DIAGONAL\n  families: BODY_DIAGONAL\n"), std::string::npos)
      << written;
  EXPECT_NE(written.find("cylinder {\n  radius: 0.021\n"), std::string::npos) << written;
}

// The calibrated card's fragment: the material alone, pasted into a scene with geometry.
TEST(SceneWriterTest, MaterialTextPastesIntoAScene) {
  auto a = parse_scene(kGood, "s.pbtxt", kConfigs);
  ASSERT_TRUE(a) << a.error();
  BodySpec material;
  material.bulk_modulus = 2.5e5 / 3;
  material.spread_modulus = material.bulk_modulus;
  material.shear_modulus = 1.0 / 7;
  SpringGroupSpec g = a.value().spec.groups[0];
  g.card.conical.precompression = 1e-4 / 3;
  g.families = kEdge;
  material.groups = {g};
  g.name = "diagonals";
  g.families = kFaceDiagonal | kBodyDiagonal;
  g.card.conical.G *= 36.0 / 17;
  material.groups.push_back(g);
  const std::string text = material_text(material);
  EXPECT_EQ(text.find("lattice"), std::string::npos) << text;
  std::string scene = kGood;
  scene.erase(scene.find("group {"), scene.find("fixed {") - scene.find("group {"));
  auto b = parse_scene(scene + text, "pasted.pbtxt", kConfigs);
  ASSERT_TRUE(b) << b.error();
  const BodySpec& s = b.value().spec;
  EXPECT_EQ(s.bulk_modulus, material.bulk_modulus);
  EXPECT_EQ(s.spread_modulus, material.spread_modulus);
  EXPECT_EQ(s.shear_modulus, material.shear_modulus);
  ExpectSameGroups(material.groups, s.groups, "pasted");
  // Zero terms are left out, as the scene's defaults are zero.
  material.spread_modulus = material.shear_modulus = 0;
  EXPECT_EQ(material_text(material).find("spread_modulus"), std::string::npos);
  EXPECT_EQ(material_text(material).find("shear_modulus"), std::string::npos);
}

}  // namespace
}  // namespace conica::io
