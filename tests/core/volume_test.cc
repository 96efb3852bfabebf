// Volume and shear stiffness against independent values: element volumes against closed forms
// (a frustum's volume, the determinant of an affine map), their gradients and the body's forces
// against finite differences of volume and stored energy, the pressure of a uniform dilation,
// the shear stress of a simple shear, the implicit step against the pressure of a confined
// compression, and the guards of the builder.
#include "core/volume.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <random>

#include "core/body.h"
#include "core/step.h"

namespace conica {
namespace {

using Hex = std::array<Vec3, 8>;

Hex UnitCube() {
  return {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(0, 1, 0),
          Vec3(0, 0, 1), Vec3(1, 0, 1), Vec3(1, 1, 1), Vec3(0, 1, 1)};
}

TEST(VolumeTest, HexahedronVolumeIsExactForAffineMapsAndPlanarFaces) {
  Hex g;
  // An affine image of the unit cube: volume det(A).
  Eigen::Matrix3d A;
  A << 1.2, 0.3, -0.1, 0.05, 0.8, 0.2, -0.2, 0.1, 1.5;
  Hex x = UnitCube();
  for (Vec3& p : x) p = A * p + Vec3(0.3, -1, 2);
  EXPECT_NEAR(hex_volume_gradient(x.data(), g.data()), A.determinant(), 1e-14);
  // A frustum of a square pyramid (planar faces): h (A1 + A2 + sqrt(A1 A2)) / 3.
  const Hex f = {Vec3(0, 0, 0),     Vec3(2, 0, 0),     Vec3(2, 2, 0),     Vec3(0, 2, 0),
                 Vec3(0.5, 0.5, 1), Vec3(1.5, 0.5, 1), Vec3(1.5, 1.5, 1), Vec3(0.5, 1.5, 1)};
  EXPECT_NEAR(hex_volume_gradient(f.data(), g.data()), (4 + 1 + 2) / 3.0, 1e-14);
  // Mirrored node order: the same volume with the opposite sign.
  Hex m = f;
  for (Vec3& p : m) p.x() = -p.x();
  EXPECT_NEAR(hex_volume_gradient(m.data(), g.data()), -7 / 3.0, 1e-14);
  // A tetrahedron: the corner of the unit cube.
  const std::array<Vec3, 4> t = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)};
  std::array<Vec3, 4> tg;
  EXPECT_NEAR(tet_volume_gradient(t.data(), tg.data()), 1 / 6.0, 1e-15);
}

TEST(VolumeTest, GradientsMatchFiniteDifferences) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> jitter(-0.2, 0.2);
  Hex x = UnitCube();
  for (Vec3& p : x) p += Vec3(jitter(rng), jitter(rng), jitter(rng));  // non-planar faces
  Hex g, scratch;
  hex_volume_gradient(x.data(), g.data());
  const double h = 1e-6;
  for (int a = 0; a < 8; ++a)
    for (int c = 0; c < 3; ++c) {
      Hex xp = x, xm = x;
      xp[a][c] += h;
      xm[a][c] -= h;
      const double fd = (hex_volume_gradient(xp.data(), scratch.data()) -
                         hex_volume_gradient(xm.data(), scratch.data())) /
                        (2 * h);
      EXPECT_NEAR(g[a][c], fd, 1e-9) << "hex node " << a << " axis " << c;
    }
  std::array<Vec3, 4> t = {Vec3(0.1, 0, 0), Vec3(1, 0.2, 0), Vec3(0, 1, 0.3), Vec3(0.2, 0.1, 1)};
  std::array<Vec3, 4> tg, ts;
  tet_volume_gradient(t.data(), tg.data());
  for (int a = 0; a < 4; ++a)
    for (int c = 0; c < 3; ++c) {
      auto tp = t, tm = t;
      tp[a][c] += h;
      tm[a][c] -= h;
      const double fd =
          (tet_volume_gradient(tp.data(), ts.data()) - tet_volume_gradient(tm.data(), ts.data())) /
          (2 * h);
      EXPECT_NEAR(tg[a][c], fd, 1e-9) << "tet node " << a << " axis " << c;
    }
}

SpringCard SoftHooke() {
  SpringCard c;
  c.law = LawKind::kHooke;
  c.hooke_k = 5;
  c.hooke_length = 0.01;
  return c;
}

// A box lattice (or its tetrahedra) with volume stiffness (and Gauss-point spread stiffness for
// hexahedra), nothing fixed.
Model VolumeBody(bool tets, double kappa, double spread = 0, double shear = 0,
                 double stiffening = 0) {
  BodySpec b;
  b.mesh = make_box_lattice(Vec3(0.02, 0.03, 0.02), {2, 3, 2});
  if (tets) {
    // Five tetrahedra per cube (alternating so that faces match is not needed for forces).
    for (const auto& h : b.mesh.hexahedra) {
      static constexpr int kFive[5][4] = {
          {0, 1, 3, 4}, {1, 2, 3, 6}, {1, 4, 5, 6}, {3, 6, 7, 4}, {1, 3, 4, 6}};
      for (const auto& t : kFive) b.mesh.tetrahedra.push_back({h[t[0]], h[t[1]], h[t[2]], h[t[3]]});
    }
    b.mesh.hexahedra.clear();
  }
  b.groups.push_back({"all", SoftHooke(), kAllFamilies, {}, Vec3::Zero(), 10});
  b.bulk_modulus = kappa;
  b.spread_modulus = tets ? 0 : spread;
  b.shear_modulus = shear;
  b.shear_stiffening = stiffening;
  Model m;
  EXPECT_EQ(build_model(b, &m), "");
  return m;
}

TEST(VolumeTest, ForcesAreMinusTheGradientOfTheStoredEnergy) {
  // Kinds 5 and 6: the shear term stiffened (Yeoh), hexahedra and tetrahedra.
  for (int kind = 0; kind < 7; ++kind) {
    const bool tets = kind == 1 || kind == 4 || kind == 6;
    const Model m =
        VolumeBody(tets, 2e5, kind == 2 ? 1.5e5 : 0, kind >= 3 ? 4e4 : 0, kind >= 5 ? 0.7 : 0);
    State s = make_state(m);
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(-1e-3, 1e-3);
    for (Vec3& x : s.x) x += Vec3(u(rng), u(rng), u(rng));
    Workspace ws(m);
    compute_forces(m, s, ws);
    const double h = 1e-8;
    for (int i : {0, 7, m.num_nodes() / 2, m.num_nodes() - 1})
      for (int c = 0; c < 3; ++c) {
        State p = s, q = s;
        p.x[i][c] += h;
        q.x[i][c] -= h;
        const double fd = -(potential_energy(m, p) - potential_energy(m, q)) / (2 * h);
        EXPECT_NEAR(ws.force[i][c], fd, 1e-6 * (1 + std::abs(fd)))
            << "kind " << kind << " node " << i << " axis " << c;
      }
  }
}

TEST(VolumeTest, UniformDilationGivesTheBulkPressureOnTheBoundary) {
  // Every element dilated by J: the interior forces cancel and the boundary carries the pressure
  // p = -kappa (J - 1) on the box's faces: total force on the x = max face is p times its area.
  const double kappa = 3e5, J = 1.01, s = std::cbrt(J);
  for (bool tets : {false, true}) {
    const Model m = VolumeBody(tets, kappa, kappa);  // the spread is zero in a uniform dilation
    State st = make_state(m);
    for (Vec3& x : st.x) x *= s;
    // Springs alone, to subtract: the same body without volume stiffness.
    Model springs_only = m;
    springs_only.bulk_modulus = 0;
    Workspace ws(m), ws0(springs_only);
    compute_forces(m, st, ws);
    compute_forces(springs_only, st, ws0);
    double fx = 0;
    for (int i = 0; i < m.num_nodes(); ++i)
      if (m.rest[i].x() > 0.02 - 1e-9) fx += ws.force[i].x() - ws0.force[i].x();
    const double area = 0.03 * 0.02 * s * s;
    // J > 1: the pressure is negative and pulls the face inward (along -x).
    EXPECT_NEAR(fx / (-kappa * (J - 1) * area), 1.0, 1e-9) << (tets ? "tets" : "hexes");
  }
}

TEST(VolumeTest, SpreadResistsTheLayerModeThatOneVolumePerElementLeavesFree) {
  // One cell whose bottom face widens and top face narrows at constant volume: a frustum with
  // planar faces, h (A1 + A2 + sqrt(A1 A2)) / 3 = h for a unit cube, so A1 = (1 + t)^2 and
  // A2 = (1 - u)^2 with u solving that. The element's volume term stores nothing; the spread term
  // stores (kappa_s / (2 V0 / 8)) sum_q d_q^2 > 0, with the Gauss-point shares computed
  // independently here from the frustum's cross-section at each point's height.
  const double t = 0.1;
  // (1 + t)^2 + (1 - u)^2 + (1 + t)(1 - u) = 3: quadratic in w = 1 - u.
  const double a = 1 + t, w = (-a + std::sqrt(a * a - 4 * (a * a - 3))) / 2;
  BodySpec b;
  b.mesh = make_box_lattice(Vec3(1, 1, 1), {1, 1, 1});
  b.groups.push_back({"all", SoftHooke(), kAllFamilies, {}, Vec3::Zero(), 10});
  b.bulk_modulus = 1e5;
  b.spread_modulus = 4e4;
  Model m;
  ASSERT_EQ(build_model(b, &m), "");
  State s = make_state(m);
  for (int i = 0; i < 8; ++i) {
    const Vec3 r = m.rest[i];
    const double side = r.z() > 0.5 ? w : a;
    s.x[i] = Vec3(0.5 + (r.x() - 0.5) * side, 0.5 + (r.y() - 0.5) * side, r.z());
  }
  Model springs_only = m;
  springs_only.bulk_modulus = 0;
  springs_only.spread_modulus = 0;
  Model bulk_only = m;
  bulk_only.spread_modulus = 0;
  const double e_springs = potential_energy(springs_only, s);
  EXPECT_NEAR(potential_energy(bulk_only, s) - e_springs, 0, 1e-12);
  // Gauss points at heights (1 -+ 1/sqrt(3)) / 2, four each; side there s(z) = a + (w - a) z, and
  // a point's share of the volume is s(z)^2 / 8 (det of the map's Jacobian / 8 on [-1, 1]^3).
  double expected = 0;
  for (double z : {(1 - 1 / std::sqrt(3.0)) / 2, (1 + 1 / std::sqrt(3.0)) / 2}) {
    const double side = a + (w - a) * z, d = side * side / 8 - 1.0 / 8;
    expected += 4 * 0.5 * 8 * 4e4 / 1.0 * d * d;
  }
  EXPECT_GT(expected, 0);
  EXPECT_NEAR(potential_energy(m, s) - e_springs, expected, 1e-9 * expected);
}

TEST(VolumeTest, SimpleShearCarriesTheShearModulusAtAnyAngle) {
  // F = I + gamma e_x e_z^T: J = 1 and F^-T has no xz entry, so the isochoric neo-Hookean first
  // Piola stress is P_xz = mu gamma exactly; the top face carries mu gamma A along x.
  const double mu = 3e4, H = 0.02;
  for (bool tets : {false, true}) {
    Model m = VolumeBody(tets, 0, 0, mu);
    Model springs_only = m;
    springs_only.shear_modulus = 0;
    for (double gamma : {1e-3, 0.3}) {
      State st = make_state(m);
      for (int i = 0; i < m.num_nodes(); ++i) st.x[i].x() += gamma * m.rest[i].z();
      Workspace ws(m), ws0(springs_only);
      compute_forces(m, st, ws);
      compute_forces(springs_only, st, ws0);
      double fx = 0;
      for (int i = 0; i < m.num_nodes(); ++i)
        if (m.rest[i].z() > H - 1e-9) fx += ws.force[i].x() - ws0.force[i].x();
      const double area = 0.02 * 0.03;
      EXPECT_NEAR(fx / (-mu * gamma * area), 1.0, 1e-9)
          << (tets ? "tets" : "hexes") << ", gamma " << gamma;
    }
  }
}

TEST(VolumeTest, StiffenedShearFollowsYeohsSimpleShearStress) {
  // Simple shear F = I + gamma e_x e_z^T: J = 1, I1b - 3 = gamma^2, so Yeoh's energy
  // (mu / 2)(gamma^2 + beta gamma^4) gives P_xz = mu gamma (1 + 2 beta gamma^2) exactly.
  const double mu = 3e4, beta = 0.8, H = 0.02;
  for (bool tets : {false, true}) {
    Model m = VolumeBody(tets, 0, 0, mu, beta);
    Model springs_only = m;
    springs_only.shear_modulus = 0;
    for (double gamma : {1e-3, 0.3, 0.8}) {
      State st = make_state(m);
      for (int i = 0; i < m.num_nodes(); ++i) st.x[i].x() += gamma * m.rest[i].z();
      Workspace ws(m), ws0(springs_only);
      compute_forces(m, st, ws);
      compute_forces(springs_only, st, ws0);
      double fx = 0;
      for (int i = 0; i < m.num_nodes(); ++i)
        if (m.rest[i].z() > H - 1e-9) fx += ws.force[i].x() - ws0.force[i].x();
      const double area = 0.02 * 0.03;
      EXPECT_NEAR(fx / (-mu * gamma * (1 + 2 * beta * gamma * gamma) * area), 1.0, 1e-9)
          << (tets ? "tets" : "hexes") << ", gamma " << gamma;
    }
  }
}

// Implicit Euler with 1 s steps (on gram nodes: each step a static Newton solve) and a CG
// budget that converges the system.
void StaticImplicitSolve(SolverOptions* o) {
  o->integrator = Integrator::kImplicitEuler;
  o->dt = 1.0;
  o->newton_iterations = 4;
  o->cg_iterations = 300;
  o->cg_tolerance = 1e-12;
}

TEST(VolumeTest, ImplicitStepHoldsAConfinedPressureAtTheBulkModulus) {
  // A cube, every face on a frictionless support except the top, pressed down by 1 % with the
  // top held: in a state of uniaxial strain the volume term's stress is kappa e (springs soft),
  // so the implicit solver's equilibrium top force is kappa e A plus the springs' share.
  const double kappa = 1e6, H = 0.02, e = 0.01;
  BodySpec b;
  b.mesh = make_box_lattice(Vec3(H, H, H), {2, 2, 2});
  b.groups.push_back({"all", SoftHooke(), kAllFamilies, {}, Vec3::Zero(), 10});
  b.bulk_modulus = kappa;
  auto plane = [](Vec3 n, double off, int axes) {
    FixedSelector f;
    f.kind = FixedSelector::Kind::kPlane;
    f.normal = n;
    f.offset = off;
    f.axes = axes;
    return f;
  };
  b.fixed = {plane(Vec3::UnitX(), 0, 1), plane(Vec3::UnitX(), H, 1), plane(Vec3::UnitY(), 0, 2),
             plane(Vec3::UnitY(), H, 2), plane(Vec3::UnitZ(), 0, 4), plane(Vec3::UnitZ(), H, 4)};
  StaticImplicitSolve(&b.options);
  Model m;
  ASSERT_EQ(build_model(b, &m), "");
  State s = make_state(m);
  for (int i = 0; i < m.num_nodes(); ++i)
    if (m.rest[i].z() > H - 1e-9) s.x[i].z() = H * (1 - e);  // the top moved down, held there
  Workspace ws(m);
  for (int k = 0; k < 5; ++k) step(m, s, ws);
  // The solver finds the uniform strain (1 s steps on grams: each one a static Newton solve).
  for (int i = 0; i < m.num_nodes(); ++i)
    EXPECT_NEAR(s.x[i].z(), m.rest[i].z() * (1 - e), 1e-9 * H) << i;
  compute_forces(m, s, ws);
  double top = 0;
  for (int i = 0; i < m.num_nodes(); ++i)
    if (m.rest[i].z() > H - 1e-9) top += ws.force[i].z();
  // Interior nodes are in equilibrium, the top carries the stress.
  for (int i = 0; i < m.num_nodes(); ++i)
    if (m.fixed[i] == 0) {
      EXPECT_LT(ws.force[i].norm(), 1e-6 * kappa * e * H * H) << i;
    }
  Model springs_only = m;
  springs_only.bulk_modulus = 0;
  Workspace ws0(springs_only);
  compute_forces(springs_only, s, ws0);
  double top0 = 0;
  for (int i = 0; i < m.num_nodes(); ++i)
    if (m.rest[i].z() > H - 1e-9) top0 += ws0.force[i].z();
  // J = 1 - e exactly, pressure kappa e, pushing the top face up (+z).
  EXPECT_NEAR((top - top0) / (kappa * e * H * H), 1.0, 1e-9);
}

TEST(VolumeTest, BuilderRefusesBadBulkModuliAndFlatElements) {
  BodySpec b;
  b.mesh = make_box_lattice(Vec3(0.01, 0.01, 0.01), {1, 1, 1});
  b.groups.push_back({"all", SoftHooke(), kAllFamilies, {}, Vec3::Zero(), 10});
  Model m;
  b.bulk_modulus = -1;
  EXPECT_NE(build_model(b, &m).find("bulk_modulus must be >= 0"), std::string::npos);
  b.bulk_modulus = std::nan("");
  EXPECT_NE(build_model(b, &m).find("bulk_modulus must be >= 0"), std::string::npos);
  b.bulk_modulus = 1e5;
  b.options.active_region = true;
  EXPECT_NE(build_model(b, &m).find("active region"), std::string::npos);
  b.options.active_region = false;
  BodySpec flat = b;
  flat.mesh.nodes.push_back(Vec3(0.02, 0, 0));
  flat.mesh.nodes.push_back(Vec3(0.03, 0, 0));
  flat.mesh.tetrahedra.push_back({0, 1, 8, 9});  // four nodes on the x axis: no volume
  EXPECT_NE(build_model(flat, &m).find("tetrahedron 0 has no volume"), std::string::npos);
}

}  // namespace
TEST(VolumeTest, ImplicitStepFindsTheEquilibriumOfAShearedBlockWithEveryElementTerm) {
  // A block clamped at its base, its top moved sideways by 10 % of its height and held: a
  // non-uniform state (bending near the free sides) in which the bulk, spread and shear terms all
  // load the nodes. With 1 s steps on grams each implicit step is a static Newton solve on the
  // system's element blocks; its interior must come to rest (zero net force on every free node).
  const double H = 0.02, mu = 2e4, gamma = 0.1;
  BodySpec b;
  b.mesh = make_box_lattice(Vec3(H, H, H), {3, 3, 3});
  b.groups.push_back({"all", SoftHooke(), kAllFamilies, {}, Vec3::Zero(), 10});
  b.bulk_modulus = 50 * mu;
  b.spread_modulus = 50 * mu;
  b.shear_modulus = mu;
  FixedSelector base, top;
  base.normal = top.normal = Vec3::UnitZ();
  top.offset = H;
  b.fixed = {base, top};
  StaticImplicitSolve(&b.options);
  Model m;
  ASSERT_EQ(build_model(b, &m), "");
  State s = make_state(m);
  for (int i = 0; i < m.num_nodes(); ++i)
    if (m.rest[i].z() > H - 1e-9) s.x[i].x() += gamma * H;
  Workspace ws(m);
  compute_forces(m, s, ws);
  double start = 0;
  for (int i = 0; i < m.num_nodes(); ++i)
    if (m.fixed[i] == 0) start = std::max(start, ws.force[i].norm());
  ASSERT_GT(start, 1e-3 * mu * gamma * H * H);  // the sheared state starts far from rest
  for (int k = 0; k < 10; ++k) step(m, s, ws);
  compute_forces(m, s, ws);
  for (int i = 0; i < m.num_nodes(); ++i)
    if (m.fixed[i] == 0) {
      EXPECT_LT(ws.force[i].norm(), 1e-8 * mu * gamma * H * H) << i;
    }
}

}  // namespace conica
