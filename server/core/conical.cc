#include "core/conical.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace conica {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

std::string fmt(double v) {
  std::ostringstream os;
  os.precision(9);
  os << v;
  return os.str();
}

}  // namespace

std::string validate(const ConicalCard& c) {
  const std::pair<const char*, double> fields[] = {
      {"G", c.G}, {"d", c.d}, {"D1", c.D1}, {"D2", c.D2}, {"L0", c.L0}, {"n_a", c.n_a}};
  for (const auto& [name, v] : fields) {
    if (!std::isfinite(v)) return std::string(name) + " must be a finite number (got " + fmt(v) + ")";
  }
  if (c.G <= 0) return "G must be > 0 (got " + fmt(c.G) + ")";
  if (c.d <= 0) return "d must be > 0 (got " + fmt(c.d) + ")";
  if (c.D1 <= 0) return "D1 must be > 0 (got " + fmt(c.D1) + ")";
  if (c.D1 >= c.D2) return "D1 must be < D2 (got D1 = " + fmt(c.D1) + ", D2 = " + fmt(c.D2) + ")";
  if (c.n_a <= 0) return "n_a must be > 0 (got " + fmt(c.n_a) + ")";
  const double dr = 0.5 * (c.D2 - c.D1);
  const double ls = std::sqrt(std::max(0.0, (c.n_a * c.d) * (c.n_a * c.d) - dr * dr));
  if (c.L0 <= ls) {
    return "L0 must be > solid height Ls = " + fmt(ls) + " (got L0 = " + fmt(c.L0) + ")";
  }
  return {};
}

const char* phase_name(Phase p) {
  switch (p) {
    case Phase::kTension: return "tension";
    case Phase::kLinear: return "linear";
    case Phase::kNonlinear: return "nonlinear";
    case Phase::kSolid: return "solid";
  }
  return "unknown";
}

ConicalLaw::ConicalLaw(const ConicalCard& card, double stiffness_cap) : card_(card) {
  r1_ = 0.5 * card.D1;
  r2_ = 0.5 * card.D2;
  const double nd = card.n_a * card.d;
  telescopic_ = (r2_ - r1_) >= nd;
  Ls_ = std::sqrt(std::max(0.0, nd * nd - (r2_ - r1_) * (r2_ - r1_)));
  S_ = card.L0 - Ls_;
  const double d4 = card.d * card.d * card.d * card.d;
  const double g = S_ / card.n_a;
  A_ = card.G * d4 * g / 64.0;
  c_ = 16.0 * card.n_a / (card.G * d4 * (r2_ - r1_));
  r1p4_ = r1_ * r1_ * r1_ * r1_;
  K0_ = 1.0 / (c_ * (r2_ * r2_ * r2_ * r2_ - r1p4_));
  Pt_ = A_ / (r2_ * r2_ * r2_);
  dt_ = Pt_ / K0_;
  Ps_ = A_ / (r1_ * r1_ * r1_);
  Et_ = 0.5 * K0_ * dt_ * dt_;

  // Stiffness cap: k_t(r) = kcap at r^4 = r1^4 + 1 / (c kcap).
  if (!(stiffness_cap > 0) || std::isinf(stiffness_cap)) {
    kcap_ = kInf;
    rcap_ = r1_;
    dcap_ = S_;
  } else if (stiffness_cap <= K0_) {
    kcap_ = K0_;
    rcap_ = r2_;
    dcap_ = dt_;
  } else {
    kcap_ = stiffness_cap;
    rcap_ = std::pow(r1p4_ + 1.0 / (c_ * kcap_), 0.25);
    dcap_ = c_ * A_ * (4.0 * r2_ - 3.0 * rcap_ - r1p4_ / (rcap_ * rcap_ * rcap_));
  }
  Pcap_ = A_ / (rcap_ * rcap_ * rcap_);
  kcap_force_ = std::isinf(kcap_) ? 0.0 : kcap_;
  Ecap_ = energy_at_radius(rcap_);

  // Inverse table over s = sqrt(S - delta) on [sqrt(S - dcap), sqrt(S - dt)].
  const double s_lo = std::sqrt(std::max(0.0, S_ - dcap_));
  s_max_ = std::sqrt(std::max(0.0, S_ - dt_));
  table_.assign(kTableSegments, {0, 0, 0, 0});
  if (s_max_ > s_lo) {
    const double h = (s_max_ - 0.0) / kTableSegments;
    inv_h_ = 1.0 / h;
    const double cA = c_ * A_;
    sqrt_cA_ = std::sqrt(cA);
    // x(s) = r_t - r1 and dx/ds = 1 / (sqrt(c A) phi'(x)) at a node.
    auto node = [&](double s, double* x, double* dxds) {
      *x = gap_from_s(s);
      const double r = r1_ + *x, ir = 1.0 / r;
      const double w = ir * (3.0 + ir * r1_ * (2.0 + ir * r1_));
      const double wp = -ir * ir * (3.0 + ir * r1_ * (4.0 + 3.0 * ir * r1_));
      const double sw = std::sqrt(w);
      *dxds = 1.0 / (std::sqrt(cA) * (sw + *x * wp / (2.0 * sw)));
    };
    double r0, m0;
    node(0.0, &r0, &m0);
    for (int i = 0; i < kTableSegments; ++i) {
      double r1n, m1;
      node((i + 1) * h, &r1n, &m1);
      // Hermite on local t in [0,1]: p(t) = a + b t + c t^2 + d t^3.
      const double a = r0, b = m0 * h;
      const double cc = 3.0 * (r1n - r0) - 2.0 * m0 * h - m1 * h;
      const double dd = 2.0 * (r0 - r1n) + m0 * h + m1 * h;
      table_[i] = {a, b, cc, dd};
      r0 = r1n;
      m0 = m1;
    }
  }
}

double ConicalLaw::deflection(double P) const {
  if (P <= Pt_) return P / K0_;  // tension and linear phase
  if (P >= Ps_) return S_;
  const double rt = std::cbrt(A_ / P);
  return c_ * P * (rt * rt * rt * rt - r1p4_) + S_ * (r2_ - rt) / (r2_ - r1_);
}

double ConicalLaw::compliance(double P) const {
  if (P <= Pt_) return 1.0 / K0_;
  if (P >= Ps_) return 0.0;
  const double rt = std::cbrt(A_ / P);
  return c_ * (rt * rt * rt * rt - r1p4_);
}

double ConicalLaw::deflection_eq11(double P, double n) const {
  const double D1 = card_.D1, D2 = card_.D2, na = card_.n_a;
  const double d4 = std::pow(card_.d, 4);
  const double b = 1.0 + (D2 / D1 - 1.0) * n / na;
  return 2.0 * P * std::pow(D1, 4) * na / (card_.G * d4 * (D2 - D1)) * (b * b * b * b - 1.0) +
         (card_.L0 - Ls_) * (1.0 - n / na);
}

double ConicalLaw::load_eq12_as_printed(double delta) const {
  const double D1 = card_.D1, D2 = card_.D2, na = card_.n_a, G = card_.G;
  const double d4 = std::pow(card_.d, 4);
  const double A5 = -2.0 * std::pow(D1, 4) * na / (G * d4 * (D2 - D1));
  const double A6 = -3.0 / (8.0 * (D2 - D1)) * std::cbrt(G * d4 * (card_.L0 - Ls_) / na);
  const double A7 = (card_.L0 - Ls_) * D2 / (D2 - D1);
  const double A4 = std::pow((A7 + delta) / A5, 2);
  const double A2 = -A6 / A5;
  const double A3 = std::cbrt(A4 / 16.0 + std::sqrt(std::pow(A4 / 16.0, 2) + std::pow(A2 / 3.0, 3)));
  const double A1 = A3 - A2 / (3.0 * A3);
  const double inner = 1.0 - std::sqrt(1.0 + A2 / (A1 * A1));
  const double bracket = 1.0 - (1.0 - 2.0 * std::sqrt(inner));
  return std::pow(A1 / 2.0, 1.5) * bracket * bracket * bracket;
}

// In the nonlinear phase S - delta = c A (3 r + r1^4 / r^3 - 4 r1)
//                                  = c A (r - r1)^2 (3 r^2 + 2 r1 r + r1^2) / r^3,
// so with x = r - r1 and s = sqrt(S - delta) the bottoming radius solves
//   phi(x) = x sqrt(w(r)) = s / sqrt(c A),   w(r) = 3/r + 2 r1/r^2 + r1^2/r^3,
// which is increasing with phi'(0) = sqrt(6 / r1) > 0: well conditioned up to the solid height,
// where the form in delta has a double root. Newton with a bisection safeguard.
double ConicalLaw::gap_from_s(double s) const {
  const double sigma = s / std::sqrt(c_ * A_);
  double lo = 0, hi = r2_ - r1_;
  double x = std::min(hi, sigma / std::sqrt(6.0 / r1_));
  for (int it = 0; it < 200; ++it) {
    const double r = r1_ + x, ir = 1.0 / r;
    const double w = ir * (3.0 + ir * r1_ * (2.0 + ir * r1_));
    const double wp = -ir * ir * (3.0 + ir * r1_ * (4.0 + 3.0 * ir * r1_));
    const double sw = std::sqrt(w);
    const double f = x * sw - sigma;
    if (f > 0) hi = std::min(hi, x); else lo = std::max(lo, x);
    const double fp = sw + x * wp / (2.0 * sw);
    double next = x - f / fp;
    if (!(next >= lo && next <= hi)) next = 0.5 * (lo + hi);
    if (next == x || hi - lo <= 1e-17 * (r2_ - r1_)) { x = next; break; }
    x = next;
  }
  return x;
}

double ConicalLaw::radius_from_deflection(double delta) const {
  return r1_ + gap_from_s(std::sqrt(std::max(0.0, S_ - delta)));
}

double ConicalLaw::energy_at_radius(double rt) const {
  // E(rt) = Et + 3 c A^2 [ (1/(2 rt^2) - 1/(2 r2^2)) - r1^4/6 (1/rt^6 - 1/r2^6) ]
  const double i2 = 1.0 / (rt * rt), j2 = 1.0 / (r2_ * r2_);
  return Et_ + 3.0 * c_ * A_ * A_ *
                   (0.5 * (i2 - j2) - r1p4_ / 6.0 * (i2 * i2 * i2 - j2 * j2 * j2));
}

LawSample ConicalLaw::evaluate_exact(double delta) const {
  if (delta < 0) return {K0_ * delta, K0_, Phase::kTension};
  if (delta <= dt_) return {K0_ * delta, K0_, Phase::kLinear};
  if (delta <= dcap_) {
    const double x = gap_from_s(std::sqrt(S_ - delta));
    const double rt = r1_ + x;
    const double k = 1.0 / (c_ * x * (2.0 * r1_ + x) * (rt * rt + r1_ * r1_));
    return {A_ / (rt * rt * rt), k, Phase::kNonlinear};
  }
  if (std::isinf(kcap_)) return {Ps_, kInf, Phase::kSolid};
  return {Pcap_ + kcap_ * (delta - dcap_), kcap_, delta > S_ ? Phase::kSolid : Phase::kNonlinear};
}

LawSample ConicalLaw::evaluate(double delta) const {
  if (delta <= dt_) return {K0_ * delta, K0_, delta < 0 ? Phase::kTension : Phase::kLinear};
  if (delta > dcap_) {
    if (std::isinf(kcap_)) return {Ps_, kInf, Phase::kSolid};
    return {Pcap_ + kcap_ * (delta - dcap_), kcap_, delta > S_ ? Phase::kSolid : Phase::kNonlinear};
  }
  // Table lookup of x = r_t - r1 in s = sqrt(S - delta), then one Newton step on
  // phi(x) = s / sqrt(c A) with the table's slope. r^4 - r1^4 = x (2 r1 + x)(r^2 + r1^2) has no
  // cancellation near the solid height.
  const double s = std::sqrt(S_ - delta);
  const double u = s * inv_h_;
  const int i = std::min(static_cast<int>(u), kTableSegments - 1);
  const double t = u - i;
  const auto& k = table_[i];
  double x = k[0] + t * (k[1] + t * (k[2] + t * k[3]));
  if constexpr (kNewtonPolish) {
    const double dxds = (k[1] + t * (2.0 * k[2] + 3.0 * t * k[3])) * inv_h_;
    const double r = r1_ + x, ir = 1.0 / r;
    const double w = ir * (3.0 + ir * r1_ * (2.0 + ir * r1_));
    x -= (x * std::sqrt(w) * sqrt_cA_ - s) * dxds;
  }
  const double r = r1_ + x, ir = 1.0 / r;
  const double ir3 = ir * ir * ir;
  return {A_ * ir3, 1.0 / (c_ * x * (2.0 * r1_ + x) * (r * r + r1_ * r1_)), Phase::kNonlinear};
}

void ConicalLaw::evaluate_batch(const double* __restrict deflection, double* __restrict force,
                                double* __restrict stiffness, int n) const {
  const double* __restrict tab = table_.front().data();
  const double dt = dt_, dcap = dcap_, S = S_, inv_h = inv_h_, r1 = r1_, A = A_, c = c_;
  const double sqrt_cA = sqrt_cA_, K0 = K0_, Pcap = Pcap_, kcap = kcap_, kcf = kcap_force_;
  for (int i = 0; i < n; ++i) {
    const double dl = deflection[i];
    // Nonlinear branch on the deflection clamped into its range; selected below.
    const double dc = std::min(std::max(dl, dt), dcap);
    const double s = std::sqrt(S - dc);
    const double u = s * inv_h;
    const int j = std::min(static_cast<int>(u), kTableSegments - 1);
    const double t = u - j;
    const double* k = tab + 4 * j;
    double x = k[0] + t * (k[1] + t * (k[2] + t * k[3]));
    if constexpr (kNewtonPolish) {
      const double dxds = (k[1] + t * (2.0 * k[2] + 3.0 * t * k[3])) * inv_h;
      const double ir = 1.0 / (r1 + x);
      const double w = ir * (3.0 + ir * r1 * (2.0 + ir * r1));
      x -= (x * std::sqrt(w) * sqrt_cA - s) * dxds;
    }
    const double r = r1 + x, ir = 1.0 / r;
    const double fN = A * ir * ir * ir;
    const double kN = 1.0 / (c * x * (2.0 * r1 + x) * (r * r + r1 * r1));
    const bool lin = dl <= dt, over = dl > dcap;
    force[i] = lin ? K0 * dl : (over ? Pcap + kcf * (dl - dcap) : fN);
    stiffness[i] = lin ? K0 : (over ? kcap : kN);
  }
}

double ConicalLaw::energy(double delta) const {
  if (delta <= dt_) return 0.5 * K0_ * delta * delta;
  if (delta <= dcap_) return energy_at_radius(radius_from_deflection(delta));
  if (std::isinf(kcap_)) return Ecap_ + Ps_ * (delta - S_);
  const double x = delta - dcap_;
  return Ecap_ + Pcap_ * x + 0.5 * kcap_ * x * x;
}

}  // namespace conica
