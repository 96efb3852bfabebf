// Body building: lattice counts, lumped masses, groups, selectors, the mapping's refinement
// independence, and refusal of bad specs.
#include "core/body.h"

#include <gtest/gtest.h>

#include <cstdio>

#include "core/step.h"

namespace conica {
namespace {

SpringCard Hooke(double k, double L) {
  SpringCard c;
  c.law = LawKind::kHooke;
  c.hooke_k = k;
  c.hooke_length = L;
  return c;
}

SpringCard Conical() {
  SpringCard c;
  c.law = LawKind::kConical;
  c.conical = ConicalCard{50e3, 1e-3, 2e-3, 8e-3, 10e-3, 3};  // SI; stroke reached at 100 % strain
  c.stiffness_cap = 1e3;
  return c;
}

BodySpec BoxSpec(std::array<int, 3> cells, Vec3 size = Vec3(0.04, 0.04, 0.04)) {
  BodySpec b;
  b.mesh = make_box_lattice(size, cells);
  b.density = 1000;
  b.groups.push_back({"all", Conical(), kAllFamilies, {}, Vec3::Zero(), 10});
  return b;
}

TEST(BodyTest, PaperCubeHas320NodesAndLatticeSpringCounts) {
  Model m;
  ASSERT_EQ(build_model(BoxSpec({7, 7, 4}), &m), "");
  EXPECT_EQ(m.num_nodes(), 320);
  const int nx = 8, ny = 8, nz = 5;
  const int edges = (nx - 1) * ny * nz + nx * (ny - 1) * nz + nx * ny * (nz - 1);
  const int faces =
      2 * ((nx - 1) * (ny - 1) * nz + (nx - 1) * ny * (nz - 1) + nx * (ny - 1) * (nz - 1));
  const int bodies = 4 * (nx - 1) * (ny - 1) * (nz - 1);
  EXPECT_EQ(m.num_springs(), edges + faces + bodies);
  // Each family alone.
  for (auto [fam, count] :
       {std::pair{kEdge, edges}, {kFaceDiagonal, faces}, {kBodyDiagonal, bodies}}) {
    BodySpec s = BoxSpec({7, 7, 4});
    s.groups[0].families = fam;
    ASSERT_EQ(build_model(s, &m), "");
    EXPECT_EQ(m.num_springs(), count);
  }
  // Boundary: 2 triangles per boundary quad.
  EXPECT_EQ(static_cast<int>(m.surface.size()), 4 * (7 * 7 + 7 * 4 + 7 * 4));
}

TEST(BodyTest, LumpedMassesSumToDensityTimesVolume) {
  Model m;
  BodySpec s = BoxSpec({3, 4, 5}, Vec3(0.03, 0.02, 0.05));
  s.density = 1070;  // Ecoflex 00-30 specific gravity 1.07
  ASSERT_EQ(build_model(s, &m), "");
  EXPECT_NEAR(m.total_mass(), 1070 * 0.03 * 0.02 * 0.05, 1e-12);
  // A corner node of a hex lattice carries 1/8 of one cell.
  EXPECT_NEAR(m.mass[0], 1070 * (0.01 * 0.005 * 0.01) / 8, 1e-15);
}

TEST(BodyTest, TetrahedronVolumeAndHexDecomposition) {
  EXPECT_NEAR(tet_volume(Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)), 1.0 / 6,
              1e-15);
  Mesh box = make_box_lattice(Vec3(2, 3, 4), {1, 1, 1});
  EXPECT_NEAR(hex_volume(box, box.hexahedra[0]), 24.0, 1e-12);
}

TEST(BodyTest, GroupsByAxisMakeAnisotropyAScene) {
  BodySpec s = BoxSpec({4, 4, 4});
  s.groups.clear();
  s.groups.push_back({"red_z", Hooke(10, 0.01), kEdge, {}, Vec3::UnitZ(), 1});
  s.groups.push_back({"white", Hooke(100, 0.01), kAllFamilies, {}, Vec3::Zero(), 10});
  Model m;
  ASSERT_EQ(build_model(s, &m), "");
  ASSERT_EQ(m.groups.size(), 2u);
  EXPECT_EQ(m.groups[0].end - m.groups[0].begin, 5 * 5 * 4);  // z edges
  for (int k = m.groups[0].begin; k < m.groups[0].end; ++k) {
    const Vec3 d = m.rest[m.spring_j[k]] - m.rest[m.spring_i[k]];
    EXPECT_NEAR(std::abs(d.normalized().z()), 1.0, 1e-12);
  }
}

TEST(BodyTest, FixedSelectors) {
  BodySpec s = BoxSpec({2, 2, 2});
  FixedSelector bottom;
  bottom.kind = FixedSelector::Kind::kPlane;
  bottom.normal = Vec3::UnitZ();
  bottom.offset = 0;
  s.fixed.push_back(bottom);
  FixedSelector one;
  one.kind = FixedSelector::Kind::kNodes;
  one.nodes = {26};
  s.fixed.push_back(one);
  Model m;
  ASSERT_EQ(build_model(s, &m), "");
  int fixed = 0;
  for (auto f : m.fixed) fixed += f == 7;
  EXPECT_EQ(fixed, 9 + 1);
  EXPECT_EQ(m.inv_mass[0], 0.0);
  EXPECT_GT(m.inv_mass[13], 0.0);
}

TEST(BodyTest, RefusesBadSpecsSayingWhy) {
  Model m;
  auto err = [&](auto mutate) {
    BodySpec s = BoxSpec({2, 2, 2});
    mutate(s);
    return build_model(s, &m);
  };
  EXPECT_NE(err([](BodySpec& s) { s.density = -1; }).find("density must be > 0"),
            std::string::npos);
  EXPECT_NE(err([](BodySpec& s) { s.groups[0].card.conical.d = 0; }).find("\"all\": d must be > 0"),
            std::string::npos);
  EXPECT_NE(err([](BodySpec& s) {
              s.groups.insert(s.groups.begin(),
                              {"none", Hooke(1, 1), kEdge, {"nowhere"}, Vec3::Zero(), 10});
            }).find("\"none\" matches no spring"),
            std::string::npos);
  EXPECT_NE(err([](BodySpec& s) {
              s.groups[0].families = kEdge;
              s.groups.push_back(s.groups[0]);
              s.groups[1].name = "edges2";
            }).find("matches no spring"),
            std::string::npos);
  EXPECT_NE(err([](BodySpec& s) {
              s.groups[0].families = kEdge;
              s.groups[0].axis = Vec3::UnitZ();  // x and y edges are left over
            }).find("springs match no spring group"),
            std::string::npos);
  EXPECT_NE(err([](BodySpec& s) {
              FixedSelector f;
              f.kind = FixedSelector::Kind::kPlane;
              f.offset = 5;
              s.fixed.push_back(f);
            }).find("matches no node"),
            std::string::npos);
  const std::string zero = err([](BodySpec& s) { s.mesh.nodes[1] = s.mesh.nodes[0]; });
  EXPECT_NE(zero.find("zero-length spring between nodes 0 and 1"), std::string::npos) << zero;
}

// Quasi-static uniaxial compression of a cube between frictionless plates, as kinematic
// boundary conditions: bottom nodes fixed in z, top nodes moved in z, two nodes pinned against
// rigid in-plane motion. Implicit Euler with a long step acts as a Newton solver. Returns the
// plate force (N) at `strain`.
double CompressForce(int cells, double strain, Mapping mapping) {
  const double H = 0.02;
  BodySpec s = BoxSpec({cells, cells, cells}, Vec3(H, H, H));
  s.mapping = mapping;
  s.options.integrator = Integrator::kImplicitEuler;
  s.options.dt = 1.0;
  s.options.newton_iterations = 4;
  s.options.cg_iterations = 300;
  s.options.cg_tolerance = 1e-9;
  FixedSelector bottom, top, pin, pin2;
  bottom.kind = top.kind = FixedSelector::Kind::kPlane;
  bottom.offset = 0;
  top.offset = H;
  bottom.tolerance = top.tolerance = 1e-9;
  bottom.axes = top.axes = 4;  // z only
  pin.kind = pin2.kind = FixedSelector::Kind::kNodes;
  // (0,0,0) and (0,0,H) fixed in x, y; (H,0,0) and (H,0,H) in y: the plates do not slide or
  // turn against each other (a free top plate lets the compressed lattice shear sideways).
  const int top0 = (cells + 1) * (cells + 1) * cells;
  pin.nodes = {0, top0};
  pin.axes = 3;
  pin2.nodes = {cells, top0 + cells};
  pin2.axes = 2;
  s.fixed = {bottom, top, pin, pin2};
  Model m;
  EXPECT_EQ(build_model(s, &m), "");
  State st = make_state(m);
  Workspace ws(m);
  std::vector<int> top_nodes;
  for (int i = 0; i < m.num_nodes(); ++i)
    if (std::abs(m.rest[i].z() - H) < 1e-9) top_nodes.push_back(i);
  const int ramp = 10;
  double force = 0;
  for (int t = 1; t <= ramp + 5; ++t) {
    for (int i : top_nodes) st.x[i].z() = H * (1 - strain * std::min(1.0, double(t) / ramp));
    step(m, st, ws);
    compute_forces(m, st, ws);
    force = 0;
    for (int i : top_nodes) force += ws.force[i].z();
  }
  EXPECT_EQ(st.counters.rollbacks, 0u);
  return force;
}

TEST(BodyTest, StrainMappingMakesCompressionForceIndependentOfResolution) {
  const double f8 = CompressForce(8, 0.2, Mapping::kStrain);
  const double f16 = CompressForce(16, 0.2, Mapping::kStrain);
  ASSERT_GT(f8, 0);
  std::printf("20 %% compression: 8^3 lattice %.6g N, 16^3 lattice %.6g N, difference %.3g %%\n",
              f8, f16, 100 * std::abs(f16 / f8 - 1));
  EXPECT_NEAR(f16 / f8, 1.0, 0.02) << "f8 = " << f8 << " N, f16 = " << f16 << " N";
  // Without the mapping (each mesh spring is the card's spring) the force depends on resolution.
  const double r8 = CompressForce(8, 0.2, Mapping::kRaw);
  const double r16 = CompressForce(16, 0.2, Mapping::kRaw);
  // About twice: four times the springs in parallel per area, twice as many in series.
  EXPECT_GT(r16 / r8, 1.5) << "r8 = " << r8 << " N, r16 = " << r16 << " N";
}

}  // namespace
}  // namespace conica
