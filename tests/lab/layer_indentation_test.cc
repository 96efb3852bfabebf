// Indentation of an elastic layer bonded to a rigid base (Hayes et al. 1972) against independent
// values only: the layer's compliance against the Navier equations integrated directly, the
// half-space and thin-layer limits (Sneddon, uniaxial strain, squeeze flow), the first-order
// correction published by Dimitriadis et al. 2002, a variational (Ritz) lower bound computed
// another way, transcriptions of Hayes' table, the sphere's stiffness against the flat punch's,
// and the quadrature's convergence.
#include "lab/layer_indentation.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "core/body.h"
#include "io/scene.h"
#include "lab/calibration.h"
#include "lab/quasi_static.h"

namespace conica::lab {
namespace {

constexpr double kPi = 3.14159265358979323846;

// K(t) from the Navier equations in Hankel space (no Love function): u_r = Int xi U J1,
// u_z = Int xi W J0, xi = mu = 1, z down from the surface; mu (U'' - U) = (l + mu) (U + W'),
// mu (W'' - W) + (l + mu) (U' + W'') = 0 (l: Lame's lambda). Surface: s_rz ~ U' - W = 0,
// s_zz = l (U + W') + 2 mu W' = -1; base z = t: U = W = 0. Shooting with RK4 on y =
// (U, U', W, W'); K = W(0) / C with C = 2 (1 - nu^2) / E = 1 - nu.
double navier_compliance(double t, double nu) {
  const double l = 2 * nu / (1 - 2 * nu), m = 1;
  using Y = std::array<double, 4>;
  auto rhs = [&](const Y& y) {
    return Y{y[1], ((l + 2 * m) * y[0] + (l + m) * y[3]) / m, y[3],
             (m * y[2] - (l + m) * y[1]) / (l + 2 * m)};
  };
  auto shoot = [&](double u0, double w0, double p) {
    Y y{u0, w0, w0, (-p - l * u0) / (l + 2 * m)};
    const int steps = 4000;
    const double dz = t / steps;
    for (int i = 0; i < steps; ++i) {
      Y k1 = rhs(y), y2, y3, y4;
      for (int j = 0; j < 4; ++j) y2[j] = y[j] + 0.5 * dz * k1[j];
      const Y k2 = rhs(y2);
      for (int j = 0; j < 4; ++j) y3[j] = y[j] + 0.5 * dz * k2[j];
      const Y k3 = rhs(y3);
      for (int j = 0; j < 4; ++j) y4[j] = y[j] + dz * k3[j];
      const Y k4 = rhs(y4);
      for (int j = 0; j < 4; ++j) y[j] += dz / 6 * (k1[j] + 2 * k2[j] + 2 * k3[j] + k4[j]);
    }
    return y;
  };
  const Y p = shoot(0, 0, 1), u = shoot(1, 0, 0), w = shoot(0, 1, 0);
  // U(t) = p0 + u0 U0 + w0 W0 = 0, W(t) = p2 + u2 U0 + w2 W0 = 0.
  const double det = u[0] * w[2] - w[0] * u[2];
  const double w0 = (-u[0] * p[2] + u[2] * p[0]) / det;
  return w0 / (1 - nu);
}

TEST(LayerIndentation, ComplianceMatchesNavierEquations) {
  for (double nu : {-0.3, 0.0, 0.3, 0.45, 0.49}) {
    for (double t : {0.05, 0.5, 1.3, 3.0}) {
      const double k = bonded_layer_compliance(t, nu);
      EXPECT_NEAR(k, navier_compliance(t, nu), 1e-9 * k) << "nu " << nu << " t " << t;
    }
  }
}

TEST(LayerIndentation, ComplianceLimits) {
  for (double nu : {-0.5, 0.0, 0.3, 0.45, 0.5}) {
    // Half-space (Boussinesq) for wavelengths much shorter than h.
    EXPECT_NEAR(bonded_layer_compliance(30, nu), 1, 1e-15);
    EXPECT_EQ(bonded_layer_compliance(0, nu), 0);
  }
  // Long wavelengths, compressible: uniaxial strain, w = p h / M, M = E (1 - nu) / ((1 + nu)
  // (1 - 2 nu)), i.e. K = t (1 - 2 nu) / (2 (1 - nu)^2) to O(t^3).
  for (double nu : {-0.5, 0.0, 0.3, 0.45}) {
    const double t = 1e-3;
    EXPECT_NEAR(bonded_layer_compliance(t, nu) / (t * (1 - 2 * nu) / (2 * (1 - nu) * (1 - nu))), 1,
                1e-4);
  }
  // Incompressible: squeeze flow of a film, shear-free on top, no slip at the base: flux
  // q = -(h^3 / (3 mu)) grad p, w = div q = -(h^3 / (3 mu)) lap p, i.e. K = 2 t^3 / 3.
  const double t = 0.01;
  EXPECT_NEAR(bonded_layer_compliance(t, 0.5) / (2 * t * t * t / 3), 1, 1e-3);
}

// The load's first-order correction is linear in a/h: the base's reaction to the punch's far
// field (a point force P) lowers the surface at the centre by (1 - nu^2) P G0 / (pi E h),
// G0 = Int_0^inf (1 - K), so kappa = 1 + (2 G0 / pi) a/h + O(a/h)^2. (kappa(0.01) - 1 is about
// 0.01, not 1e-3: kappa -> 1 only linearly.)
double first_order_coefficient(double nu) {
  const int n = 40000;  // Simpson on [0, 40]; 1 - K ~ 4 t^2 e^(-2t) / (3 - 4 nu)
  const double dt = 40.0 / n;
  double sum = 0;
  for (int i = 0; i <= n; ++i) {
    const double wgt = (i == 0 || i == n) ? 1 : (i % 2 ? 4 : 2);
    sum += wgt * (1 - bonded_layer_compliance(i * dt, nu));
  }
  return 2 / kPi * sum * dt / 3;
}

TEST(LayerIndentation, HalfSpaceLimitIsSneddon) {
  for (double nu : {0.0, 0.3, 0.45, 0.5}) {
    const double c1 = first_order_coefficient(nu);
    for (double l : {1e-3, 1e-2}) {
      EXPECT_NEAR(bonded_layer_kappa(l, nu), 1 + c1 * l, 2 * l * l) << "nu " << nu;
    }
  }
  // Dimitriadis, Horkay, Maresca, Kachar & Chadwick 2002 (Biophys. J. 82:2798), bonded sample:
  // F = F_Hertz (1 - 2 alpha0 chi / pi + ...), chi = sqrt(R d) / h, with the fit
  // alpha0 = -(1.2876 - 1.4678 nu + 1.3442 nu^2) / (1 - nu); the coefficients as transcribed in
  // pawelHerm/AtomicJ HertzianThinSampleParaboloidChadwick.java (we have no copy of the paper;
  // the bibliographic details are from memory). The sphere's first-order
  // coefficient equals the flat punch's (see SphereHalfSpaceIsHertz), so -2 alpha0 / pi = c1.
  // Their fit is within 0.6 % of G0 for 0.3 <= nu <= 0.5 (it is 6 % off at nu = 0).
  for (double nu : {0.3, 0.4, 0.45, 0.5}) {
    const double alpha0 = -(1.2876 - 1.4678 * nu + 1.3442 * nu * nu) / (1 - nu);
    const double slope = (bonded_layer_kappa(1e-3, nu) - 1) / 1e-3;
    EXPECT_NEAR(slope / (-2 * alpha0 / kPi), 1, 0.01) << "nu " << nu;
  }
}

// Thin compressible layer: the layer under the punch is in uniaxial strain, P -> pi a^2 w M / h,
// kappa -> pi (a/h) (1 - nu)^2 / (2 (1 - 2 nu)). The next order is an edge term, relative
// c h / a: c = +0.245 at nu = 0.3 (the ring of layer around the punch, dragged down, carries
// load), c = -1.09 at nu = 0.45 (a nearly incompressible layer bulges at the edge: the pressure
// falls over a length ~ h sqrt(M / (3 mu)) inside it). So 2 r(2 l) - r(l) -> 1 at O(1/l^2).
double uniaxial_ratio(double l, double nu) {
  return bonded_layer_kappa(l, nu) / (kPi * l * (1 - nu) * (1 - nu) / (2 * (1 - 2 * nu)));
}

TEST(LayerIndentation, ThinCompressibleLayerIsInUniaxialStrain) {
  const double r20 = uniaxial_ratio(20, 0.3), r50 = uniaxial_ratio(50, 0.3);
  const double r100 = uniaxial_ratio(100, 0.3);
  EXPECT_GT(r20, 1);
  EXPECT_LT(r20, 1.02);
  EXPECT_LT(r100, r50);
  EXPECT_NEAR(2 * r100 - r50, 1, 1e-4);
  const double s50 = uniaxial_ratio(50, 0.45), s100 = uniaxial_ratio(100, 0.45);
  EXPECT_LT(s50, s100);
  EXPECT_LT(s100, 1);
  EXPECT_NEAR(2 * s100 - s50, 1, 1e-3);
}

// Thin incompressible layer (nu = 1/2): squeeze flow. Under the shear-free punch over the
// no-slip base the flux is -(h^3 / (3 mu)) grad p, so (h^3 / (3 mu)) lap p = -w with p(a) = 0:
// p = (3 mu w / (4 h^3)) (a^2 - r^2), P = (3 pi / 8) mu w a^4 / h^3 = (pi / 8) E w a^4 / h^3,
// kappa -> 3 pi (a/h)^3 / 64. (A punch bonded to the layer, no slip on both faces, has flux
// h^3 / (12 mu), p = (3 mu w / h^3) (a^2 - r^2) and 4 times the load.) The approach is slow:
// r = 1 + 5.8 h/a + 13 (h/a)^2 (the pressure falls to zero across an edge zone of width ~ h,
// not at r = a: in effect a wider punch), so two Richardson steps.
TEST(LayerIndentation, ThinIncompressibleLayerIsSqueezeFlow) {
  std::vector<double> r;
  for (double l : {25.0, 50.0, 100.0}) {
    r.push_back(bonded_layer_kappa(l, 0.5) / (3 * kPi * l * l * l / 64));
  }
  EXPECT_GT(r[0], r[1]);
  EXPECT_GT(r[1], r[2]);
  EXPECT_GT(r[2], 1);
  EXPECT_NEAR((8 * r[2] - 6 * r[1] + r[0]) / 3, 1, 1e-3);
}

// Monotonic in nu for nu >= 0 only: for auxetic layers kappa falls with nu (thin-layer limit
// pi (a/h) (1 - nu)^2 / (2 (1 - 2 nu)) is smallest at nu = 0; kappa(1, -0.5) = 2.249 >
// kappa(1, 0) = 2.226).
TEST(LayerIndentation, KappaIncreasesWithAspectRatioAndPoisson) {
  const std::vector<double> nus = {0.0, 0.1, 0.3, 0.4, 0.45, 0.49, 0.5};
  const std::vector<double> ls = {0.05, 0.1, 0.2, 0.5, 1, 1.5, 2, 4, 8};
  std::vector<double> previous(ls.size(), 0);
  for (double nu : nus) {
    double last = 1;
    for (size_t i = 0; i < ls.size(); ++i) {
      const double k = bonded_layer_kappa(ls[i], nu);
      EXPECT_GT(k, last) << "a/h " << ls[i] << " nu " << nu;
      EXPECT_GT(k, previous[i]) << "a/h " << ls[i] << " nu " << nu;
      last = previous[i] = k;
    }
  }
}

// n-point Gauss-Legendre on [lo, hi] (Newton on the recurrence).
void gauss_legendre(int n, double lo, double hi, std::vector<double>* x, std::vector<double>* w) {
  for (int i = 0; i < n; ++i) {
    double z = std::cos(kPi * (i + 0.75) / (n + 0.5)), dp = 1;
    for (int it = 0; it < 100; ++it) {
      double p0 = 1, p1 = z;
      for (int k = 2; k <= n; ++k) {
        const double p2 = ((2 * k - 1) * z * p1 - (k - 1) * p0) / k;
        p0 = p1;
        p1 = p2;
      }
      dp = n * (z * p1 - p0) / (z * z - 1);
      z -= p1 / dp;
      if (std::abs(p1 / dp) < 1e-16) break;
    }
    x->push_back(lo + (hi - lo) * 0.5 * (1 + z));
    w->push_back((hi - lo) / ((1 - z * z) * dp * dp));
  }
}

// Complementary energy: of all pressures under the punch with resultant P the true one has the
// least energy Int p w dA = P^2 / S, so every trial pressure bounds the stiffness from below.
// Trial pressures in Copson's form, phi(t) = sum_m c_m P_2m(t / a) (Legendre), p^ = Int phi cos:
// energy 2 pi C a c^T G c, load 2 pi a c_0, G_mn = Int_0^inf F_m F_n K(u / l) du with
// F_m(u) = Int_0^1 P_2m(y) cos(u y) dy; the best c gives kappa >= (pi / 2) (G^-1)_00. The
// half-space part by Parseval: Int F_m F_n du = (pi / 2) delta_mn / (4 m + 1). A Galerkin method
// in Hankel space: shares only K (checked above) with the Nystrom solution.
double ritz_lower_bound(double l, double nu, int terms) {
  std::vector<double> y, wy, u, wu;
  gauss_legendre(64, 0, 1, &y, &wy);
  const int panels = static_cast<int>(std::ceil(36 * l / 0.5));  // 1 - K(u / l) < 1e-25 past
  for (int p = 0; p < panels; ++p) gauss_legendre(20, p * 0.5, (p + 1) * 0.5, &u, &wu);
  Eigen::MatrixXd legendre(terms, y.size());
  for (size_t j = 0; j < y.size(); ++j) {
    double p0 = 1, p1 = y[j];
    legendre(0, j) = 1;
    for (int k = 2; k <= 2 * terms - 2; ++k) {
      const double p2 = ((2 * k - 1) * y[j] * p1 - (k - 1) * p0) / k;
      p0 = p1;
      p1 = p2;
      if (k % 2 == 0) legendre(k / 2, j) = p2;
    }
  }
  Eigen::MatrixXd g = Eigen::MatrixXd::Zero(terms, terms);
  for (int m = 0; m < terms; ++m) g(m, m) = kPi / 2 / (4 * m + 1);
  Eigen::VectorXd cosines(y.size());
  for (size_t i = 0; i < u.size(); ++i) {
    for (size_t j = 0; j < y.size(); ++j) cosines(j) = wy[j] * std::cos(u[i] * y[j]);
    const Eigen::VectorXd f = legendre * cosines;
    g -= wu[i] * (1 - bonded_layer_compliance(u[i] / l, nu)) * f * f.transpose();
  }
  return kPi / 2 * g.ldlt().solve(Eigen::VectorXd::Unit(terms, 0))(0);
}

TEST(LayerIndentation, RitzLowerBound) {
  for (double nu : {0.3, 0.5}) {
    for (double l : {1.0, 2.0, 4.0}) {
      const double k = bonded_layer_kappa(l, nu), bound = ritz_lower_bound(l, nu, 8);
      EXPECT_LE(bound, k * (1 + 1e-10)) << "a/h " << l << " nu " << nu;
      EXPECT_NEAR(bound, k, 1e-7 * k) << "a/h " << l << " nu " << nu;
    }
  }
}

// Hayes et al. 1972 (J. Biomech. 5:541), table of kappa for the flat punch, as transcribed in
// public analysis code (we have no copy of the paper):
//  - nu = 0.5: ImanKafian/CartilageStaticElasticModuliEstimation,
//    cartilage_static_elastic_mod_estimator.py ("poisson_inst_vals"); the same numbers are in an
//    R helper Hayes_correction documented as Hayes 1972, nu = 0.5.
//  - nu = 0.3: MohammadHosseinEbrahimi/Equilibrium-and-instantaneous-moduli,
//    equilibrium_instantaneous.m ("Hayes et al, 1972").
// Both agree with ours to the quoted 4 digits at a/h = 0.2; past it the table falls below our
// values by an amount growing with a/h (nu = 0.5: 0.04 % at 0.4, 0.27 % at 1, 0.9 % at 2;
// nu = 0.3: 0.14 % at 1, 0.4 % at 2). The table is too low there: the Ritz lower bound with two
// trial pressures already exceeds it at a/h = 2, with four at a/h = 1 (if the transcriptions
// are faithful, Hayes' 1972 numerics lost accuracy as a/h grew).
TEST(LayerIndentation, HayesTable) {
  const std::vector<double> nu05 = {1.281, 1.683, 2.211, 2.855, 3.609,
                                    4.469, 5.441, 6.528, 7.735, 9.069};
  const std::vector<double> nu03 = {1.207, 1.472, 1.784, 2.124, 2.480,
                                    2.845, 3.214, 3.586, 3.960, 4.336};
  for (const auto& [nu, table] : {std::pair{0.5, nu05}, std::pair{0.3, nu03}}) {
    for (size_t i = 0; i < table.size(); ++i) {
      const double l = 0.2 * static_cast<double>(i + 1), k = bonded_layer_kappa(l, nu);
      if (i == 0) {
        EXPECT_NEAR(k, table[i], 5e-4) << "nu " << nu;
      } else {
        EXPECT_GE(k / table[i] - 1, 0) << "a/h " << l << " nu " << nu;
        EXPECT_LE(k / table[i] - 1, 0.01) << "a/h " << l << " nu " << nu;
      }
    }
  }
  EXPECT_GT(ritz_lower_bound(2, 0.5, 2), nu05[9]);
  EXPECT_GT(ritz_lower_bound(2, 0.3, 2), nu03[9]);
  EXPECT_GT(ritz_lower_bound(1, 0.5, 4), nu05[4]);
  EXPECT_GT(ritz_lower_bound(1, 0.3, 4), nu03[4]);
}

TEST(LayerIndentation, QuadratureConverged) {
  for (double nu : {0.3, 0.5}) {
    for (double l : {0.01, 0.5, 2.0, 8.0, 50.0}) {
      EXPECT_NEAR(bonded_layer_kappa(l, nu, 2), bonded_layer_kappa(l, nu), 1e-6)
          << "a/h " << l << " nu " << nu;
    }
  }
  const SphereFactors s1 = bonded_layer_sphere(3, 0.5), s2 = bonded_layer_sphere(3, 0.5, 2);
  EXPECT_NEAR(s1.depth_factor, s2.depth_factor, 1e-9);
  EXPECT_NEAR(s1.force_factor, s2.force_factor, 1e-9);
}

TEST(LayerIndentation, IncompressibleIsTheLimitOfCompressible) {
  for (double l : {0.2, 1.0, 4.0}) {
    const double k = bonded_layer_kappa(l, 0.5);
    EXPECT_NEAR(bonded_layer_kappa(l, 0.5 - 1e-7, 1), k, 1e-5 * k) << "a/h " << l;
  }
}

TEST(LayerIndentation, PunchForceInSiUnits) {
  // a = 2 mm, h = 4 mm, E = 50 kPa, nu = 0.45, w = 0.1 mm.
  const double k = bonded_layer_kappa(0.5, 0.45);
  const double p = bonded_layer_punch_force(2e-3, 4e-3, 5e4, 0.45, 1e-4);
  EXPECT_NEAR(p, 2 * 2e-3 * 5e4 * 1e-4 * k / (1 - 0.45 * 0.45), 1e-12);
  EXPECT_NEAR(bonded_layer_punch_force(2e-3, 4e-3, 5e4, 0.45, 2e-4), 2 * p, 1e-12);
  EXPECT_EQ(bonded_layer_punch_force(2e-3, 4e-3, 5e4, 0.45, 0), 0);
  // A layer 1e4 punch radii thick is a half-space: Sneddon's 2 a E w / (1 - nu^2).
  const double sneddon = 2 * 2e-3 * 5e4 * 1e-4 / (1 - 0.45 * 0.45);
  EXPECT_NEAR(bonded_layer_punch_force(2e-3, 20, 5e4, 0.45, 1e-4), sneddon, 2e-4 * sneddon);
}

// Throws std::invalid_argument whose message names `arg`.
template <typename F>
void expect_refused(F f, const std::string& arg) {
  try {
    f();
    ADD_FAILURE() << "accepted bad " << arg;
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(arg), std::string::npos) << e.what();
  }
}

TEST(LayerIndentation, RefusesBadInput) {
  const double inf = INFINITY, nan = NAN;
  for (double l : {0.0, -1.0, inf, nan, 2 * kMaxAOverH}) {
    expect_refused([&] { bonded_layer_kappa(l, 0.3); }, "a_over_h");
    expect_refused([&] { bonded_layer_sphere(l, 0.3); }, "a_over_h");
  }
  for (double nu : {-1.0, -2.0, 0.5000001, 1.0, nan, inf}) {
    expect_refused([&] { bonded_layer_kappa(1, nu); }, "nu");
    expect_refused([&] { bonded_layer_sphere(1, nu); }, "nu");
    expect_refused([&] { bonded_layer_compliance(1, nu); }, "nu");
    expect_refused([&] { bonded_layer_punch_force(1, 1, 1, nu, 1); }, "nu");
  }
  expect_refused([&] { bonded_layer_kappa(1, 0.3, 0); }, "refine");
  expect_refused([&] { bonded_layer_compliance(-1, 0.3); }, "t");
  for (double bad : {0.0, -1.0, nan, inf}) {
    expect_refused([&] { bonded_layer_punch_force(bad, 1, 1, 0.3, 1); }, "a");
    expect_refused([&] { bonded_layer_punch_force(1, bad, 1, 0.3, 1); }, "h");
    expect_refused([&] { bonded_layer_punch_force(1, 1, bad, 0.3, 1); }, "E");
  }
  expect_refused([&] { bonded_layer_punch_force(1, 1, 1, 0.3, -1e-6); }, "w");
  expect_refused([&] { bonded_layer_punch_force(1, 1, 1, 0.3, nan); }, "w");
}

// Rigid sphere. On a half-space: Hertz (both factors 1). To first order in a/h the base adds a
// uniform displacement, which leaves the force at given contact radius unchanged and lowers the
// depth by (2/3) c1 a/h (c1: the flat punch's first-order coefficient).
TEST(LayerIndentation, SphereHalfSpaceIsHertz) {
  for (double nu : {0.3, 0.5}) {
    const double l = 1e-3;
    const SphereFactors s = bonded_layer_sphere(l, nu);
    EXPECT_NEAR(s.force_factor, 1, 1e-5);
    EXPECT_NEAR(s.depth_factor, 1 - 2.0 / 3 * first_order_coefficient(nu) * l, 2 * l * l);
  }
}

// For frictionless contact on a linear elastic body the stiffness dP/dw at contact radius a is
// the flat punch's of radius a (the load added while the contact grows from a to a + da is a
// flat-punch increment; Pharr, Oliver & Brotzen 1992 for the half-space): here
// d(4/3 F l^3) / d(D l^2) = 2 l kappa(l), F, D the force and depth factors.
TEST(LayerIndentation, SphereStiffnessIsFlatPunchStiffness) {
  for (double nu : {0.3, 0.5}) {
    for (double l : {0.3, 1.0, 3.0, 10.0}) {
      const double e = 1e-4 * l;
      const SphereFactors lo = bonded_layer_sphere(l - e, nu), hi = bonded_layer_sphere(l + e, nu);
      const double dp =
          4.0 / 3 * (hi.force_factor * std::pow(l + e, 3) - lo.force_factor * std::pow(l - e, 3));
      const double dw = hi.depth_factor * (l + e) * (l + e) - lo.depth_factor * (l - e) * (l - e);
      EXPECT_NEAR(dp / dw / (2 * l * bonded_layer_kappa(l, nu)), 1, 1e-6)
          << "a/h " << l << " nu " << nu;
    }
  }
}

// Thin layers under a sphere. Compressible: a Winkler foundation of stiffness M / h, contact
// where w > r^2 / (2 R): w = a^2 / (2 R), P = pi M a^4 / (4 R h), i.e. depth factor 1/2 and force
// factor 3 pi (a/h) (1 - nu)^2 / (16 (1 - 2 nu)). Incompressible: squeeze flow as for the punch
// with (h^3 / (3 mu)) lap p = -(w - r^2 / (2 R)), p(a) = p'(a) = 0 (the contact edge):
// w = a^2 / (4 R), p = (3 mu / (32 h^3 R)) (a^2 - r^2)^2, depth factor 1/4, force factor
// 3 pi (a/h)^3 / 512. Corrections O(h/a) as for the punch.
TEST(LayerIndentation, SphereThinLayerLimits) {
  auto winkler = [](double l) {
    const SphereFactors s = bonded_layer_sphere(l, 0.3);
    return std::array<double, 2>{s.depth_factor / 0.5,
                                 s.force_factor / (3 * kPi * l * 0.49 / (16 * 0.4))};
  };
  const auto w50 = winkler(50), w100 = winkler(100);
  for (int i = 0; i < 2; ++i) EXPECT_NEAR(2 * w100[i] - w50[i], 1, 1e-3) << i;
  auto squeeze = [](double l) {
    const SphereFactors s = bonded_layer_sphere(l, 0.5);
    return std::array<double, 2>{s.depth_factor / 0.25,
                                 s.force_factor / (3 * kPi * l * l * l / 512)};
  };
  const auto s25 = squeeze(25), s50 = squeeze(50), s100 = squeeze(100);
  for (int i = 0; i < 2; ++i) EXPECT_NEAR((8 * s100[i] - 6 * s50[i] + s25[i]) / 3, 1, 2e-3) << i;
}

// The lattice against the reference: the EF30 block's card (configs/validation) on layers of its
// 60 x 60 mm footprint, 30 and 5 mm thick in 2.5 mm cells (12 and 2 cells), bonded to a rigid
// base, a flat punch of radius 5 mm (the top nodes within it) pressed 0.05 mm. The thickness
// correction, the 5 mm layer's force over the 30 mm layer's, follows Hayes' kappa ratio (2.57 at
// the body's Poisson ratio 0.45; 2.62 measured, +2.2 %, and +0.06 % in 1.875 mm cells:
// `conica-lab validate --case layer`), where a half-space model would give 1.
TEST(LayerIndentation, LatticeLayerFollowsTheThicknessCorrection) {
  BodySpec block;
  ASSERT_EQ(io::load_scene(CONICA_SOURCE_DIR "/configs/validation/punch-block-ef30.pbtxt", &block),
            "");
  const double nu =
      body_poisson(lattice_moduli(block.groups), block.bulk_modulus, block.shear_modulus);
  const double a = 0.005, d = 5e-5;
  double force[2] = {0, 0};
  const double h[2] = {0.03, 0.005};
  for (int i = 0; i < 2; ++i) {
    BodySpec s = block;
    s.mesh =
        make_box_lattice(Vec3(0.06, 0.06, h[i]), {24, 24, static_cast<int>(h[i] / 0.0025 + 0.5)});
    PunchPress press;
    ASSERT_EQ(press_flat_punch(s, a, d, PunchRule::kNodes, &press), "");
    force[i] = press.force;
  }
  const double measured = force[1] / force[0];
  const double hayes = bonded_layer_kappa(a / h[1], nu) / bonded_layer_kappa(a / h[0], nu);
  std::printf("Poisson %.4f: thickness correction %.4f, Hayes %.4f (%+.2f %%)\n", nu, measured,
              hayes, 100 * (measured / hayes - 1));
  EXPECT_GT(hayes, 2.3);
  EXPECT_NEAR(measured / hayes, 1, 0.04);
}

}  // namespace
}  // namespace conica::lab
