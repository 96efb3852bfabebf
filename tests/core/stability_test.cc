// Material stability under homogeneous compression (core/stability.h) against independent
// values: the body's own energy (step.h potential_energy) under an affine deformation, finite
// differences of it, and the acoustic tensor of isotropic elasticity with an initial stress in
// closed form.
#include "core/stability.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <cstdio>

#include "core/body.h"
#include "core/step.h"

namespace conica {
namespace {

// A 2 x 2 x 2 lattice (20 mm) of a stiffening conical card with volume and shear terms.
Model StiffeningBlock(double bulk, double shear) {
  BodySpec spec;
  spec.mesh = make_box_lattice(Vec3(0.02, 0.02, 0.02), {2, 2, 2});
  SpringCard card;
  card.law = LawKind::kConical;
  card.conical = ConicalCard{2e8, 1.2e-3, 2e-3, 8e-3, 10e-3, 3};
  card.stiffness_cap = 1000;
  spec.groups.push_back({"all", card, kAllFamilies, {}, Vec3::Zero(), 10});
  spec.bulk_modulus = bulk;
  spec.spread_modulus = bulk;
  spec.shear_modulus = shear;
  Model m;
  EXPECT_EQ(build_model(spec, &m), "");
  return m;
}

TEST(StabilityTest, HomogenisedStateIsTheBodyEnergyOfAnAffineDeformation) {
  const Model m = StiffeningBlock(4e4, 1e4);
  // Compressed 35 % along z (its edges in their stiffening phase), stretched and sheared.
  Mat3 F;
  F << 1.12, 0.04, 0.03, -0.02, 1.15, 0.05, 0.01, -0.03, 0.65;
  State s = make_state(m);
  for (int i = 0; i < m.num_nodes(); ++i) s.x[i] = F * m.rest[i];
  const HomogenisedState h = homogenised_state(m, F);
  EXPECT_NEAR(h.energy * body_volume(m) / potential_energy(m, s), 1.0, 1e-10);
  // Stress: central differences of the energy; tangent: of the stress.
  const double step = 1e-6;
  for (int k = 0; k < 9; ++k) {
    Mat3 Fp = F, Fm = F;
    Fp.data()[k] += step;
    Fm.data()[k] -= step;
    const HomogenisedState hp = homogenised_state(m, Fp), hm = homogenised_state(m, Fm);
    EXPECT_NEAR((hp.energy - hm.energy) / (2 * step), h.stress.data()[k], 1e-6 * h.stress.norm())
        << "stress component " << k;
    const Mat3 dP = (hp.stress - hm.stress) / (2 * step);
    for (int j = 0; j < 9; ++j)
      EXPECT_NEAR(dP.data()[j], h.tangent(j, k), 1e-5 * h.tangent.norm())
          << "tangent (" << j << ", " << k << ")";
  }
}

// A(i, A, j, B) of isotropic linear elasticity (Lame lambda, mu) with an initial stress S:
// lambda d_iA d_jB + mu (d_ij d_AB + d_iB d_jA) + S_AB d_ij. Its acoustic tensor is
// mu I + (lambda + mu) n n^T + (n . S n) I.
Mat9 IsotropicWithInitialStress(double lambda, double mu, const Mat3& S) {
  Mat9 A = Mat9::Zero();
  auto d = [](int a, int b) { return a == b ? 1.0 : 0.0; };
  for (int i = 0; i < 3; ++i)
    for (int a = 0; a < 3; ++a)
      for (int j = 0; j < 3; ++j)
        for (int b = 0; b < 3; ++b)
          A(3 * a + i, 3 * b + j) = lambda * d(i, a) * d(j, b) +
                                    mu * (d(i, j) * d(a, b) + d(i, b) * d(j, a)) +
                                    S(a, b) * d(i, j);
  return A;
}

TEST(StabilityTest, SoftestWaveOfIsotropicElasticityUnderAnInitialStress) {
  const double lambda = 3e5, mu = 2e4;
  // No initial stress: every direction's softest wave is a shear wave of modulus mu.
  EXPECT_NEAR(softest_wave(IsotropicWithInitialStress(lambda, mu, Mat3::Zero())).modulus, mu,
              1e-9 * mu);
  // A compressive stress s along z lowers the waves travelling along z by s: the softest is
  // mu - s, normal z, polarised across it. Past s = mu it is negative (strong ellipticity lost).
  for (double s : {0.5 * mu, 1.5 * mu}) {
    const Mat3 S = Vec3(0, 0, -s).asDiagonal();
    const SoftestWave w = softest_wave(IsotropicWithInitialStress(lambda, mu, S));
    EXPECT_NEAR(w.modulus, mu - s, 1e-9 * mu) << s;
    EXPECT_NEAR(std::abs(w.normal.z()), 1.0, 1e-9) << s;
    EXPECT_NEAR(w.polarisation.z(), 0.0, 1e-6) << s;
  }
  // An oblique stress axis: the softest normal follows it.
  const Vec3 axis = Vec3(1, 2, 2).normalized();
  const Mat3 S = -0.3 * mu * axis * axis.transpose();
  const SoftestWave w = softest_wave(IsotropicWithInitialStress(lambda, mu, S));
  EXPECT_NEAR(w.modulus, 0.7 * mu, 1e-9 * mu);
  EXPECT_NEAR(std::abs(w.normal.dot(axis)), 1.0, 1e-9);
}

TEST(StabilityTest, UniaxialPathLeavesTheLateralFacesFree) {
  const Model m = StiffeningBlock(4e4, 1e4);
  const CompressionStability c = uniaxial_compression_stability(m, Vec3::UnitZ(), 0.3);
  EXPECT_EQ(c.checked_to, 0.3);
  // The lateral stretches of that state leave no lateral normal stress and are equal (the
  // lattice is symmetric in x and y); the body expands sideways.
  const Mat3 F = Vec3(c.lateral_stretch(0), c.lateral_stretch(1), 0.7).asDiagonal();
  const HomogenisedState h = homogenised_state(m, F);
  EXPECT_LT(std::abs(h.stress(0, 0)), 1e-8 * std::abs(h.stress(2, 2)));
  EXPECT_LT(std::abs(h.stress(1, 1)), 1e-8 * std::abs(h.stress(2, 2)));
  EXPECT_NEAR(c.lateral_stretch(0), c.lateral_stretch(1), 1e-9);
  EXPECT_GT(c.lateral_stretch(0), 1.0);
  // A tilted axis gives the same answer in its own frame (the material check does not depend on
  // the world frame): the lattice is cubic, so along x it is the same as along z.
  const CompressionStability cx = uniaxial_compression_stability(m, Vec3::UnitX(), 0.3);
  EXPECT_NEAR(cx.lateral_stretch(0), c.lateral_stretch(0), 1e-8);
}

TEST(StabilityTest, ShearStiffnessDelaysTheOnset) {
  // The stiffening card's edges carry the load; with little shear stiffness the material loses
  // strong ellipticity (at 48 % strain) long before its coils bottom out (the stroke is 80 % of
  // the spring's length); more shear stiffness moves the onset later (none to 80 % here).
  const CompressionStability weak =
      uniaxial_compression_stability(StiffeningBlock(4e4, 1e3), Vec3::UnitZ(), 0.8);
  const CompressionStability firm =
      uniaxial_compression_stability(StiffeningBlock(4e4, 3e4), Vec3::UnitZ(), 0.8);
  std::printf("onset of strong-ellipticity loss: shear 1 kPa %.4f, 30 kPa %.4f (-1: none)\n",
              weak.onset_strain, firm.onset_strain);
  ASSERT_GT(weak.onset_strain, 0);
  EXPECT_TRUE(firm.onset_strain < 0 || firm.onset_strain > weak.onset_strain + 0.01)
      << weak.onset_strain << " " << firm.onset_strain;
  // At the onset the softest wave travels along the load, polarised across it: the zig-zag of
  // the compressed columns.
  EXPECT_NEAR(std::abs(weak.wave.normal.z()), 1.0, 1e-3);
  EXPECT_NEAR(weak.wave.polarisation.z(), 0.0, 1e-3);
  EXPECT_NEAR(weak.wave.modulus, 0.0, 1e-3 * 1e3);
}

// The body's stiffness at a state, from a different route than equilibrium_stability's (central
// second differences of the stored energy, potential_energy, on the free axes): its eigenvalues.
Eigen::VectorXd EnergyHessianEigenvalues(const Model& m, const State& s0) {
  std::vector<std::pair<int, int>> dof;
  for (int i = 0; i < m.num_nodes(); ++i)
    for (int c = 0; c < 3; ++c)
      if (m.free_axes[i][c] != 0) dof.push_back({i, c});
  const int n = static_cast<int>(dof.size());
  const double h = 1e-6;  // m
  State s = s0;
  auto energy = [&](int a, double da, int b, double db) {
    s.x[dof[a].first][dof[a].second] += da;
    s.x[dof[b].first][dof[b].second] += db;
    const double e = potential_energy(m, s);
    s.x[dof[a].first][dof[a].second] -= da;
    s.x[dof[b].first][dof[b].second] -= db;
    return e;
  };
  Eigen::MatrixXd H(n, n);
  for (int a = 0; a < n; ++a)
    for (int b = a; b < n; ++b) {
      H(a, b) =
          (energy(a, h, b, h) - energy(a, h, b, -h) - energy(a, -h, b, h) + energy(a, -h, b, -h)) /
          (4 * h * h);
      H(b, a) = H(a, b);
    }
  return Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(H).eigenvalues();
}

TEST(StabilityTest, EquilibriumStabilityCountsTheEnergyHessiansNegativeEigenvalues) {
  // The stiffening block with little shear stiffness (its material loses strong ellipticity at
  // 48 % strain), its base clamped, squeezed along z and stretched across it: the count of modes
  // along which the energy falls (eigenvalues below -shift) against the eigenvalues of the
  // energy's Hessian, from none at rest and stretched (-10 %) to many under compression (its
  // compressed columns' transverse stiffness -f / l; the top is free here).
  const Model m = [] {
    Model b = StiffeningBlock(4e4, 1e3);
    for (int i = 0; i < b.num_nodes(); ++i)
      if (b.rest[i].z() < 1e-9) {
        b.free_axes[i] = Vec3::Zero();
        b.fixed[i] = 7;
      }
    return b;
  }();
  int unstable = 0, stable = 0;
  for (double strain : {-0.1, 0.0, 0.1, 0.3, 0.5, 0.7}) {
    State s = make_state(m);
    const double lateral = 1 + 0.3 * strain;
    for (int i = 0; i < m.num_nodes(); ++i)
      s.x[i] = Vec3(lateral * m.rest[i].x(), lateral * m.rest[i].y(), (1 - strain) * m.rest[i].z());
    // A small irregular displacement, so that no count rests on the symmetry of the lattice.
    for (int i = 0; i < m.num_nodes(); ++i)
      if (m.fixed[i] == 0) s.x[i] += 1e-4 * Vec3(std::sin(3.1 * i), std::cos(1.7 * i), std::sin(i));
    const EquilibriumStability e = equilibrium_stability(m, s);
    ASSERT_TRUE(e.factored) << strain;
    const Eigen::VectorXd ev = EnergyHessianEigenvalues(m, s);
    int below = 0;
    for (int k = 0; k < ev.size(); ++k) below += ev[k] < -e.shift;
    std::printf("strain %.2f: %d negative (energy Hessian: %d below -%.3g N/m; lowest %.4g)\n",
                strain, e.negative, below, e.shift, ev[0]);
    EXPECT_EQ(e.negative, below) << "strain " << strain;
    (e.negative > 0 ? unstable : stable) += 1;
  }
  EXPECT_GE(stable, 1);
  EXPECT_GE(unstable, 1);
}

}  // namespace
}  // namespace conica
