// The CalculiX reference (lab/fem_reference.h): the quadratic mesh, the Yeoh fit, and a deck that
// ccx solves: homogeneous frictionless compression of a block, whose force is the law's own
// uniaxial stress times the area (an analytic value). The ccx case is skipped, saying so, when
// ccx is not installed (Debian calculix-ccx, in scripts/setup.sh).
#include "lab/fem_reference.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/body.h"
#include "io/scene.h"
#include "lab/calibration.h"
#include "lab/compression.h"
#include "lab/quasi_static.h"

namespace conica::lab {
namespace {

TEST(FemReferenceTest, QuadraticMeshSharesNodesAndEdges) {
  const Mesh box = make_box_lattice(Vec3(0.02, 0.02, 0.02), {2, 2, 2});
  const FemMesh a = make_c3d20_mesh(box, 1, false);
  EXPECT_FALSE(a.quarter);
  EXPECT_EQ(a.elements.size(), 8u);
  // Corners (n + 1)^3 and one midside node per lattice edge, 3 n (n + 1)^2.
  EXPECT_EQ(a.nodes.size(), 27u + 54u);
  const FemMesh b = make_c3d20_mesh(make_box_lattice(Vec3(0.02, 0.02, 0.02), {1, 1, 1}), 2, false);
  EXPECT_EQ(b.elements.size(), 8u);
  EXPECT_EQ(b.nodes.size(), 81u);
  for (const auto& e : a.elements) {
    // Midside node 9 (index 8) halfway along edge 1-2, node 17 (16) along 1-5.
    EXPECT_NEAR((a.nodes[e[8]] - 0.5 * (a.nodes[e[0]] + a.nodes[e[1]])).norm(), 0, 1e-15);
    EXPECT_NEAR((a.nodes[e[16]] - 0.5 * (a.nodes[e[0]] + a.nodes[e[4]])).norm(), 0, 1e-15);
    // Positive orientation: node 2 along +x, 4 along +y, 5 along +z from node 1.
    const Vec3 dx = a.nodes[e[1]] - a.nodes[e[0]], dy = a.nodes[e[3]] - a.nodes[e[0]],
               dz = a.nodes[e[4]] - a.nodes[e[0]];
    EXPECT_GT(dx.cross(dy).dot(dz), 0);
  }
  const FemMesh q = make_c3d20_mesh(box, 1, true);
  EXPECT_TRUE(q.quarter);
  EXPECT_EQ(q.elements.size(), 2u);  // one column of the two layers
  // A 3 x 3 lattice has an element across the centre planes: no quarter.
  EXPECT_FALSE(
      make_c3d20_mesh(make_box_lattice(Vec3(0.03, 0.03, 0.01), {3, 3, 1}), 1, true).quarter);
}

// The punch block of configs/validation (60 x 60 x 30 mm, 2.5 mm cells): thinned away from the
// punch, the same box; the punch drives whole quadratic faces (every node of a top face whose
// centre lies within the radius, none of a face partly under it).
TEST(FemReferenceTest, PunchMeshIsGradedAndDrivesWholeFaces) {
  const Mesh box = make_box_lattice(Vec3(0.06, 0.06, 0.03), {24, 24, 12});
  Mesh graded;
  ASSERT_EQ(coarsen_box_lattice(box, Vec3(0.03, 0.03, 0.015), 0.01, &graded), "");
  // Planes kept: x, y 10 mm each side at 2.5 mm, then 5, 10, 5 mm; z 10 mm at 2.5, then 5, 10, 5.
  EXPECT_EQ(graded.hexahedra.size(), 14u * 14u * 7u);
  double volume = 0;
  for (const auto& h : graded.hexahedra) volume += (graded.nodes[h[6]] - graded.nodes[h[0]]).prod();
  EXPECT_NEAR(volume, 0.06 * 0.06 * 0.03, 1e-15);
  Mesh holed = box;
  holed.hexahedra.pop_back();
  EXPECT_NE(coarsen_box_lattice(holed, Vec3(0.03, 0.03, 0.015), 0.01, &graded), "");

  ASSERT_EQ(coarsen_box_lattice(box, Vec3(0.03, 0.03, 0.015), 0.01, &graded), "");
  const FemMesh mesh = make_c3d20_mesh(graded, 1, true);
  ASSERT_TRUE(mesh.quarter);
  FemCase c;
  c.test = FemCase::Test::kIndent;
  c.travel = 0.006;
  c.punch_radius = 0.005;
  std::string deck;
  int driven = 0;
  ASSERT_EQ(write_calculix_deck(mesh, YeohLaw{16000, -2000, 1000, 6e-6}, c, "t", &deck, &driven),
            "");
  // Three faces of the quarter (centres at 1.77, 3.95, 3.95 mm from the axis): 3 x 8 nodes less
  // the 6 shared. Not the corner node at (5, 0), 5 mm from the axis but on a face partly outside.
  EXPECT_EQ(driven, 18);
  // The first increment a quarter of the largest.
  EXPECT_NE(deck.find("*STATIC\n0.0125, 1., "), std::string::npos)
      << deck.substr(deck.find("*STEP"));
}

TEST(FemReferenceTest, YeohFitRecoversItsLawAndTheSmallStrainModulus) {
  YeohLaw law{12000, -800, 900, 0};
  std::vector<double> e, p;
  for (int k = 1; k <= 40; ++k) {
    e.push_back(0.5 * k / 40);
    p.push_back(yeoh_uniaxial_stress(law, e.back()));
  }
  YeohLaw fit;
  ASSERT_EQ(fit_yeoh(e, p, 0.45, 0.03, &fit), "");
  EXPECT_NEAR(fit.c10 / law.c10, 1, 1e-9);
  EXPECT_NEAR(fit.c20 / law.c20, 1, 1e-7);
  EXPECT_NEAR(fit.c30 / law.c30, 1, 1e-7);
  // Small strain: E = 3 mu = 6 C10 (incompressible); K = 2 mu (1 + nu) / (3 (1 - 2 nu)).
  EXPECT_NEAR(yeoh_uniaxial_stress(law, 1e-6) / 1e-6 / (6 * law.c10), 1, 1e-5);
  const double mu = 2 * law.c10, k = 2 * mu * 1.45 / (3 * 0.1);
  EXPECT_NEAR(fit.d1 * k / 2, 1, 1e-9);
  EXPECT_NE(fit_yeoh({0.1, 0.2}, {1, 2}, 0.45, 0.03, &fit), "");
  // A softening curve has no stable fit.
  EXPECT_NE(fit_yeoh({0.1, 0.2, 0.3, 0.4}, {4, 3, 2, 1}, 0.45, 0.03, &fit), "");
}

TEST(FemReferenceTest, ReadsTheDriveSetTotals) {
  const std::string dat =
      "\n total force (fx,fy,fz) for set NDRIVE and time  0.5000000E+00\n\n"
      "        1.0E-03  2.0E-03 -3.000000E+00\n\n"
      " total force (fx,fy,fz) for set NDRIVE and time  0.1000000E+01\n\n"
      "        1.0E-03  2.0E-03 -7.000000E+00\n";
  FemCase c;
  c.travel = 0.004;
  std::vector<FemPoint> curve;
  ASSERT_EQ(read_calculix_totals(dat, c, true, &curve), "");
  ASSERT_EQ(curve.size(), 3u);
  EXPECT_NEAR(curve[1].displacement, 0.002, 1e-15);
  EXPECT_NEAR(curve[1].force, 12, 1e-12);
  EXPECT_NEAR(curve[2].force, 28, 1e-12);
  EXPECT_NE(read_calculix_totals("no totals", c, false, &curve), "");
}

// Runs ccx on `deck` in a fresh temporary folder and reads the driven set's reaction curve.
void RunCalculix(const std::string& deck, const FemCase& c, bool quarter, const std::string& tag,
                 std::vector<FemPoint>* curve) {
  const auto dir = std::filesystem::temp_directory_path() /
                   ("conica-fem-test-" + std::to_string(::getpid()) + tag);
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "job.inp") << deck;
  const std::string cmd = "cd '" + dir.string() + "' && ccx -i job > job.log 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << "ccx failed, see " << dir;
  std::ifstream in(dir / "job.dat");
  std::stringstream dat;
  dat << in.rdbuf();
  ASSERT_EQ(read_calculix_totals(dat.str(), c, quarter, curve), "");
  std::filesystem::remove_all(dir);
}

// ccx on a 2 x 2 x 1 block (frictionless plates: base held in z, the centre pinned), 30 % strain.
// A homogeneous state: the force is the uniaxial nominal stress times the rest area, for every
// increment, to the law's compressibility (Poisson 0.4999).
TEST(FemReferenceTest, CalculixCompressesABlockAsTheLawSays) {
  if (std::system("command -v ccx >/dev/null 2>&1") != 0)
    GTEST_SKIP() << "ccx (Debian calculix-ccx) is not installed: the CalculiX case is skipped";
  const double side = 0.02, height = 0.01;
  const YeohLaw law0{10000, -500, 800, 0};
  std::vector<double> e, p;
  for (int k = 1; k <= 30; ++k) {
    e.push_back(0.5 * k / 30);
    p.push_back(yeoh_uniaxial_stress(law0, e.back()));
  }
  YeohLaw law;
  ASSERT_EQ(fit_yeoh(e, p, 0.4999, 0.03, &law), "");
  for (bool quarter : {true, false}) {
    const FemMesh mesh =
        make_c3d20_mesh(make_box_lattice(Vec3(side, side, height), {2, 2, 1}), 1, quarter);
    ASSERT_EQ(mesh.quarter, quarter);
    FemCase c;
    c.test = FemCase::Test::kCompress;
    c.travel = 0.3 * height;
    c.increments = 6;
    std::string deck;
    ASSERT_EQ(write_calculix_deck(mesh, law, c, "test", &deck), "");
    std::vector<FemPoint> curve;
    RunCalculix(deck, c, mesh.quarter, quarter ? "q" : "f", &curve);
    ASSERT_GE(curve.size(), 7u);
    EXPECT_NEAR(curve.back().displacement, c.travel, 1e-12);
    for (size_t k = 1; k < curve.size(); ++k) {
      const double strain = curve[k].displacement / height;
      const double ref = yeoh_uniaxial_stress(law, strain) * side * side;
      EXPECT_NEAR(curve[k].force / ref, 1, 2e-3) << "strain " << strain << " quarter " << quarter;
    }
  }
}

// The shape factor of a bonded cube (S = 1/4), where Gent and Lindley's 1 + 2 S^2 is only a thin
// block's approximation: the bonded-to-frictionless force ratio of the served EF30 cube
// (configs/validation/cube-ef30.pbtxt, 10 x 10 x 10 cells) at 0.2 % strain against CalculiX's on
// the same geometry, quadratic hexahedra (a quarter, each cell split in 2 x 2 x 2), with a law of
// the body's small-strain Poisson ratio (the ratio does not depend on the modulus). Measured:
// conica 1.1906, CalculiX 1.1773 (1.1755 with each cell split in 3 x 3 x 3); docs/validation.md.
TEST(FemReferenceTest, BondedCubeStiffensAsTheContinuumDoes) {
  if (std::system("command -v ccx >/dev/null 2>&1") != 0)
    GTEST_SKIP() << "ccx (Debian calculix-ccx) is not installed: the CalculiX case is skipped";
  BodySpec spec;
  ASSERT_EQ(io::load_scene(CONICA_SOURCE_DIR "/configs/validation/cube-ef30.pbtxt", &spec), "");
  const double nu =
      body_poisson(lattice_moduli(spec.groups), spec.bulk_modulus, spec.shear_modulus);
  ASSERT_NEAR(nu, 0.45, 0.01);
  const double strain = 0.002;
  double conica[2] = {0, 0}, fem[2] = {0, 0};
  for (int bonded = 0; bonded < 2; ++bonded) {
    BodySpec s = spec;
    ensure_top_plate(&s);
    if (bonded) {
      ASSERT_EQ(bond_compression_plates(&s), "");
    }
    Model m;
    ASSERT_EQ(build_model(s, &m), "");
    m.planes[0].stiffness = std::max(m.planes[0].stiffness, rigid_plate_stiffness(m, false));
    QuasiStaticOptions o;
    o.samples = 1;
    o.tolerance = 1e-6;
    QuasiStaticStats st;
    const double travel = strain * plate_height(m);
    const Curve c = quasi_static_curve(m, plate_load(m), plate_reaction(), travel, o, &st);
    ASSERT_EQ(st.unconverged, 0);
    conica[bonded] = c.back().force;

    // A law of that Poisson ratio (its modulus scale cancels in the ratio).
    std::vector<double> e, p;
    const YeohLaw law0{10000, 0, 0, 0};
    for (int k = 1; k <= 10; ++k) {
      e.push_back(0.01 * k);
      p.push_back(yeoh_uniaxial_stress(law0, e.back()));
    }
    YeohLaw law;
    ASSERT_EQ(fit_yeoh(e, p, nu, 0.0, &law), "");
    const FemMesh mesh = make_c3d20_mesh(spec.mesh, 2, true);
    ASSERT_TRUE(mesh.quarter);
    FemCase fc;
    fc.test = FemCase::Test::kCompress;
    fc.bonded = bonded;
    fc.travel = travel;
    fc.increments = 1;
    std::string deck;
    ASSERT_EQ(write_calculix_deck(mesh, law, fc, "test", &deck), "");
    std::vector<FemPoint> curve;
    RunCalculix(deck, fc, mesh.quarter, bonded ? "cb" : "cf", &curve);
    ASSERT_GE(curve.size(), 2u);
    fem[bonded] = curve.back().force;
  }
  const double ratio = conica[1] / conica[0], ref = fem[1] / fem[0];
  EXPECT_GT(ref, 1);  // bonded is stiffer
  EXPECT_NEAR(ratio / ref, 1, 0.03) << "conica " << ratio << ", CalculiX " << ref;
}

}  // namespace
}  // namespace conica::lab
