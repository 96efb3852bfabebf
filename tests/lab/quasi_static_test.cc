// Quasi-static loading (lab/quasi_static.h) with bonded plates and a flat punch, against the
// static equilibrium of the same body solved directly: the stiffness by central finite
// differences of the force pass, the free nodes' equations solved densely.
#include "lab/quasi_static.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>

#include "core/step.h"
#include "hooke_block.h"

namespace conica::lab {
namespace {

BodySpec Block(int nx, int nz, double side, double height) {
  return HookeBlock(nx, nz, side, height);
}

// The reaction (N) of the linearised body with the driven nodes `driven` moved by `u` (m) on
// their fixed axes and every other fixed axis held: J_ff x_f = -J_fp u_p, reaction = the sum
// over the driven nodes of the z force.
double LinearReaction(const Model& m, const std::vector<int>& driven, const Vec3& u) {
  const int n = 3 * m.num_nodes();
  State s = make_state(m);
  for (auto& p : s.planes) p.offset = -1e9;  // plates out of the way: bonded nodes only
  Workspace ws(m);
  Eigen::MatrixXd J(n, n);
  const double h = 1e-7;
  for (int j = 0; j < n; ++j) {
    Eigen::VectorXd fp(n), fm(n);
    s.x = m.rest;
    s.x[j / 3][j % 3] += h;
    compute_forces(m, s, ws);
    for (int i = 0; i < m.num_nodes(); ++i) fp.segment<3>(3 * i) = ws.force[i];
    s.x[j / 3][j % 3] -= 2 * h;
    compute_forces(m, s, ws);
    for (int i = 0; i < m.num_nodes(); ++i) fm.segment<3>(3 * i) = ws.force[i];
    J.col(j) = (fp - fm) / (2 * h);
  }
  Eigen::VectorXd up = Eigen::VectorXd::Zero(n);
  std::vector<int> is_driven(m.num_nodes(), 0);
  for (int i : driven) is_driven[i] = 1;
  for (int i : driven)
    for (int a = 0; a < 3; ++a)
      if (m.free_axes[i][a] == 0) up(3 * i + a) = u[a];
  std::vector<int> free;
  for (int j = 0; j < n; ++j)
    if (m.free_axes[j / 3][j % 3] != 0) free.push_back(j);
  Eigen::MatrixXd Jff(free.size(), free.size());
  Eigen::VectorXd rhs(free.size());
  const Eigen::VectorXd Jup = J * up;
  for (size_t a = 0; a < free.size(); ++a) {
    rhs(a) = -Jup(free[a]);
    for (size_t b = 0; b < free.size(); ++b) Jff(a, b) = J(free[a], free[b]);
  }
  const Eigen::VectorXd xf = Jff.fullPivLu().solve(rhs);
  Eigen::VectorXd x = up;
  for (size_t a = 0; a < free.size(); ++a) x(free[a]) = xf(a);
  const Eigen::VectorXd f = J * x;
  double r = 0;
  for (int i : driven) r += f(3 * i + 2);
  return r;
}

TEST(QuasiStaticTest, BondedCompressionMatchesTheLinearEquilibrium) {
  BodySpec spec = Block(2, 2, 0.02, 0.02);
  ASSERT_EQ(bond_compression_plates(&spec), "");
  Model m;
  ASSERT_EQ(build_model(spec, &m), "");
  ASSERT_EQ(m.planes[0].bonded_nodes.size(), 9u);
  const double travel = 1e-6;  // m: 5e-5 strain, linear
  QuasiStaticOptions o;
  o.samples = 2;
  o.tolerance = 1e-9;
  QuasiStaticStats st;
  const Curve c = quasi_static_curve(m, plate_load(m), plate_reaction(), travel, o, &st);
  EXPECT_EQ(st.unconverged, 0);
  EXPECT_LT(st.worst_residual, 1e-9);
  EXPECT_LT(st.failed_at, 0);
  const double ref = LinearReaction(m, m.planes[0].bonded_nodes, Vec3(0, 0, -travel));
  ASSERT_GT(ref, 0);
  EXPECT_NEAR(c.back().force / ref, 1, 1e-4) << c.back().force << " vs " << ref;
  EXPECT_NEAR(c[1].force / c.back().force, 0.5, 1e-4);  // linear
}

// An increment that ends far out of balance is no result: with one crude iteration per
// increment (one Newton iteration, five CG iterations, no parts) a 20 % bonded compression does
// not reach equilibrium, and the stats name the travel of the first such increment.
TEST(QuasiStaticTest, AnIncrementFarOutOfBalanceIsReportedAsAFailure) {
  BodySpec spec = Block(2, 2, 0.02, 0.02);
  ASSERT_EQ(bond_compression_plates(&spec), "");
  Model m;
  ASSERT_EQ(build_model(spec, &m), "");
  QuasiStaticOptions o;
  o.samples = 4;
  o.max_iterations = 1;
  o.max_parts = 1;
  o.newton_iterations = 1;
  o.cg_iterations = 5;
  QuasiStaticStats st;
  const Curve all = quasi_static_curve(m, plate_load(m), plate_reaction(), 0.004, o, &st);
  EXPECT_GT(st.unconverged, 0);
  EXPECT_GT(st.worst_residual, kQuasiStaticFailure);
  EXPECT_NEAR(st.failed_at, 0.001, 1e-12);  // the first increment
  EXPECT_EQ(all.size(), 5u);
  EXPECT_EQ(st.increments, 4);
  // Asked to stop there, the run ends with that increment: the same point, no more steps.
  o.stop_at_failure = true;
  QuasiStaticStats cut;
  const Curve c = quasi_static_curve(m, plate_load(m), plate_reaction(), 0.004, o, &cut);
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(cut.increments, 1);
  EXPECT_NEAR(cut.failed_at, 0.001, 1e-12);
  EXPECT_EQ(c[1].displacement, all[1].displacement);
  EXPECT_EQ(c[1].force, all[1].force);
  EXPECT_EQ(cut.steps, 1);
}

TEST(QuasiStaticTest, BondedIsStifferThanFrictionless) {
  // The same block and travel: bonding the plates adds the lateral constraint (shape factor).
  double force[2];
  for (int bonded = 0; bonded < 2; ++bonded) {
    BodySpec spec = Block(3, 2, 0.03, 0.02);
    if (bonded) {
      ASSERT_EQ(bond_compression_plates(&spec), "");
    } else {
      std::vector<int> unused;
      ensure_top_plate(&spec);
      FixedSelector base;
      base.kind = FixedSelector::Kind::kPlane;
      base.offset = 0;
      base.axes = 4;
      FixedSelector pin;
      pin.kind = FixedSelector::Kind::kNodes;
      pin.nodes = {0};
      pin.axes = 3;
      FixedSelector pin2 = pin;
      pin2.nodes = {3};
      pin2.axes = 2;
      spec.fixed = {base, pin, pin2};
    }
    Model m;
    ASSERT_EQ(build_model(spec, &m), "");
    m.planes[0].stiffness = rigid_plate_stiffness(m, false);
    QuasiStaticOptions o;
    o.samples = 2;
    QuasiStaticStats st;
    force[bonded] =
        quasi_static_curve(m, plate_load(m), plate_reaction(), 2e-4, o, &st).back().force;
    EXPECT_EQ(st.unconverged, 0);
  }
  EXPECT_GT(force[1], 1.05 * force[0]);
}

TEST(QuasiStaticTest, FlatPunchMatchesTheLinearEquilibrium) {
  for (bool punch_bonded : {false, true}) {
    BodySpec spec = Block(4, 2, 0.04, 0.02);
    std::vector<int> punch;
    ASSERT_EQ(add_flat_punch(&spec, 0.0101, punch_bonded, true, &punch), "");
    ASSERT_EQ(punch.size(), 9u);  // the four top faces about the centre (theirs at 7.1 mm)
    Model m;
    ASSERT_EQ(build_model(spec, &m), "");
    const double depth = 1e-6;
    QuasiStaticOptions o;
    o.samples = 1;
    o.tolerance = 1e-9;
    QuasiStaticStats st;
    const Curve c = quasi_static_curve(m, punch_load(punch), punch_reaction(punch), depth, o, &st);
    EXPECT_EQ(st.unconverged, 0);
    const double ref = LinearReaction(m, punch, Vec3(0, 0, -depth));
    ASSERT_GT(ref, 0);
    EXPECT_NEAR(c.back().force / ref, 1, 1e-4) << punch_bonded;
  }
}

TEST(QuasiStaticTest, PunchDrivesWholeFacesWhoseCentreItCovers) {
  // 2 x 2 top faces of 10 mm, their centres 7.07 mm from the axis: a 1 mm punch covers none.
  BodySpec spec = Block(2, 1, 0.02, 0.01);
  std::vector<int> punch;
  EXPECT_EQ(add_flat_punch(&spec, 1e-3, false, true, &punch).find("no face"), 0u);
  // 7.1 mm covers all four: their nine nodes, 400 mm^2 (the whole top, a disc of 11.3 mm).
  BodySpec spec2 = Block(2, 1, 0.02, 0.01);
  double area = 0;
  ASSERT_EQ(add_flat_punch(&spec2, 7.1e-3, false, true, &punch, &area), "");
  EXPECT_EQ(punch.size(), 9u);
  EXPECT_NEAR(area, 4e-4, 1e-12);
  // One face centred on the axis is under any punch, however small.
  BodySpec spec3 = Block(1, 1, 0.02, 0.01);
  ASSERT_EQ(add_flat_punch(&spec3, 1e-4, false, true, &punch, &area), "");
  EXPECT_EQ(punch.size(), 4u);
  EXPECT_NEAR(area, 4e-4, 1e-12);
  // Tetrahedra: the same 20 mm square top split into triangles, each face judged by its centroid.
  BodySpec tet = Block(1, 1, 0.02, 0.01);
  std::vector<std::array<int, 4>> tets;
  for (const auto& h : tet.mesh.hexahedra) {
    // The six-tetrahedron split of a cube about its 0-6 diagonal.
    static constexpr int kSplit[6][4] = {{0, 1, 2, 6}, {0, 2, 3, 6}, {0, 3, 7, 6},
                                         {0, 7, 4, 6}, {0, 4, 5, 6}, {0, 5, 1, 6}};
    for (const auto& t : kSplit) tets.push_back({h[t[0]], h[t[1]], h[t[2]], h[t[3]]});
  }
  tet.mesh.hexahedra.clear();
  tet.mesh.tetrahedra = tets;
  // Top triangles (4, 5, 6) and (4, 6, 7): centroids 4.7 mm from the axis.
  EXPECT_EQ(add_flat_punch(&tet, 4e-3, false, true, &punch, &area).find("no face"), 0u);
  BodySpec tet2 = tet;
  tet2.fixed.clear();
  ASSERT_EQ(add_flat_punch(&tet2, 5e-3, false, true, &punch, &area), "");
  EXPECT_EQ(punch.size(), 4u);
  EXPECT_NEAR(area, 4e-4, 1e-12);
}

}  // namespace
}  // namespace conica::lab
