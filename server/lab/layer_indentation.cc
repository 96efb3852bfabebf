#include "lab/layer_indentation.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

namespace conica::lab {
namespace {

constexpr double kPi = 3.14159265358979323846;

// The layer's surface Green's function. Cylindrical (r, z), z down from the loaded surface
// (z = 0) to the base (z = h). Love's strain function Phi (biharmonic) gives
//   2 mu u_r = -d2Phi/dr dz,  2 mu u_z = 2 (1 - nu) lap Phi - d2Phi/dz2,
//   s_zz = d/dz [(2 - nu) lap Phi - d2Phi/dz2],  s_rz = d/dr [(1 - nu) lap Phi - d2Phi/dz2].
// With Phi = Int xi F(xi, z) J0(xi r) dxi, F = (A + B xi z) e^(-xi z) + (C + D xi z) e^(xi z);
// the four constants from s_zz = -p, s_rz = 0 at z = 0 (normal pressure p, frictionless) and
// u_r = u_z = 0 at z = h (bonded). The surface deflection (into the layer) is then
//   w(r) = 2 (1 - nu^2) / E  Int_0^inf p^(xi) K(xi h) J0(xi r) dxi,  p^(xi) = Int_0^inf p r J0 dr,
//   K(t) = (k0 sinh 2t - 2t) / (k0 cosh 2t + 2 t^2 + (1 + k0^2) / 2),  k0 = 3 - 4 nu.
// Checks: K -> 1 as t -> inf (Boussinesq's half-space, also found from the decaying terms alone);
// K ~ t (1 - 2 nu) / (2 (1 - nu)^2) as t -> 0, i.e. w = p h / M with M the constrained modulus
// (uniaxial strain); at nu = 1/2, K ~ 2 t^3 / 3, i.e. w = -(h^3 / (3 mu)) lap p: lubrication
// flux of a film with a shear-free top over a no-slip base.
//
// The punch (Copson, Sneddon): p^(xi) = Int_0^a phi(t) cos(xi t) dt makes p vanish for r > a and
// P = 2 pi Int_0^a phi. With Int_0^inf cos(xi t) J0(xi r) dxi = H(r - t) / sqrt(r^2 - t^2) and
// J0(xi r) = (2 / pi) Int_0^r cos(xi s) / sqrt(r^2 - s^2) ds, w(r) for r < a is an Abel integral
// of phi(s) - (2 / pi) Int_0^inf (1 - K) p^ cos(xi s) dxi; inverting it, with t = a y, s = a x,
// lambda = a / h and phi(a x) = E psi(x) / (pi (1 - nu^2)) (psi in m):
//   psi(x) - (1 / pi) Int_0^1 psi(y) [L(x - y) + L(x + y)] dy = f(x),
//   L(u) = lambda Int_0^inf (1 - K(s)) cos(lambda u s) ds,
// f = w (flat punch), f = w - a^2 x^2 / R (sphere: profile w - r^2 / (2 R), a << R), and
// P = 2 a E / (1 - nu^2) Int_0^1 psi. Half-space: L = 0, psi = f (Sneddon, Hertz).
// 1 - K(t) written with decaying exponentials: no cancellation, finite for every nu in
// (-1, 1/2] (k0 in [1, 7)), 1 at t = 0, ~ (4 t^2 / k0) e^(-2t) for large t.
double one_minus_k(double t, double k0) {
  const double e2 = std::exp(-2 * t), e4 = e2 * e2, c = 1 + k0 * k0;
  return (2 * k0 * e4 + (4 * t * t + 4 * t + c) * e2) / (k0 * (1 + e4) + (4 * t * t + c) * e2);
}

// Numerics. Both quadratures are composite Gauss-Legendre of kOrder points a panel. The kernel's
// spectral integral: s in [0, kSMax] (1 - K < 1e-20 past it), panels at most 1 wide and at most
// two periods of the fastest product cos(lambda s x) cos(lambda s y) (2 pi / lambda). Nystrom on
// [0, 1]: L varies on the scale 1 / lambda (it is analytic in |Im u| < 2 / lambda), so panels of
// width <= 2 / lambda. Both rules converge exponentially; `refine` multiplies the panels.
constexpr int kOrder = 16;
constexpr double kSMax = 28;

struct Rule {
  std::vector<double> x, w;
};

// n-point Gauss-Legendre on [-1, 1]: Newton on the Legendre recurrence.
Rule gauss_legendre(int n) {
  Rule r{std::vector<double>(n), std::vector<double>(n)};
  for (int i = 0; i < n; ++i) {
    double x = std::cos(kPi * (i + 0.75) / (n + 0.5)), dp = 1;
    for (int it = 0; it < 100; ++it) {
      double p0 = 1, p1 = x;
      for (int k = 2; k <= n; ++k) {
        const double p2 = ((2 * k - 1) * x * p1 - (k - 1) * p0) / k;
        p0 = p1;
        p1 = p2;
      }
      dp = n * (x * p1 - p0) / (x * x - 1);
      const double dx = p1 / dp;
      x -= dx;
      if (std::abs(dx) < 1e-16) break;
    }
    r.x[i] = x;
    r.w[i] = 2 / ((1 - x * x) * dp * dp);
  }
  return r;
}

// The kOrder-point rule repeated on `panels` equal panels of [lo, hi].
Rule composite(double lo, double hi, int panels) {
  static const Rule base = gauss_legendre(kOrder);
  Rule r;
  const double width = (hi - lo) / panels;
  for (int p = 0; p < panels; ++p) {
    for (int i = 0; i < kOrder; ++i) {
      r.x.push_back(lo + width * (p + 0.5 * (base.x[i] + 1)));
      r.w.push_back(0.5 * width * base.w[i]);
    }
  }
  return r;
}

// The discretised equation (I - T) psi = f on the x-rule (x_i, w_i): T_ij = (2 lambda / pi)
// (B B^T)_ij w_j, B_ik = sqrt(v_k (1 - K(s_k))) cos(lambda s_k x_i), i.e. the kernel
// L(x - y) + L(x + y) = 2 lambda Int (1 - K(s)) cos(lambda s x) cos(lambda s y) ds as a sum over
// the s-rule (s_k, v_k). B is formed kBlock columns at a time: memory n x kBlock, not n x q.
constexpr int kBlock = 256;

struct LayerOperator {
  double lambda = 0;
  Rule x, s;
  Eigen::VectorXd root_vg;  // sqrt(v_k (1 - K(s_k)))
  Eigen::PartialPivLU<Eigen::MatrixXd> lu;
};

// Columns [k0, k0 + cols) of B at the points x.
Eigen::MatrixXd b_block(const LayerOperator& op, const std::vector<double>& x, int k0, int cols) {
  Eigen::MatrixXd b(static_cast<int>(x.size()), cols);
  for (int k = 0; k < cols; ++k) {
    for (int i = 0; i < b.rows(); ++i) {
      b(i, k) = op.root_vg(k0 + k) * std::cos(op.lambda * op.s.x[k0 + k] * x[i]);
    }
  }
  return b;
}

void check(bool ok, const char* what, const char* arg, double value) {
  if (!ok) {
    throw std::invalid_argument(std::string(what) + ": " + arg + " out of range (" +
                                std::to_string(value) + ")");
  }
}

void check_nu(const char* what, double nu) {
  check(std::isfinite(nu) && nu > -1 && nu <= 0.5, what, "nu", nu);
}

void check_layer(const char* what, double a_over_h, double nu, int refine) {
  check(std::isfinite(a_over_h) && a_over_h > 0 && a_over_h <= kMaxAOverH, what, "a_over_h",
        a_over_h);
  check_nu(what, nu);
  check(refine >= 1 && refine <= 4, what, "refine", refine);
}

LayerOperator build(double lambda, double nu, int refine) {
  LayerOperator op;
  op.lambda = lambda;
  const double s_width = std::min(1.0, 2 * kPi / lambda);
  op.s = composite(0, kSMax, refine * static_cast<int>(std::ceil(kSMax / s_width)));
  op.x = composite(0, 1, refine * static_cast<int>(std::ceil(lambda / 2)));
  const int n = static_cast<int>(op.x.x.size()), q = static_cast<int>(op.s.x.size());
  op.root_vg.resize(q);
  for (int k = 0; k < q; ++k) {
    op.root_vg(k) = std::sqrt(op.s.w[k] * one_minus_k(op.s.x[k], 3 - 4 * nu));
  }
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(n, n);
  for (int k0 = 0; k0 < q; k0 += kBlock) {
    const Eigen::MatrixXd b = b_block(op, op.x.x, k0, std::min(kBlock, q - k0));
    a.selfadjointView<Eigen::Lower>().rankUpdate(b, -2 * lambda / kPi);
  }
  a = a.selfadjointView<Eigen::Lower>();
  const Eigen::Map<const Eigen::RowVectorXd> w(op.x.w.data(), n);
  a.array().rowwise() *= w.array();
  a.diagonal().array() += 1;
  op.lu.compute(a);
  return op;
}

// psi at the nodes for right-hand side f(x) = c0 + c2 x^2.
Eigen::VectorXd solve(const LayerOperator& op, double c0, double c2) {
  Eigen::VectorXd f(op.x.x.size());
  for (int i = 0; i < f.size(); ++i) f(i) = c0 + c2 * op.x.x[i] * op.x.x[i];
  return op.lu.solve(f);
}

double integral(const LayerOperator& op, const Eigen::VectorXd& psi) {
  return Eigen::Map<const Eigen::VectorXd>(op.x.w.data(), psi.size()).dot(psi);
}

// psi(1) by Nystrom interpolation: f(1) + (2 lambda / pi) B(1) B^T W psi.
double psi_at_edge(const LayerOperator& op, const Eigen::VectorXd& psi, double f1) {
  const Eigen::VectorXd wpsi =
      Eigen::Map<const Eigen::VectorXd>(op.x.w.data(), psi.size()).cwiseProduct(psi);
  const int q = static_cast<int>(op.s.x.size());
  double sum = 0;
  for (int k0 = 0; k0 < q; k0 += kBlock) {
    const int cols = std::min(kBlock, q - k0);
    const Eigen::VectorXd bt_wpsi = b_block(op, op.x.x, k0, cols).transpose() * wpsi;
    sum += b_block(op, {1.0}, k0, cols).row(0).dot(bt_wpsi.transpose());
  }
  return f1 + 2 * op.lambda / kPi * sum;
}

}  // namespace

double bonded_layer_compliance(double t, double nu) {
  check(std::isfinite(t) && t >= 0, "bonded_layer_compliance", "t", t);
  check_nu("bonded_layer_compliance", nu);
  return 1 - one_minus_k(t, 3 - 4 * nu);
}

double bonded_layer_kappa(double a_over_h, double nu, int refine) {
  check_layer("bonded_layer_kappa", a_over_h, nu, refine);
  const LayerOperator op = build(a_over_h, nu, refine);
  return integral(op, solve(op, 1, 0));
}

double bonded_layer_punch_force(double a, double h, double E, double nu, double w) {
  const char* what = "bonded_layer_punch_force";
  check(std::isfinite(a) && a > 0, what, "a", a);
  check(std::isfinite(h) && h > 0, what, "h", h);
  check(std::isfinite(E) && E > 0, what, "E", E);
  check(std::isfinite(w) && w >= 0, what, "w", w);
  check_nu(what, nu);
  return 2 * a * E * w * bonded_layer_kappa(a / h, nu) / (1 - nu * nu);
}

SphereFactors bonded_layer_sphere(double a_over_h, double nu, int refine) {
  check_layer("bonded_layer_sphere", a_over_h, nu, refine);
  const LayerOperator op = build(a_over_h, nu, refine);
  // psi = d psi_1 - psi_2 in units of a^2 / R (psi_1: f = 1, psi_2: f = x^2); the pressure is
  // bounded at the contact edge when psi(1) = 0, which fixes the depth d.
  const Eigen::VectorXd psi1 = solve(op, 1, 0), psi2 = solve(op, 0, 1);
  SphereFactors out;
  out.depth_factor = psi_at_edge(op, psi2, 1) / psi_at_edge(op, psi1, 1);
  // P = 2 a E / (1 - nu^2) (a^2 / R) Int psi; Hertz is 2/3 of that prefactor.
  out.force_factor = 1.5 * (out.depth_factor * integral(op, psi1) - integral(op, psi2));
  return out;
}

}  // namespace conica::lab
