// Compression experiments: a linear lattice cube against the analytic stiffness of its lattice,
// and the homogenised cell surrogate against the full body between plates.
#include "lab/compression.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>

#include "core/stability.h"
#include "lab/quasi_static.h"

namespace conica::lab {
namespace {

SpringCard Hooke(double k, double L) {
  SpringCard c;
  c.law = LawKind::kHooke;
  c.hooke_k = k;
  c.hooke_length = L;
  return c;
}

// A cube of side H and cells^3 hexahedra between frictionless plates: base held along z, two
// base nodes pinned against rigid motion, a top plate from ensure_top_plate. Implicit solver.
BodySpec CubeSpec(const SpringCard& card, int cells, double H) {
  BodySpec s;
  s.mesh = make_box_lattice(Vec3(H, H, H), {cells, cells, cells});
  s.density = 1000;
  s.groups.push_back({"all", card, kAllFamilies, {}, Vec3::Zero(), 10});
  FixedSelector base, pin, pin2;
  base.kind = FixedSelector::Kind::kPlane;
  base.offset = 0;
  base.axes = 4;
  pin.kind = pin2.kind = FixedSelector::Kind::kNodes;
  pin.nodes = {0};
  pin.axes = 3;
  pin2.nodes = {cells};
  pin2.axes = 2;
  s.fixed = {base, pin, pin2};
  s.options.integrator = Integrator::kImplicitEuler;
  s.options.dt = 0.01;
  s.options.newton_iterations = 3;
  s.options.cg_iterations = 200;
  s.options.cg_tolerance = 1e-10;
  s.options.mass_damping = 20;
  EXPECT_TRUE(ensure_top_plate(&s));
  return s;
}

// Uniaxial modulus of the hex lattice with edge, face-diagonal and body-diagonal springs by
// homogenisation. Under the strain mapping a spring of rest length l0 and volume share V/28 (each
// cell gives each of its 28 springs 1/28 of its volume) has axial stiffness
// k_s = (V / (28 l0 L^2)) K (L / l0), so k_s l0^2 = V K / (28 L) and the stiffness tensor
// (Cauchy-Born, pair springs) is C_ijkl = (1/V) sum_s k_s l0^2 d_i d_j d_k d_l
//                                      = K / (28 L) sum over the 28 directions of d_i d_j d_k d_l.
// With lateral contraction free, E_z = 1 / S_zzzz, S = C^-1 in Voigt form.
// kappa (Pa): volume stiffness, which adds kappa to C11 and C12 (a bulk term kappa tr(e)^2 / 2);
// mu (Pa): shear stiffness, an isotropic term of shear modulus mu and no bulk modulus.
double LatticeYoungZ(double K, double L, double kappa = 0, double mu = 0) {
  std::vector<Vec3> dirs;
  for (int i = 0; i < 8; ++i)
    for (int j = i + 1; j < 8; ++j) {
      const Vec3 a(i & 1, (i >> 1) & 1, (i >> 2) & 1), b(j & 1, (j >> 1) & 1, (j >> 2) & 1);
      dirs.push_back((b - a).normalized());
    }
  EXPECT_EQ(dirs.size(), 28u);
  const int vi[6] = {0, 1, 2, 1, 0, 0}, vj[6] = {0, 1, 2, 2, 2, 1};
  Eigen::Matrix<double, 6, 6> C = Eigen::Matrix<double, 6, 6>::Zero();
  for (const Vec3& d : dirs)
    for (int p = 0; p < 6; ++p)
      for (int q = 0; q < 6; ++q) C(p, q) += d[vi[p]] * d[vj[p]] * d[vi[q]] * d[vj[q]];
  C *= K / (28 * L);
  C.topLeftCorner<3, 3>().array() += kappa - 2 * mu / 3;
  for (int p = 0; p < 3; ++p) {
    C(p, p) += 2 * mu;
    C(p + 3, p + 3) += mu;
  }
  // Voigt compliance: S = C^-1 (engineering shear strains); S(2,2) is S_zzzz.
  const Eigen::Matrix<double, 6, 6> S = C.inverse();
  return 1.0 / S(2, 2);
}

TEST(CompressionTest, HookeCubeMatchesAnalyticLatticeModulus) {
  const double K = 100, L = 0.01, H = 0.02;
  // Cubic symmetry gives C11 = 58/9, C12 = C44 = 13/9 (x K / (28 L)), so
  // E = (C11 - C12)(C11 + 2 C12) / (C11 + C12) = 3780/639 K / (28 L) = 0.21127 K / L.
  const double E = LatticeYoungZ(K, L);
  EXPECT_NEAR(E, 3780.0 / 639 / 28 * K / L, 1e-9 * E);
  Model m;
  ASSERT_EQ(build_model(CubeSpec(Hooke(K, L), 4, H), &m), "");
  const double strain = 0.01, rate = 0.2e-3;  // 0.2 mm/s: 1 s of compression
  CompressionStats st;
  const Curve c = compression_curve(m, rate, strain, 10, &st);
  EXPECT_EQ(st.rollbacks, 0u);
  EXPECT_LT(st.failed_at, 0);  // a sound run
  EXPECT_LT(st.max_penetration, 1e-3 * strain * H);
  const double E_sim = c.back().force / (H * H) / strain;
  EXPECT_NEAR(E_sim / E, 1.0, 0.01) << "simulated " << E_sim << " Pa, lattice " << E << " Pa";
  // Halfway the curve is linear.
  EXPECT_NEAR(c[5].force / c.back().force, 0.5, 0.01);
}

TEST(CompressionTest, CellSurrogateMatchesFullBodyWhileHomogeneous) {
  SpringCard card;
  card.law = LawKind::kConical;
  card.conical = ConicalCard{2e8, 1.2e-3, 2e-3, 8e-3, 10e-3, 3};  // Type I, stroke 0.8 L0
  card.stiffness_cap = 1000;
  const double H = 0.02;
  Model body, cell;
  const BodySpec spec = CubeSpec(card, 3, H);
  ASSERT_EQ(build_model(spec, &body), "");
  ASSERT_EQ(make_uniaxial_cell(spec.groups, Mapping::kStrain, 0.01, &cell), "");
  const double strain = 0.15;
  const Curve c = compression_curve(body, 1e-3, strain, 5);
  const std::vector<double> sigma = cell_stress_curve(cell, {0.03, 0.06, 0.09, 0.12, 0.15});
  for (int i = 1; i <= 5; ++i)
    EXPECT_NEAR(c[i].force / (sigma[i - 1] * H * H), 1.0, 0.02) << "strain " << 0.03 * i;
  // Small-strain cell modulus is the lattice's.
  const ConicalLaw law(card.conical);
  const std::vector<double> s0 = cell_stress_curve(cell, {1e-5});
  EXPECT_NEAR(s0[0] / 1e-5 / LatticeYoungZ(law.k0(), card.conical.L0), 1.0, 1e-3);
}

TEST(CompressionTest, VolumeAndShearStiffnessKeepTheCompressedBodyStable) {
  // Small strain: the cell's modulus is that of C + kappa (1 1 1)(1 1 1)^T (kappa = 20 E0 gives
  // the body a Poisson ratio of 0.49). The full body between frictionless plates follows the cell
  // while it stays homogeneous: pair springs alone and with volume stiffness to 24 % strain (the
  // points checked), near where this card's edges enter their stiffening phase (the volume body
  // still does at 27 %, the pair-spring body is at 71 % of the cell there). Past it the
  // pair-spring body collapses (its force falls to a fraction of the cell's, as in
  // docs/paper-reproduction.md); with volume
  // stiffness it leaves the homogeneous state but keeps carrying a rising load near the cell's;
  // with shear stiffness too (mu = E0 / 3, and the Gauss-point spread) it stays homogeneous to
  // 36 %.
  SpringCard card;
  card.law = LawKind::kConical;
  card.conical = ConicalCard{2e8, 1.2e-3, 2e-3, 8e-3, 10e-3, 3};
  card.stiffness_cap = 1000;
  const ConicalLaw law(card.conical);
  const double E0 = LatticeYoungZ(law.k0(), card.conical.L0);
  const double H = 0.02;
  std::vector<double> strains;
  for (int i = 1; i <= 12; ++i) strains.push_back(0.03 * i);
  enum Body { kSprings, kVolume, kVolumeShear };
  for (Body kind : {kSprings, kVolume, kVolumeShear}) {
    const double kappa = kind == kSprings ? 0 : 20 * E0;
    BodySpec spec = CubeSpec(card, 3, H);
    spec.bulk_modulus = kappa;
    spec.spread_modulus = kind == kVolumeShear ? kappa : 0;
    spec.shear_modulus = kind == kVolumeShear ? E0 / 3 : 0;
    Model cell, body;
    ASSERT_EQ(
        make_uniaxial_cell(spec.groups, Mapping::kStrain, 0.01, &cell, kappa, spec.shear_modulus),
        "");
    // Small strain: the lattice, the bulk term and the shear term (C11 += 4/3 mu, C12 -= 2/3 mu,
    // C44 += mu) in the analytic modulus.
    const double Ek = LatticeYoungZ(law.k0(), card.conical.L0, kappa, spec.shear_modulus);
    EXPECT_NEAR(cell_stress_curve(cell, {1e-5})[0] / 1e-5 / Ek, 1.0, 1e-3) << "body " << kind;
    ASSERT_EQ(build_model(spec, &body), "");
    const Curve c = compression_curve(body, 2e-3, 0.36, 12);
    const std::vector<double> sigma = cell_stress_curve(cell, strains);
    const int homogeneous = kind == kVolumeShear ? 12 : 8;
    for (int i = 1; i <= homogeneous; ++i)
      EXPECT_NEAR(c[i].force / (sigma[i - 1] * H * H), 1.0, 0.01)
          << "strain " << strains[i - 1] << ", body " << kind;
    std::printf("body %d (0 springs, 1 + volume, 2 + volume, spread, shear): full / cell at", kind);
    for (int i = 9; i <= 12; ++i)
      std::printf(" %.0f %%: %.3f", 100 * strains[i - 1], c[i].force / (sigma[i - 1] * H * H));
    std::printf("\n");
    const double end = c[12].force / (sigma[11] * H * H);
    if (kind == kSprings) {
      EXPECT_LT(end, 0.5) << "pair springs alone";
    } else {
      EXPECT_GT(Ek, 1.2 * E0);  // the bulk term matters at this kappa (1.26 E0)
      EXPECT_GT(end, 0.8) << "with volume stiffness";
      for (int i = 9; i <= 12; ++i)
        EXPECT_GT(c[i].force, c[i - 1].force) << "strain " << strains[i - 1] << ", body " << kind;
    }
  }
}

// The quasi-static test (static_compression_curve) against two independent answers on the
// shear-stiff cube of the test above: the homogenised cell (between frictionless plates a box
// lattice's affine state is an exact equilibrium, so the static body must give the cell's stress
// times its cross-section to the solver's tolerance), and the dynamic test at a slow plate
// (1 mm/s on a 20 mm cube, whose viscous and inertial forces are then a small part of the load):
// static and dynamic answers agree. And the static solve has no rate: damping on the cards does
// not change it.
// The shear-stiff cube of the test above (H = 20 mm, 3 cells, the Type I card with volume,
// spread and shear terms) and its homogenised cell's stress at 3, 6, ... 30 % strain.
constexpr double kCubeH = 0.02;
struct ShearStiffCube {
  BodySpec spec;
  std::vector<double> strains, sigma;  // -, Pa
};
ShearStiffCube MakeShearStiffCube() {
  SpringCard card;
  card.law = LawKind::kConical;
  card.conical = ConicalCard{2e8, 1.2e-3, 2e-3, 8e-3, 10e-3, 3};
  card.stiffness_cap = 1000;
  const ConicalLaw law(card.conical);
  const double E0 = LatticeYoungZ(law.k0(), card.conical.L0);
  const double kappa = 20 * E0;
  ShearStiffCube c;
  c.spec = CubeSpec(card, 3, kCubeH);
  c.spec.bulk_modulus = c.spec.spread_modulus = kappa;
  c.spec.shear_modulus = E0 / 3;
  Model cell;
  EXPECT_EQ(make_uniaxial_cell(c.spec.groups, Mapping::kStrain, 0.01, &cell, kappa, E0 / 3), "");
  for (int i = 1; i <= 10; ++i) c.strains.push_back(0.03 * i);
  c.sigma = cell_stress_curve(cell, c.strains);
  return c;
}

TEST(CompressionTest, StaticCompressionMatchesTheCellAndASlowDynamicTest) {
  const ShearStiffCube cube = MakeShearStiffCube();
  const BodySpec& spec = cube.spec;
  const std::vector<double>&strains = cube.strains, &sigma = cube.sigma;
  const double H = kCubeH;
  Model body;
  ASSERT_EQ(build_model(spec, &body), "");
  CompressionStats st;
  const Curve quasi = static_compression_curve(body, 0.3, 10, &st);
  const Curve dynamic = compression_curve(body, 1e-3, 0.3, 10);
  ASSERT_EQ(quasi.size(), 11u);
  for (int i = 1; i <= 10; ++i) {
    EXPECT_NEAR(quasi[i].displacement, 0.03 * i * H, 1e-12);
    // 3-5e-4 low: the plate is a stiff penalty, the body is compressed by the travel less the
    // plate's penetration
    EXPECT_NEAR(quasi[i].force / (sigma[i - 1] * H * H), 1.0, 1e-3) << "strain " << strains[i - 1];
    EXPECT_NEAR(dynamic[i].force / quasi[i].force, 1.0, 0.01) << "strain " << strains[i - 1];
  }
  EXPECT_LT(st.layer_spread / st.half_width, 1e-4) << "homogeneous";
  EXPECT_EQ(st.rollbacks, 0u);
  std::printf("static: %ld steps for 10 samples; dynamic / static at 30 %%: %.5f\n", st.steps,
              dynamic[10].force / quasi[10].force);
  BodySpec damped = spec;
  damped.groups[0].card.damping = 5;
  Model damped_body;
  ASSERT_EQ(build_model(damped, &damped_body), "");
  const Curve quasi_damped = static_compression_curve(damped_body, 0.3, 10);
  for (int i = 1; i <= 10; ++i) EXPECT_NEAR(quasi_damped[i].force / quasi[i].force, 1.0, 1e-9) << i;
}

// Through the served configuration (compression_curve's `served`): a multi-rate body (served at
// 1 kHz, the body at 50 Hz with a factor renewed every 10 body steps and a Newton tolerance)
// stepped as the body thread steps it compresses like the homogeneous cell (an independent
// one-cell computation) within 1 % to 30 % strain, at 0.6 mm/s.
TEST(CompressionTest, ServedMultiRateBodyCompressesLikeTheCell) {
  ShearStiffCube cube = MakeShearStiffCube();
  BodySpec& spec = cube.spec;
  const std::vector<double>&strains = cube.strains, &sigma = cube.sigma;
  const double H = kCubeH;
  spec.options.dt = 1e-3;
  spec.options.newton_iterations = 4;
  spec.options.cg_iterations = 40;
  spec.options.cg_tolerance = 1e-6;
  spec.options.newton_tolerance = 1e-7;
  spec.options.linear_solver = LinearSolver::kFactorCG;
  spec.options.body_rate_hz = 50;
  spec.options.refactor_every = 10;
  spec.options.refactor_iterations = 10;
  Model body;
  ASSERT_EQ(build_model(spec, &body), "");
  CompressionStats st;
  const Curve served = compression_curve(body, 0.6e-3, 0.3, 10, &st, true);
  EXPECT_NEAR(st.dt, 0.02, 1e-12);  // the body's step, 1 / 50 Hz
  EXPECT_EQ(st.rollbacks, 0u);
  for (int i = 1; i <= 10; ++i)
    EXPECT_NEAR(served[i].force / (sigma[i - 1] * H * H), 1.0, 0.01) << "strain " << strains[i - 1];
}

// A run that blows up says where: symplectic Euler at 10 ms on a lattice whose nodes ring at
// about 900 rad/s (omega h about 9, far past 2) fails on its first steps.
TEST(CompressionTest, ABlownUpRunSaysWhereItFailed) {
  BodySpec spec = CubeSpec(Hooke(100, 0.01), 4, 0.02);
  spec.options.integrator = Integrator::kSymplecticEuler;
  Model m;
  ASSERT_EQ(build_model(spec, &m), "");
  CompressionStats st;
  compression_curve(m, 1e-3, 0.2, 10, &st);
  EXPECT_GE(st.failed_at, 0);
  EXPECT_LT(st.failed_at, 0.1 * 0.2 * 0.02);  // within the first tenth of the travel
}

TEST(CompressionTest, AddsATopPlateOnlyWhenNone) {
  BodySpec s;
  s.mesh = make_box_lattice(Vec3(0.01, 0.01, 0.03), {1, 1, 3});
  EXPECT_TRUE(ensure_top_plate(&s));
  ASSERT_EQ(s.planes.size(), 1u);
  EXPECT_NEAR(s.planes[0].normal.z(), -1, 0);
  EXPECT_NEAR(s.planes[0].offset, -0.03, 1e-15);
  EXPECT_FALSE(ensure_top_plate(&s));
}

// layer_spread on a 2 x 2 x 4 cm box lattice (half width: the corner, sqrt(2) cm from the axis):
// 0 under any homogeneous compression with lateral expansion; a lean (each layer shifted along
// x in proportion to its height, top by s) moves the top layer's far corner to
// sqrt((a + s)^2 + a^2) while the base keeps sqrt(2) a; layers alternately wider and narrower
// (every other one scaled by 1.1) spread by 0.1 sqrt(2) a x its lateral stretch.
TEST(CompressionTest, LayerSpreadMeasuresTheDepartureFromTheHomogeneousState) {
  const double a = 0.01, H = 0.04;
  BodySpec spec = CubeSpec(Hooke(100, 0.01), 2, a * 2);
  spec.mesh = make_box_lattice(Vec3(2 * a, 2 * a, H), {2, 2, 4});
  spec.fixed.resize(1);
  spec.planes.clear();
  ASSERT_TRUE(ensure_top_plate(&spec));
  Model m;
  ASSERT_EQ(build_model(spec, &m), "");
  const Vec3 c(a, a, 0);  // the axis: through the rest centroid
  auto map = [&](auto f) {
    std::vector<Vec3> x(m.num_nodes());
    for (int i = 0; i < m.num_nodes(); ++i) x[i] = f(m.rest[i]);
    return x;
  };
  const double lat = 1.3, ax = 0.5;
  EXPECT_NEAR(layer_spread(m, map([&](const Vec3& r) {
                             return Vec3(c.x() + lat * (r.x() - c.x()),
                                         c.y() + lat * (r.y() - c.y()), ax * r.z());
                           })),
              0, 1e-15);
  const double shift = 2e-3;
  EXPECT_NEAR(layer_spread(m, map([&](const Vec3& r) {
                             return Vec3(r.x() + shift * r.z() / H, r.y(), ax * r.z());
                           })),
              std::hypot(a + shift, a) - std::sqrt(2.0) * a, 1e-12);
  EXPECT_NEAR(layer_spread(m, map([&](const Vec3& r) {
                             const double g = lat * (std::lround(r.z() / 0.01) % 2 ? 1.1 : 1.0);
                             return Vec3(c.x() + g * (r.x() - c.x()), c.y() + g * (r.y() - c.y()),
                                         ax * r.z());
                           })),
              0.1 * lat * std::sqrt(2.0) * a, 1e-12);
}

// The material check (core/stability.h) against the body: a lattice cube of a stiffening card
// with little shear stiffness between frictionless plates, solved quasi-statically. The analysis
// says the material loses strong ellipticity at some strain e*: the body follows the homogenised
// cell up to shortly before e*, and does not carry on evenly much past it (it finds no
// equilibrium, or its layers leave the homogeneous state). (The converse does not hold: a material
// that stays elliptic can still let a finite body buckle.)
TEST(CompressionTest, TheBodyBucklesWhereItsMaterialLosesStrongEllipticity) {
  SpringCard card;
  card.law = LawKind::kConical;
  card.conical = ConicalCard{2e8, 1.2e-3, 2e-3, 8e-3, 10e-3, 3};
  card.stiffness_cap = 1000;
  const double H = 0.02, travel = 0.6;
  const int samples = 15;
  for (double mu : {1e3}) {
    BodySpec spec = CubeSpec(card, 3, H);
    spec.bulk_modulus = spec.spread_modulus = 4e4;
    spec.shear_modulus = mu;
    Model body, cell;
    ASSERT_EQ(build_model(spec, &body), "");
    ASSERT_EQ(make_uniaxial_cell(spec.groups, Mapping::kStrain, 0.01, &cell, 4e4, mu), "");
    const CompressionStability c = uniaxial_compression_stability(body, Vec3::UnitZ(), travel);
    body.planes[0].stiffness = rigid_plate_stiffness(body, false);
    QuasiStaticOptions qo;
    qo.samples = samples;
    QuasiStaticStats st;
    double first_uneven = -1;
    int j = 0;
    const Curve curve =
        quasi_static_curve(body, plate_load(body), plate_reaction(), travel * H, qo, &st,
                           [&](const Model& m, const State& s) {
                             ++j;
                             if (first_uneven < 0 && layer_spread(m, s.x) > 0.02 * 0.5 * H)
                               first_uneven = travel * j / samples;
                           });
    std::vector<double> strains;
    for (int k = 1; k <= samples; ++k) strains.push_back(travel * k / samples);
    const std::vector<double> sigma = cell_stress_curve(cell, strains);
    const double failed = st.failed_at >= 0 ? st.failed_at / H : -1;
    std::printf(
        "shear %.0f Pa: onset of strong-ellipticity loss %.3f; body failed at %.3f, uneven from "
        "%.3f (-1: never)\n",
        mu, c.onset_strain, failed, first_uneven);
    // Where the material is elliptic the body is the cell.
    const double stable_to = c.onset_strain < 0 ? travel : c.onset_strain - 0.03;
    for (int k = 1; k <= samples && strains[k - 1] <= stable_to; ++k)
      EXPECT_NEAR(curve[k].force / (sigma[k - 1] * H * H), 1.0, 0.01)
          << "strain " << strains[k - 1] << ", shear " << mu;
    ASSERT_GT(c.onset_strain, 0.3);
    ASSERT_LT(c.onset_strain, travel - 0.08);
    // Past the onset the body fails or leaves the homogeneous state, within 0.08 of it (two
    // increments).
    const double broke =
        failed >= 0 && (first_uneven < 0 || failed < first_uneven) ? failed : first_uneven;
    EXPECT_GE(broke, c.onset_strain - 0.03);
    EXPECT_LE(broke, c.onset_strain + 0.08);
    // The body's own check (its stiffness along the same quasi-static path) finds the equilibrium
    // unstable no later than the body leaves it, and no later than the material: a body with free
    // faces between frictionless plates loses stability before its bulk loses strong ellipticity
    // (measured: at 40-44 %, the material at 48.3 %; the symmetric quasi-static path follows the
    // cell on past it, the unstable branch).
    const CompressionEquilibria e = compression_equilibria(body, travel, samples);
    std::printf("body's equilibrium stable to %.3f, unstable at %.3f (%d modes)\n", e.stable_to,
                e.unstable_at, e.modes);
    EXPECT_TRUE(e.factored);
    ASSERT_GT(e.unstable_at, 0);
    EXPECT_LE(e.unstable_at, broke);
    EXPECT_LE(e.unstable_at, c.onset_strain);
    EXPECT_GE(e.stable_to, 0.3);
  }
}

}  // namespace
}  // namespace conica::lab
