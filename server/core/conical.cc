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

// The nonlinear-phase inverse shared by evaluate() and evaluate_batch(), so that both give the same
// bits. For a deflection in [delta_t, delta_cap]:
//   s = sqrt(S - delta), u = s / h, segment i = min(floor(u), N - 1), t = u - i
//   x0 = p_i(t) (cubic Hermite of x = r_t - r1), then one Newton step on
//   phi(x) = x sqrt(w(r1 + x)) = s / sqrt(c A) with the table's slope dx/ds,
//   force = A / r^3 and stiffness = 1 / C with the compliance C = c x (2 r1 + x)(r^2 + r1^2)
//   (= c (r^4 - r1^4) without cancellation); both from the single reciprocal q = 1 / (r C).
// At the solid height itself (x = 0) q is infinite and the results are NaN: callers select the
// solid branch there. Inline and free of branches, so that the array loop vectorises.
struct NonlinearKernel {
  double S, inv_h, r1, A, c, sqrt_cA;
  const double* __restrict c0;
  const double* __restrict c1;
  const double* __restrict c2;
  const double* __restrict c3;
  int last;  // N - 1

  inline void operator()(double delta, double* force, double* stiffness) const {
    const double s = std::sqrt(S - delta);
    const double u = s * inv_h;
    const int i = std::min(static_cast<int>(u), last);
    const double t = u - i;
    const double a0 = c0[i], a1 = c1[i], a2 = c2[i], a3 = c3[i];
    const double x0 = a0 + t * (a1 + t * (a2 + t * a3));
    const double dxds = (a1 + t * (2.0 * a2 + 3.0 * t * a3)) * inv_h;
    const double ir0 = 1.0 / (r1 + x0);
    const double w = ir0 * (3.0 + ir0 * r1 * (2.0 + ir0 * r1));
    const double x = x0 - (x0 * std::sqrt(w) * sqrt_cA - s) * dxds;
    const double r = r1 + x;
    const double C = c * x * (2.0 * r1 + x) * (r * r + r1 * r1);
    const double q = 1.0 / (r * C);
    const double ir = C * q;
    *force = A * ir * ir * ir;
    *stiffness = r * q;
  }
};

// The kernel over a table of n cubic segments per coefficient (c0 c1 c2 c3 in turn).
inline NonlinearKernel make_kernel(double S, double inv_h, double r1, double A, double c,
                                   double sqrt_cA, const double* tab, int n) {
  return NonlinearKernel{S,   inv_h,   r1,          A,           c,    sqrt_cA,
                         tab, tab + n, tab + 2 * n, tab + 3 * n, n - 1};
}

}  // namespace

std::string validate(const ConicalCard& c) {
  const std::pair<const char*, double> fields[] = {{"G", c.G},   {"d", c.d},   {"D1", c.D1},
                                                   {"D2", c.D2}, {"L0", c.L0}, {"n_a", c.n_a}};
  for (const auto& [name, v] : fields) {
    if (!std::isfinite(v))
      return std::string(name) + " must be a finite number (got " + fmt(v) + ")";
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
  if (!std::isfinite(c.precompression))
    return "precompression must be a finite number (got " + fmt(c.precompression) + ")";
  if (c.precompression < 0 || c.precompression >= c.L0 - ls) {
    return "precompression must be >= 0 and < stroke S = L0 - Ls = " + fmt(c.L0 - ls) + " (got " +
           fmt(c.precompression) + ")";
  }
  return {};
}

const char* phase_name(Phase p) {
  switch (p) {
    case Phase::kTension:
      return "tension";
    case Phase::kLinear:
      return "linear";
    case Phase::kNonlinear:
      return "nonlinear";
    case Phase::kSolid:
      return "solid";
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
    // r^4 - r1^4 = 1 / (c kcap), solved for x = r - r1 without cancellation: a start from the
    // fourth root, one Newton step on x (2 r1 + x)(r^2 + r1^2). Then S - delta_cap in the
    // cancellation-free form c A x^2 (3 r^2 + 2 r1 r + r1^2) / r^3 (see gap_from_s).
    kcap_ = stiffness_cap;
    const double K = 1.0 / (c_ * kcap_);
    double x = std::pow(r1p4_ + K, 0.25) - r1_;
    double r = r1_ + x;
    x -= (x * (2.0 * r1_ + x) * (r * r + r1_ * r1_) - K) / (4.0 * r * r * r);
    r = r1_ + x;
    rcap_ = r;
    dcap_ = S_ - c_ * A_ * x * x * (3.0 * r * r + 2.0 * r1_ * r + r1_ * r1_) / (r * r * r);
  }
  Pcap_ = A_ / (rcap_ * rcap_ * rcap_);
  kcap_force_ = std::isinf(kcap_) ? 0.0 : kcap_;
  Ecap_ = energy_at_radius(rcap_);

  // Inverse table over s = sqrt(S - delta) on [sqrt(S - dcap), sqrt(S - dt)].
  const double s_lo = std::sqrt(std::max(0.0, S_ - dcap_));
  s_max_ = std::sqrt(std::max(0.0, S_ - dt_));
  table_.assign(4 * kTableSegments, 0.0);
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
      table_[i] = a;
      table_[kTableSegments + i] = b;
      table_[2 * kTableSegments + i] = cc;
      table_[3 * kTableSegments + i] = dd;
      r0 = r1n;
      m0 = m1;
    }
  }

  // Pre-compression: the plain law's values at delta0 (validate() keeps delta0 in [0, S)).
  d0_ = card.precompression;
  if (d0_ != 0) {
    const LawSample t = evaluate_plain(d0_), x = evaluate_exact_plain(d0_);
    F0_ = t.force;
    F0x_ = x.force;
    k_rest_ = x.stiffness;
    E0_ = energy_plain(d0_);
  } else {
    k_rest_ = K0_;
  }
}

double ConicalLaw::deflection(double P) const {
  P += F0x_;
  double delta;
  if (P <= Pt_) {
    delta = P / K0_;  // tension and linear phase
  } else if (P >= Ps_) {
    delta = S_;
  } else {
    const double rt = std::cbrt(A_ / P);
    delta = c_ * P * (rt * rt * rt * rt - r1p4_) + S_ * (r2_ - rt) / (r2_ - r1_);
  }
  return delta - d0_;
}

double ConicalLaw::compliance(double P) const {
  P += F0x_;
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
  const double A3 =
      std::cbrt(A4 / 16.0 + std::sqrt(std::pow(A4 / 16.0, 2) + std::pow(A2 / 3.0, 3)));
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
    if (f > 0)
      hi = std::min(hi, x);
    else
      lo = std::max(lo, x);
    const double fp = sw + x * wp / (2.0 * sw);
    double next = x - f / fp;
    if (!(next >= lo && next <= hi)) next = 0.5 * (lo + hi);
    if (next == x || hi - lo <= 4.0 * std::numeric_limits<double>::epsilon() * hi) {
      x = next;
      break;
    }
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
  return Et_ + 3.0 * c_ * A_ * A_ * (0.5 * (i2 - j2) - r1p4_ / 6.0 * (i2 * i2 * i2 - j2 * j2 * j2));
}

LawSample ConicalLaw::evaluate_exact(double delta) const {
  LawSample s = evaluate_exact_plain(delta + d0_);
  s.force -= F0x_;
  return s;
}

LawSample ConicalLaw::evaluate(double delta) const {
  LawSample s = evaluate_plain(delta + d0_);
  s.force -= F0_;
  return s;
}

LawSample ConicalLaw::evaluate_exact_plain(double delta) const {
  if (delta < 0) return {K0_ * delta, K0_, Phase::kTension};
  if (delta <= dt_) return {K0_ * delta, K0_, Phase::kLinear};
  if (delta < dcap_) {
    const double x = gap_from_s(std::sqrt(S_ - delta));
    const double rt = r1_ + x;
    const double k = 1.0 / (c_ * x * (2.0 * r1_ + x) * (rt * rt + r1_ * r1_));
    return {A_ / (rt * rt * rt), k, Phase::kNonlinear};
  }
  if (std::isinf(kcap_)) return {Ps_, kInf, Phase::kSolid};
  return {Pcap_ + kcap_ * (delta - dcap_), kcap_, delta > S_ ? Phase::kSolid : Phase::kNonlinear};
}

LawSample ConicalLaw::evaluate_plain(double delta) const {
  if (delta <= dt_) return {K0_ * delta, K0_, delta < 0 ? Phase::kTension : Phase::kLinear};
  if (delta >= dcap_) {
    if (std::isinf(kcap_)) return {Ps_, kInf, Phase::kSolid};
    return {Pcap_ + kcap_ * (delta - dcap_), kcap_, delta > S_ ? Phase::kSolid : Phase::kNonlinear};
  }
  const double* tab = table_.data();
  const NonlinearKernel kern = make_kernel(S_, inv_h_, r1_, A_, c_, sqrt_cA_, tab, kTableSegments);
  LawSample out{0, 0, Phase::kNonlinear};
  kern(delta, &out.force, &out.stiffness);
  return out;
}

void ConicalLaw::evaluate_batch(const double* __restrict deflection, double* __restrict force,
                                double* __restrict stiffness, int n) const {
  // Two instances so that the plain law (delta0 = 0) keeps its loop as it was: the shifted one
  // adds delta0 to every deflection and subtracts the preload from every force.
  if (d0_ != 0) {
    evaluate_batch_impl<true>(deflection, force, stiffness, n);
  } else {
    evaluate_batch_impl<false>(deflection, force, stiffness, n);
  }
}

template <bool kShifted>
void ConicalLaw::evaluate_batch_impl(const double* __restrict deflection, double* __restrict force,
                                     double* __restrict stiffness, int n) const {
  const double* tab = table_.data();
  const NonlinearKernel kern = make_kernel(S_, inv_h_, r1_, A_, c_, sqrt_cA_, tab, kTableSegments);
  const double dt = dt_, dcap = dcap_, K0 = K0_, Pcap = Pcap_, kcap = kcap_, kcf = kcap_force_;
  const double d0 = d0_, F0 = F0_;
  for (int begin = 0; begin < n; begin += kBatchChunk) {
    const int m = std::min(kBatchChunk, n - begin);
    const double* __restrict dl = deflection + begin;
    double* __restrict f = force + begin;
    double* __restrict k = stiffness + begin;
    // A chunk with every spring in tension or in the linear phase is a Hooke chunk.
    int nonlinear = 0;
    if constexpr (kShifted) {
      for (int i = 0; i < m; ++i) nonlinear |= dl[i] + d0 > dt;
      if (!nonlinear) {
        for (int i = 0; i < m; ++i) {
          f[i] = K0 * (dl[i] + d0) - F0;
          k[i] = K0;
        }
        continue;
      }
    } else {
      for (int i = 0; i < m; ++i) nonlinear |= dl[i] > dt;
      if (!nonlinear) {
        for (int i = 0; i < m; ++i) {
          f[i] = K0 * dl[i];
          k[i] = K0;
        }
        continue;
      }
    }
    // Pass 1: the nonlinear branch for every spring, on its deflection clamped into
    // [delta_t, delta_cap]. Pass 2: select the phase. Keeping the selection out of pass 1 keeps
    // the gathers and square roots unconditional, which is what lets GCC vectorise pass 1.
    for (int i = 0; i < m; ++i) {
      const double x = kShifted ? dl[i] + d0 : dl[i];
      kern(std::min(std::max(x, dt), dcap), &f[i], &k[i]);
    }
    for (int i = 0; i < m; ++i) {
      const double x = kShifted ? dl[i] + d0 : dl[i], fn = f[i], kn = k[i];
      const bool lin = x <= dt, over = x >= dcap;
      const double fx = lin ? K0 * x : (over ? Pcap + kcf * (x - dcap) : fn);
      f[i] = kShifted ? fx - F0 : fx;
      k[i] = lin ? K0 : (over ? kcap : kn);
    }
  }
}

double ConicalLaw::energy(double delta) const {
  if (d0_ == 0) return energy_plain(delta);
  return energy_plain(d0_ + delta) - E0_ - F0x_ * delta;
}

double ConicalLaw::energy_plain(double delta) const {
  if (delta <= dt_) return 0.5 * K0_ * delta * delta;
  if (delta <= dcap_) return energy_at_radius(radius_from_deflection(delta));
  if (std::isinf(kcap_)) return Ecap_ + Ps_ * (delta - S_);
  const double x = delta - dcap_;
  return Ecap_ + Pcap_ * x + 0.5 * kcap_ * x * x;
}

}  // namespace conica
