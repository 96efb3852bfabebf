#include "lab/calibration.h"

#include <ceres/ceres.h>

#include <Eigen/Dense>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>
#include <thread>

namespace conica::lab {
namespace {

std::vector<std::string> split(std::string_view line, char sep) {
  std::vector<std::string> out;
  size_t a = 0;
  while (true) {
    const size_t b = line.find(sep, a);
    out.emplace_back(line.substr(a, b == std::string_view::npos ? std::string_view::npos : b - a));
    if (b == std::string_view::npos) break;
    a = b + 1;
  }
  for (auto& s : out) {
    while (!s.empty() && (s.back() == '\r' || s.back() == ' ' || s.back() == ';')) s.pop_back();
    while (!s.empty() && s.front() == ' ') s.erase(s.begin());
  }
  return out;
}

std::string fmt(double v, int precision = 6) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*g", precision, v);
  return buf;
}

double sigmoid(double x) { return 1.0 / (1.0 + std::exp(-x)); }
double logit(double p) { return std::log(p / (1.0 - p)); }

// Runs fn(0) .. fn(n - 1) on up to `threads` threads (0: one per hardware thread), each index
// once; fn must not touch shared state.
void parallel_for(int n, int threads, const std::function<void(int)>& fn) {
  if (threads <= 0) threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  threads = std::min(threads, n);
  std::atomic<int> next{0};
  auto work = [&] {
    for (int k = next++; k < n; k = next++) fn(k);
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < threads; ++t) pool.emplace_back(work);
  work();
  for (std::thread& t : pool) t.join();
}

// Unconstrained coordinates of K shapes: [ln E_c (K), logit stroke (K), logit taper (K, or 1
// when tied), logit pre-compression (K, with pre)], the logits over the bounds. The
// pre-compression's upper bound depends on the stroke: p <= min(p_max, 1 - smin / s), so that the
// stroke left, (1 - p) s, stays above the card's largest strain.
struct Layout {
  int cards = 1;
  bool tie = false;
  ShapeBounds b;
  std::vector<double> smin;  // (cards) stroke lower bound per card
  bool iso = false;          // K > 1: moduli tied by the isotropy condition
  bool pre = false;          // pre-compressions fitted
  double stroke_min(int c) const {
    return c < static_cast<int>(smin.size()) ? smin[c] : b.stroke_min;
  }
  double pre_max(int c, double stroke) const {
    return std::max(0.0, std::min(b.precompression_max, 1 - stroke_min(c) / stroke));
  }
  int moduli() const { return iso && cards > 1 ? cards - 1 : cards; }
  int size() const { return moduli() + cards + (tie ? 1 : cards) + (pre ? cards : 0); }
};
double to01(double v, double lo, double hi) {
  return std::clamp((v - lo) / (hi - lo), 1e-6, 1 - 1e-6);
}
// k_t(delta0) / K0 of a shape: the factor from the card modulus E_c to the modulus at rest
// (1 without pre-compression; shape-only, so any base card gives it).
double rest_factor(const CardShape& sh) {
  if (!(sh.precompression > 0)) return 1.0;
  const ConicalCard c = card_with_shape({1e9, 1e-3, 2e-3, 8e-3, 10e-3, 3}, sh);
  if (!validate(c).empty()) return 1.0;
  const ConicalLaw law(c);
  return law.rest_stiffness() / law.k0();
}
// Isotropic splits: K = 2, E_diag = 36/17 E_edge; K = 3, E_body = 4.5 w E_edge (w <= 0.8),
// E_face = 4 (1 - w) E_edge (so that 4 E_e = E_f + 8/9 E_b).
std::vector<CardShape> decode(const double* x, const Layout& L) {
  std::vector<CardShape> out(L.cards);
  const int M = L.moduli();
  for (int c = 0; c < L.cards; ++c) {
    out[c].stroke = L.stroke_min(c) + (L.b.stroke_max - L.stroke_min(c)) * sigmoid(x[M + c]);
    out[c].taper =
        L.b.taper_min + (L.b.taper_max - L.b.taper_min) * sigmoid(x[M + L.cards + (L.tie ? 0 : c)]);
    if (L.pre)
      out[c].precompression =
          L.pre_max(c, out[c].stroke) * sigmoid(x[M + L.cards + (L.tie ? 1 : L.cards) + c]);
  }
  if (L.iso && L.cards == 2) {
    out[0].modulus = std::exp(x[0]);
    out[1].modulus = 36.0 / 17 * out[0].modulus;
  } else if (L.iso && L.cards == 3) {
    const double w = 0.8 * sigmoid(x[1]);  // w <= 0.8: the face diagonals keep a share
    out[0].modulus = std::exp(x[0]);
    out[1].modulus = 4 * (1 - w) * out[0].modulus;
    out[2].modulus = 4.5 * w * out[0].modulus;
  } else {
    for (int c = 0; c < L.cards; ++c) out[c].modulus = std::exp(x[c]);
  }
  // With pre-compressions the isotropy tie holds for the moduli at rest, E_c k_t(delta0) / K0.
  if (L.iso && L.cards > 1 && L.pre)
    for (CardShape& sh : out) sh.modulus /= rest_factor(sh);
  return out;
}
std::vector<double> encode(const std::vector<CardShape>& s, const Layout& L) {
  std::vector<double> x(L.size());
  const int M = L.moduli();
  for (int c = 0; c < L.cards; ++c) {
    x[M + c] = logit(to01(s[c].stroke, L.stroke_min(c), L.b.stroke_max));
    if (!L.tie || c == 0)
      x[M + L.cards + c] = logit(to01(s[c].taper, L.b.taper_min, L.b.taper_max));
    if (L.pre) {
      const double hi = L.pre_max(c, s[c].stroke);
      x[M + L.cards + (L.tie ? 1 : L.cards) + c] =
          logit(hi > 0 ? to01(s[c].precompression, 0, hi) : 1e-6);
    }
  }
  const bool rest = L.iso && L.cards > 1 && L.pre;
  auto rest_modulus = [&](int c) { return s[c].modulus * (rest ? rest_factor(s[c]) : 1.0); };
  x[0] = std::log(rest_modulus(0));
  if (L.iso && L.cards == 3)
    x[1] = logit(std::clamp(rest_modulus(2) / (4.5 * 0.8 * rest_modulus(0)), 1e-6, 1 - 1e-6));
  else if (!L.iso)
    for (int c = 1; c < L.cards; ++c) x[c] = std::log(s[c].modulus);
  return x;
}

std::string shapes_text(const std::vector<CardShape>& sh) {
  std::string t;
  for (size_t c = 0; c < sh.size(); ++c)
    t += (c ? "; " : "") + std::string("E_c ") + fmt(sh[c].modulus, 5) + " Pa, taper " +
         fmt(sh[c].taper, 4) + ", stroke " + fmt(sh[c].stroke, 4) +
         (sh[c].precompression > 0 ? ", pre-compression " + fmt(sh[c].precompression, 4) + " S"
                                   : std::string());
  return t;
}

struct BodyGeometry {
  double height = 0;  // m, along the plate normal
  double area = 0;    // m^2
};

std::vector<double> surrogate_impl(const std::vector<SpringGroupSpec>& groups, Mapping mapping,
                                   const BodyGeometry& geo, const std::vector<double>& grid,
                                   double bulk_modulus, double shear_modulus) {
  Model cell;
  if (!make_uniaxial_cell(groups, mapping, 0.01, &cell, bulk_modulus, shear_modulus).empty())
    return std::vector<double>(grid.size(), std::numeric_limits<double>::quiet_NaN());
  std::vector<double> strains(grid.size());
  for (size_t k = 0; k < grid.size(); ++k) strains[k] = grid[k] / geo.height;
  std::vector<double> f = cell_stress_curve(cell, strains);
  for (double& v : f) v *= geo.area;
  return f;
}

std::vector<ConicalCard> cards_of(const ConicalCard& base, const std::vector<CardShape>& sh) {
  std::vector<ConicalCard> out;
  for (const CardShape& s : sh) out.push_back(card_with_shape(base, s));
  return out;
}

// Residuals (model - data) / data over grid indices >= first, for Ceres.
struct RelativeResiduals {
  std::function<std::vector<double>(const std::vector<ConicalCard>&)> model;
  ConicalCard base;
  Layout layout;
  const std::vector<double>* data = nullptr;
  int first = 0;

  bool operator()(double const* const* x, double* r) const {
    const std::vector<ConicalCard> cards = cards_of(base, decode(x[0], layout));
    for (const ConicalCard& c : cards)
      if (!validate(c).empty()) return false;
    const std::vector<double> f = model(cards);
    for (size_t k = first; k < data->size(); ++k) {
      if (!std::isfinite(f[k])) return false;
      r[k - first] = (f[k] - (*data)[k]) / (*data)[k];
    }
    return true;
  }
};

class Progress : public ceres::IterationCallback {
 public:
  Progress(const FitOptions& o, std::string stage, int n, const double* x, const Layout& L)
      : o_(o), stage_(std::move(stage)), n_(n), x_(x), L_(L) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    if (o_.progress)
      o_.progress(stage_ + " iteration " + std::to_string(s.iteration) + ": rms relative error " +
                  fmt(100 * std::sqrt(2 * s.cost / n_), 4) + " %, " + shapes_text(decode(x_, L_)) +
                  (s.step_is_successful ? "" : " (step rejected)"));
    return ceres::SOLVER_CONTINUE;
  }

 private:
  const FitOptions& o_;
  std::string stage_;
  int n_;
  const double* x_;
  Layout L_;
};

// Levenberg-Marquardt from x (updated in place).
void solve_lm(RelativeResiduals res, int num_residuals, int iterations, bool central,
              double relative_step, const FitOptions& o, const std::string& stage, double* x) {
  const Layout L = res.layout;
  ceres::Problem problem;
  ceres::NumericDiffOptions nd;
  nd.relative_step_size = relative_step;
  ceres::DynamicCostFunction* cost;
  if (central) {
    cost = new ceres::DynamicNumericDiffCostFunction<RelativeResiduals, ceres::CENTRAL>(
        new RelativeResiduals(std::move(res)), ceres::TAKE_OWNERSHIP, nd);
  } else {
    cost = new ceres::DynamicNumericDiffCostFunction<RelativeResiduals, ceres::FORWARD>(
        new RelativeResiduals(std::move(res)), ceres::TAKE_OWNERSHIP, nd);
  }
  cost->AddParameterBlock(L.size());
  cost->SetNumResiduals(num_residuals);
  problem.AddResidualBlock(cost, nullptr, x);
  ceres::Solver::Options so;
  so.minimizer_type = ceres::TRUST_REGION;
  so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = iterations;
  so.function_tolerance = 1e-10;
  so.parameter_tolerance = 1e-10;
  so.num_threads = 1;
  so.logging_type = ceres::SILENT;
  Progress cb(o, stage, num_residuals, x, L);
  so.callbacks.push_back(&cb);
  so.update_state_every_iteration = true;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  if (o.progress)
    o.progress(stage + ": " + summary.message + " (" + std::to_string(summary.iterations.size()) +
               " iterations)");
}

// Lawson-Hanson non-negative least squares: min |A x - b| subject to x >= 0.
Eigen::VectorXd nnls(const Eigen::MatrixXd& A, const Eigen::VectorXd& b) {
  const int m = static_cast<int>(A.cols());
  Eigen::VectorXd x = Eigen::VectorXd::Zero(m);
  std::vector<char> passive(m, 0);
  const double tol = 1e-12 * std::max(1.0, A.norm() * b.norm());
  for (int outer = 0; outer < 3 * m; ++outer) {
    const Eigen::VectorXd grad = A.transpose() * (b - A * x);
    int t = -1;
    for (int j = 0; j < m; ++j)
      if (!passive[j] && grad[j] > tol && (t < 0 || grad[j] > grad[t])) t = j;
    if (t < 0) break;
    passive[t] = 1;
    for (int inner = 0; inner < 3 * m; ++inner) {
      std::vector<int> P;
      for (int j = 0; j < m; ++j)
        if (passive[j]) P.push_back(j);
      Eigen::MatrixXd Ap(A.rows(), P.size());
      for (size_t q = 0; q < P.size(); ++q) Ap.col(q) = A.col(P[q]);
      const Eigen::VectorXd zp = Ap.colPivHouseholderQr().solve(b);
      bool all_positive = true;
      for (size_t q = 0; q < P.size(); ++q) all_positive &= zp[q] > 0;
      if (all_positive) {
        x.setZero();
        for (size_t q = 0; q < P.size(); ++q) x[P[q]] = zp[q];
        break;
      }
      double alpha = 1;
      for (size_t q = 0; q < P.size(); ++q)
        if (zp[q] <= 0) alpha = std::min(alpha, x[P[q]] / (x[P[q]] - zp[q]));
      for (size_t q = 0; q < P.size(); ++q) {
        x[P[q]] += alpha * (zp[q] - x[P[q]]);
        if (x[P[q]] <= 1e-15) {
          x[P[q]] = 0;
          passive[P[q]] = 0;
        }
      }
    }
  }
  return x;
}

}  // namespace

ColumnFloor column_floor(const std::vector<double>& strain, const std::vector<double>& force,
                         int first, double area, const ShapeBounds& B, bool precompressed) {
  ColumnFloor out;
  const int n = static_cast<int>(strain.size());
  if (n != static_cast<int>(force.size()) || n - first < 2 || strain.empty()) return out;
  const double max_strain = strain.back();
  const double smin = std::max(B.stroke_min, std::min(0.99 * B.stroke_max, 1.02 * max_strain));
  // Basis: column stress per unit modulus, sigma(eps) = P(L0 eps) / L0^2 at E_c = 1 Pa.
  const ConicalCard base{1e9, 1e-3, 2e-3, 8e-3, 10e-3, 3};
  // Plain laws: 24 tapers x 24 strokes. Pre-compressed: 16 x 16 x 12 pre-compressions p from 0
  // to the largest that leaves (1 - p) s >= smin.
  const int nt = precompressed ? 16 : 24, ns = nt, np = precompressed ? 12 : 1;
  std::vector<CardShape> shapes;
  std::vector<std::vector<double>> cols;
  for (int i = 0; i < nt; ++i)
    for (int j = 0; j < ns; ++j)
      for (int q = 0; q < np; ++q) {
        CardShape sh{1.0, B.taper_min + (B.taper_max - B.taper_min) * i / (nt - 1),
                     smin + (B.stroke_max - smin) * j / (ns - 1)};
        if (np > 1)
          sh.precompression =
              std::max(0.0, std::min(B.precompression_max, 1 - smin / sh.stroke)) * q / (np - 1);
        if (q > 0 && sh.precompression == 0) continue;
        const ConicalCard card = card_with_shape(base, sh);
        if (!validate(card).empty()) continue;
        const ConicalLaw law(card);
        std::vector<double> c(n);
        bool ok = true;
        for (int k = 0; k < n && ok; ++k) {
          const double delta = strain[k] * card.L0;
          ok = delta < law.remaining_stroke();
          c[k] = ok ? law.evaluate_exact(delta).force / (card.L0 * card.L0) * area : 0;
        }
        if (!ok) continue;
        shapes.push_back(sh);
        cols.push_back(std::move(c));
      }
  const int m = static_cast<int>(cols.size());
  const int R = n - first;
  if (m == 0) return out;
  Eigen::MatrixXd A(R, m);
  Eigen::VectorXd scale(m);
  for (int j = 0; j < m; ++j) {
    for (int k = 0; k < R; ++k) A(k, j) = cols[j][first + k] / force[first + k];
    scale[j] = A.col(j).norm();
    A.col(j) /= scale[j];
  }
  // Iteratively reweighted least squares for the L1 error: weights 1 / max(|r|, eps).
  Eigen::VectorXd omega = Eigen::VectorXd::Ones(R), best_x;
  double best = std::numeric_limits<double>::infinity();
  for (int it = 0; it < 60; ++it) {
    const Eigen::VectorXd sw = omega.cwiseSqrt();
    const Eigen::VectorXd x = nnls(sw.asDiagonal() * A, sw);
    const Eigen::VectorXd r = A * x - Eigen::VectorXd::Ones(R);
    const double e = r.cwiseAbs().mean();
    if (e < best) {
      best = e;
      best_x = x;
    }
    const double eps = std::max(1e-7, 1e-3 * e);
    for (int k = 0; k < R; ++k) omega[k] = 1 / std::max(std::abs(r[k]), eps);
  }
  out.error = best;
  out.force.assign(n, 0.0);
  for (int j = 0; j < m; ++j) {
    const double w = best_x[j] / scale[j];  // modulus, Pa
    if (!(w > 0)) continue;
    CardShape sh = shapes[j];
    sh.modulus = w;
    out.shapes.push_back(sh);
    for (int k = 0; k < n; ++k) out.force[k] += w * cols[j][k];
  }
  return out;
}

bool parse_force_curve(std::string_view text, Curve* out, std::string* error) {
  out->clear();
  int col_u = -1, col_f = -1;
  size_t pos = 0;
  int line_no = 0;
  double max_u = -std::numeric_limits<double>::infinity();
  size_t max_at = 0;
  while (pos < text.size()) {
    size_t end = text.find('\n', pos);
    if (end == std::string_view::npos) end = text.size();
    const std::string_view line = text.substr(pos, end - pos);
    pos = end + 1;
    ++line_no;
    if (line.find_first_not_of(" \r\t") == std::string_view::npos) continue;
    const auto cells = split(line, ',');
    if (col_u < 0) {
      for (size_t c = 0; c < cells.size(); ++c) {
        if (cells[c] == "Compression (mm)") col_u = static_cast<int>(c);
        if (cells[c] == "Load (N)") col_f = static_cast<int>(c);
      }
      if (col_u >= 0 && col_f < 0) {
        *error = "line " + std::to_string(line_no) + ": no \"Load (N)\" column";
        return false;
      }
      continue;
    }
    if (static_cast<int>(cells.size()) <= std::max(col_u, col_f)) {
      *error = "line " + std::to_string(line_no) + ": " + std::to_string(cells.size()) +
               " columns, expected at least " + std::to_string(std::max(col_u, col_f) + 1);
      return false;
    }
    char* e1 = nullptr;
    char* e2 = nullptr;
    const double u = std::strtod(cells[col_u].c_str(), &e1);
    const double f = std::strtod(cells[col_f].c_str(), &e2);
    if (e1 == cells[col_u].c_str() || e2 == cells[col_f].c_str() || *e1 || *e2 ||
        !std::isfinite(u) || !std::isfinite(f)) {
      *error = "line " + std::to_string(line_no) + ": not a number";
      return false;
    }
    out->push_back({u * 1e-3, f});
    if (u > max_u) {
      max_u = u;
      max_at = out->size();
    }
  }
  if (col_u < 0) {
    *error = "no column header with \"Compression (mm)\" and \"Load (N)\"";
    return false;
  }
  if (out->size() < 2) {
    *error = "fewer than two data rows";
    return false;
  }
  out->resize(max_at);  // the loading branch
  return true;
}

CardShape shape_of(const ConicalCard& card) {
  const ConicalLaw law(card);
  return {law.k0() / card.L0, card.D1 / card.D2, law.stroke() / card.L0,
          card.precompression / law.stroke()};
}

ConicalCard card_with_shape(const ConicalCard& base, const CardShape& shape) {
  ConicalCard c = base;
  const double r2 = base.D2 / 2, r1 = shape.taper * r2;
  c.D1 = 2 * r1;
  const double Ls = std::max(0.0, (1 - shape.stroke) * base.L0);
  c.d = std::sqrt(Ls * Ls + (r2 - r1) * (r2 - r1)) / base.n_a;
  const double k0 = shape.modulus * base.L0;
  const double d4 = c.d * c.d * c.d * c.d;
  c.G = k0 * 16 * base.n_a * (std::pow(r2, 4) - std::pow(r1, 4)) / (d4 * (r2 - r1));
  c.precompression = shape.precompression * shape.stroke * base.L0;
  return c;
}

double average_relative_error(const std::vector<double>& model, const std::vector<double>& data,
                              int first) {
  double sum = 0;
  int n = 0;
  for (size_t k = first; k < data.size() && k < model.size(); ++k, ++n)
    sum += std::abs(model[k] - data[k]) / std::abs(data[k]);
  return n ? sum / n : std::numeric_limits<double>::quiet_NaN();
}

bool mean_curve(const std::vector<Curve>& curves, const std::vector<double>& grid,
                std::vector<double>* mean, std::string* error) {
  mean->assign(grid.size(), 0.0);
  for (size_t c = 0; c < curves.size(); ++c) {
    const Curve& cv = curves[c];
    if (cv.empty() || cv.back().displacement < grid.back() * (1 - 1e-9)) {
      *error = "curve " + std::to_string(c + 1) + " ends at " +
               fmt(cv.empty() ? 0 : cv.back().displacement * 1e3) + " mm, before " +
               fmt(grid.back() * 1e3) + " mm";
      return false;
    }
    size_t j = 1;
    for (size_t k = 0; k < grid.size(); ++k) {
      while (j + 1 < cv.size() && cv[j].displacement < grid[k]) ++j;
      const CurvePoint &a = cv[j - 1], &b = cv[j];
      const double t = b.displacement > a.displacement
                           ? (grid[k] - a.displacement) / (b.displacement - a.displacement)
                           : 1.0;
      (*mean)[k] += (a.force + std::clamp(t, 0.0, 1.0) * (b.force - a.force)) / curves.size();
    }
  }
  return true;
}

std::vector<int> card_families(int cards) {
  if (cards == 2) return {kEdge, kFaceDiagonal | kBodyDiagonal};
  if (cards == 3) return {kEdge, kFaceDiagonal, kBodyDiagonal};
  return {kAllFamilies};
}

std::string families_name(int f) {
  switch (f) {
    case kEdge:
      return "edges";
    case kFaceDiagonal:
      return "face-diagonals";
    case kBodyDiagonal:
      return "body-diagonals";
    case kFaceDiagonal | kBodyDiagonal:
      return "diagonals";
    case kAllFamilies:
      return "all";
    default:
      return "families-" + std::to_string(f);
  }
}

LatticeModuli lattice_moduli(const std::vector<SpringGroupSpec>& groups) {
  LatticeModuli m;
  double ee = 0, ef = 0, eb = 0;  // family moduli E_c = K0 / L0 (first group wins, as in build)
  int taken = 0;
  for (const SpringGroupSpec& g : groups) {
    if (!g.regions.empty() || g.axis.norm() > 0) {
      m.c11 = m.c12 = m.c44 = m.young = m.poisson = m.anisotropy = std::nan("");
      return m;
    }
    // modulus at rest: K0, or k_t(delta0) for a pre-compressed card
    const double e = (g.card.law == LawKind::kConical ? ConicalLaw(g.card.conical).rest_stiffness()
                                                      : g.card.k0()) /
                     g.card.free_length();
    const int f = g.families & ~taken;
    if (f & kEdge) ee = e;
    if (f & kFaceDiagonal) ef = e;
    if (f & kBodyDiagonal) eb = e;
    taken |= g.families;
  }
  m.c11 = (4 * ee + 2 * ef + 4.0 / 9 * eb) / 28;
  m.c12 = m.c44 = (ef + 4.0 / 9 * eb) / 28;
  m.young = (m.c11 - m.c12) * (m.c11 + 2 * m.c12) / (m.c11 + m.c12);
  m.poisson = m.c12 / (m.c11 + m.c12);
  m.anisotropy = 2 * m.c44 / (m.c11 - m.c12);
  return m;
}

double lattice_shear(const LatticeModuli& m) { return (m.c11 - m.c12 + 3 * m.c44) / 5; }

double body_poisson(const LatticeModuli& m, double kappa, double mu) {
  const double K = (m.c11 + 2 * m.c12) / 3 + kappa, G = lattice_shear(m) + mu;
  return (3 * K - 2 * G) / (2 * (3 * K + G));
}

double bulk_for_poisson(const LatticeModuli& m, double nu, double mu) {
  const double G = lattice_shear(m) + mu;
  const double K = 2 * G * (1 + nu) / (3 * (1 - 2 * nu));
  return std::max(0.0, K - (m.c11 + 2 * m.c12) / 3);
}

std::vector<SpringGroupSpec> split_groups(const BodySpec& spec,
                                          const std::vector<ConicalCard>& cards,
                                          std::string* error) {
  std::vector<SpringGroupSpec> out;
  const std::vector<int> fam = card_families(static_cast<int>(cards.size()));
  bool done = false;
  for (const SpringGroupSpec& g : spec.groups) {
    if (done || g.card.law != LawKind::kConical) {
      out.push_back(g);
      continue;
    }
    done = true;
    for (size_t c = 0; c < cards.size(); ++c) {
      SpringGroupSpec part = g;
      part.families = g.families & fam[c];
      if (part.families == 0) {
        if (error) *error = "group \"" + g.name + "\" has no " + families_name(fam[c]);
        return {};
      }
      if (cards.size() > 1) part.name = g.name + "-" + families_name(fam[c]);
      part.card.conical = cards[c];
      out.push_back(part);
    }
  }
  return out;
}

std::vector<double> surrogate_force(const BodySpec& spec,
                                    const std::vector<SpringGroupSpec>& groups,
                                    const std::vector<double>& grid) {
  Model m;
  if (!build_model(spec, &m).empty() || m.planes.empty())
    return std::vector<double>(grid.size(), std::numeric_limits<double>::quiet_NaN());
  return surrogate_impl(groups, spec.mapping, {plate_height(m), cross_section(m)}, grid,
                        spec.bulk_modulus, spec.shear_modulus);
}

std::vector<double> surrogate_force(const BodySpec& spec, const ConicalCard& card,
                                    const std::vector<double>& grid) {
  std::vector<SpringGroupSpec> groups = spec.groups;
  for (auto& g : groups)
    if (g.card.law == LawKind::kConical) g.card.conical = card;
  return surrogate_force(spec, groups, grid);
}

FitResult calibrate(const BodySpec& spec, const std::vector<Curve>& curves, const FitOptions& o) {
  FitResult r;
  auto say = [&](const std::string& s) {
    if (o.progress) o.progress(s);
  };
  const SpringGroupSpec* conical = nullptr;
  for (const auto& g : spec.groups)
    if (g.card.law == LawKind::kConical && !conical) conical = &g;
  if (!conical) {
    r.error = "the scene has no conical spring group to fit";
    return r;
  }
  if (spec.mapping != Mapping::kStrain) {
    r.error = "calibration needs the strain mapping (a raw-mapped body depends on resolution)";
    return r;
  }
  if (curves.empty() || o.points < 4 || !(o.max_strain > 0 && o.max_strain < 1)) {
    r.error = "need at least one curve, points >= 4 and 0 < max_strain < 1";
    return r;
  }
  if (o.cards < 1 || o.cards > 3) {
    r.error = "cards must be 1, 2 or 3";
    return r;
  }
  const int K = o.cards;
  const ConicalCard base = conical->card.conical;
  if (std::string e; split_groups(spec, std::vector<ConicalCard>(K, base), &e).empty()) {
    r.error = e;
    return r;
  }
  Model body;
  if (std::string e = build_model(spec, &body); !e.empty() || body.planes.empty()) {
    r.error = e.empty() ? "the scene has no plate" : e;
    return r;
  }
  const BodyGeometry geo{plate_height(body), cross_section(body)};
  say("body: height " + fmt(geo.height * 1e3) + " mm, cross-section " + fmt(geo.area * 1e6) +
      " mm^2, " + std::to_string(body.num_nodes()) + " nodes, " +
      std::to_string(body.num_springs()) + " springs; " + std::to_string(K) + " card(s)" +
      (K > 1 && o.tie_taper ? ", one shared taper" : ""));

  // Common grid and the mean measured curve.
  const int n = o.points;
  r.grid.resize(n);
  for (int k = 0; k < n; ++k) r.grid[k] = o.max_strain * geo.height * (k + 1) / n;
  if (!mean_curve(curves, r.grid, &r.data, &r.error)) return r;
  r.first = 0;
  while (r.first < n && r.grid[r.first] < o.skip_strain * geo.height * (1 - 1e-12)) ++r.first;
  if (n - r.first < 4) {
    r.error = "fewer than 4 grid points above skip_strain";
    return r;
  }
  for (int k = r.first; k < n; ++k)
    if (!(r.data[k] > 0)) {
      r.error = "measured force <= 0 at " + fmt(r.grid[k] * 1e3) + " mm";
      return r;
    }
  if (o.column_floor) {
    std::vector<double> strain(n);
    for (int k = 0; k < n; ++k) strain[k] = r.grid[k] / geo.height;
    r.floor = column_floor(strain, r.data, r.first, geo.area, o.bounds);
    r.floor_precompressed = column_floor(strain, r.data, r.first, geo.area, o.bounds, true);
    for (const ColumnFloor* f : {&r.floor, &r.floor_precompressed}) {
      say(std::string("column floor") + (f == &r.floor ? "" : ", pre-compressed laws too") +
          ": the best sum of conical laws in parallel along the load (none past its stroke) has "
          "average relative error " +
          fmt(100 * f->error, 4) + " % (" + std::to_string(f->shapes.size()) +
          " laws: " + shapes_text(f->shapes) + ")");
    }
  }
  say("data: " + std::to_string(curves.size()) + " curve(s) averaged on " + std::to_string(n) +
      " points up to " + fmt(r.grid.back() * 1e3) + " mm (strain " + fmt(o.max_strain) +
      "), error over points from " + fmt(r.grid[r.first] * 1e3) +
      " mm (strain >= " + fmt(o.skip_strain) + ")");

  auto groups_for = [&](const std::vector<ConicalCard>& cards) {
    return split_groups(spec, cards);
  };
  // Volume stiffness: the scene's Poisson ratio (or the asked one) kept as the cards change, so
  // that kappa scales with the spring moduli and forces stay proportional to a common factor.
  const LatticeModuli scene_moduli = lattice_moduli(spec.groups);
  const double shear_ratio = spec.shear_modulus / lattice_shear(scene_moduli);
  auto shear_for = [&](const std::vector<SpringGroupSpec>& groups) {
    return spec.shear_modulus > 0 ? shear_ratio * lattice_shear(lattice_moduli(groups)) : 0.0;
  };
  const bool with_volume = o.poisson >= 0 || spec.bulk_modulus > 0;
  const double scene_nu = o.poisson >= 0
                              ? o.poisson
                              : body_poisson(scene_moduli, spec.bulk_modulus, spec.shear_modulus);
  if (with_volume && !(scene_nu < 0.5)) {
    r.error = "Poisson ratio must be < 0.5 (got " + fmt(scene_nu) + ")";
    return r;
  }
  // The body's Poisson ratio: the scene's (or the asked one) until the full-body grid picks one.
  double nu = scene_nu;
  auto bulk_for = [&](const std::vector<SpringGroupSpec>& groups, double ratio) {
    return with_volume ? bulk_for_poisson(lattice_moduli(groups), ratio, shear_for(groups)) : 0.0;
  };
  const double spread_ratio = spec.bulk_modulus > 0 ? spec.spread_modulus / spec.bulk_modulus : 0.0;
  // The element terms of a body with `groups` as its springs (BodySpec fields).
  struct ElementModuli {
    double bulk, spread, shear;
  };
  auto element_moduli = [&](const std::vector<SpringGroupSpec>& groups, double ratio) {
    const double bulk = bulk_for(groups, ratio);
    return ElementModuli{bulk, spread_ratio * bulk, shear_for(groups)};
  };
  if (with_volume)
    say("volume stiffness: Poisson ratio " + fmt(nu, 4) +
        " kept while fitting (bulk modulus at "
        "the scene's card " +
        fmt(bulk_for(spec.groups, nu), 5) + " Pa)");
  auto surrogate = [&](const std::vector<ConicalCard>& cards) {
    ++r.evaluations;
    const std::vector<SpringGroupSpec> groups = groups_for(cards);
    const ElementModuli em = element_moduli(groups, nu);
    return surrogate_impl(groups, spec.mapping, geo, r.grid, em.bulk, em.shear);
  };
  // Best common scale of the moduli: at fixed tapers and strokes, forces are proportional to a
  // common factor on every E_c.
  auto best_scale = [&](const std::vector<double>& f) {
    double a = 0, b = 0;
    for (int k = r.first; k < n; ++k) {
      const double q = f[k] / r.data[k];
      if (!std::isfinite(q)) return 0.0;
      a += q;
      b += q * q;
    }
    return b > 0 ? a / b : 0.0;
  };
  // Error of shapes with the moduli scaled in closed form (shapes updated).
  auto scaled_error = [&](std::vector<CardShape>* sh) {
    const std::vector<ConicalCard> cards = cards_of(base, *sh);
    for (const ConicalCard& c : cards)
      if (!validate(c).empty()) return std::numeric_limits<double>::infinity();
    std::vector<double> f = surrogate(cards);
    const double scale = best_scale(f);
    if (!(scale > 0)) return std::numeric_limits<double>::infinity();
    for (double& v : f) v *= scale;
    for (CardShape& s : *sh) s.modulus *= scale;
    return average_relative_error(f, r.data, r.first);
  };

  const ShapeBounds& B = o.bounds;
  // Stroke bounds per card: a family's springs must not reach their stroke (the hard stop) in
  // the fitted range; their compressive strain is at most the body's for edges, half of it for
  // face diagonals and a third for body diagonals (lateral expansion only lowers them).
  std::vector<double> smin(K);
  for (int c = 0; c < K; ++c) {
    const int f = card_families(K)[c];
    const double share = (f & kEdge) ? 1.0 : (f & kFaceDiagonal) ? 0.5 : 1.0 / 3;
    smin[c] = std::min(B.stroke_max * 0.99, std::max(B.stroke_min, 1.02 * share * o.max_strain));
  }

  // 1. One card: grid search over (taper, stroke[, pre-compression]), modulus in closed form,
  // then LM. Pre-compressions on the grid: fractions of the largest the stroke allows.
  const bool pre = o.fit_precompression;
  CardShape best{1e4, 0.25, 0.9}, best_plain = best;
  double best_err = std::numeric_limits<double>::infinity(), best_plain_err = best_err;
  const int nt = 8, ns = 9, np = pre ? 6 : 1;
  const Layout L1{1, false, B, {smin[0]}, false, pre};
  for (int i = 0; i < nt; ++i)
    for (int j = 0; j < ns; ++j)
      for (int q = 0; q < np; ++q) {
        std::vector<CardShape> sh(K);
        sh[0].modulus = 1e4;
        sh[0].taper = B.taper_min + (B.taper_max - B.taper_min) * (i + 0.5) / nt;
        sh[0].stroke = smin[0] + (B.stroke_max - smin[0]) * (j + 1.0) / ns;
        sh[0].precompression = L1.pre_max(0, sh[0].stroke) * q / np;
        for (int c = 1; c < K; ++c) sh[c] = sh[0];
        const double e = scaled_error(&sh);
        if (e < best_err) {
          best_err = e;
          best = sh[0];
        }
        if (q == 0 && e < best_plain_err) {
          best_plain_err = e;
          best_plain = sh[0];
        }
      }
  say("grid search (" + std::to_string(nt * ns * np) + " shapes, one card): start " +
      shapes_text({best}) + ", average relative error " + fmt(100 * best_err, 4) + " %");

  const int R = n - r.first;
  RelativeResiduals res;
  res.model = surrogate;
  res.base = base;
  res.data = &r.data;
  res.first = r.first;
  res.layout = L1;
  std::vector<double> x1 = encode({best}, L1);
  solve_lm(res, R, o.max_iterations, true, 1e-6, o, "surrogate LM (one card)", x1.data());
  const CardShape one = decode(x1.data(), L1)[0];

  // 2. K cards: starts from the one-card optimum, LM from the best few.
  struct Candidate {
    std::vector<CardShape> shapes;
    double surrogate_error = 0;
  };
  std::vector<Candidate> found;
  if (K == 1) {
    found.push_back({{one}, 0});
    if (pre) {
      // The plain optimum too: its body may hold up better than the pre-compressed one's (the
      // full body is checked at both, below).
      const Layout L0p{1, false, B, {smin[0]}, false, false};
      res.layout = L0p;
      std::vector<double> x0 = encode({best_plain}, L0p);
      solve_lm(res, R, o.max_iterations, true, 1e-6, o, "surrogate LM (one card, plain law)",
               x0.data());
      const CardShape plain = decode(x0.data(), L0p)[0];
      found.push_back(
          {{plain}, average_relative_error(surrogate(cards_of(base, {plain})), r.data, r.first)});
      found[0].surrogate_error =
          average_relative_error(surrogate(cards_of(base, {one})), r.data, r.first);
      res.layout = L1;
    }
  } else {
    Layout L{K, o.tie_taper, B, smin, o.isotropic, pre};
    res.layout = L;
    std::vector<Candidate> starts;
    auto add_start = [&](std::vector<CardShape> sh) {
      const double e = scaled_error(&sh);
      if (std::isfinite(e)) starts.push_back({sh, e});
    };
    if (!o.isotropic) add_start(std::vector<CardShape>(K, one));  // the one-card body itself
    // Diagonal cards: modulus relative to the edges' (36/17: isotropic) and stroke on a grid;
    // the edges keep the one-card shape.
    std::vector<double> ratios = {0.5, 1.0, 36.0 / 17, 5.0};
    if (o.isotropic)
      ratios = K == 2 ? std::vector<double>{36.0 / 17} : std::vector<double>{0.1, 0.4, 0.7};
    for (double ratio : ratios)
      for (double stroke : {0.25, 0.4, 0.6, 0.8})
        for (double taper : {one.taper, 0.3}) {
          std::vector<CardShape> sh(K, one);
          for (int c = 1; c < K; ++c) {
            sh[c].modulus = ratio * one.modulus;
            if (o.isotropic && K == 3)  // ratio is the body-diagonal weight w
              sh[c].modulus = (c == 1 ? 4 * (1 - ratio) : 4.5 * ratio) * one.modulus;
            sh[c].stroke = std::clamp(stroke, smin[c], B.stroke_max);
            sh[c].taper = o.tie_taper ? one.taper : std::clamp(taper, B.taper_min, B.taper_max);
          }
          // the edges stiffen later when the diagonals take part of the stiffening
          for (double edge_stroke : {one.stroke, std::min(B.stroke_max, one.stroke * 1.15)}) {
            sh[0].stroke = edge_stroke;
            for (int c = 0; c < K; ++c)  // the stroke left must still cover the card's strain
              sh[c].precompression = std::min(one.precompression, L.pre_max(c, sh[c].stroke));
            add_start(sh);
          }
        }
    std::sort(starts.begin(), starts.end(), [](const Candidate& a, const Candidate& b) {
      return a.surrogate_error < b.surrogate_error;
    });
    say("starts: " + std::to_string(starts.size()) + " shapes, best " +
        fmt(100 * starts.front().surrogate_error, 4) + " %");
    const int tries = std::min<int>(4, static_cast<int>(starts.size()));
    for (int t = 0; t < tries; ++t) {
      std::vector<double> x = encode(starts[t].shapes, L);
      solve_lm(
          res, R, o.max_iterations, true, 1e-6, o,
          "surrogate LM (" + std::to_string(K) + " cards, start " + std::to_string(t + 1) + ")",
          x.data());
      const std::vector<CardShape> sh = decode(x.data(), L);
      found.push_back({sh, average_relative_error(surrogate(cards_of(base, sh)), r.data, r.first)});
    }
    // The one-card body as a candidate too (the cards may not help in the full body).
    if (!o.isotropic)
      found.push_back(
          {std::vector<CardShape>(K, one),
           average_relative_error(surrogate(cards_of(base, std::vector<CardShape>(K, one))), r.data,
                                  r.first)});
    std::stable_sort(found.begin(), found.end(), [](const Candidate& a, const Candidate& b) {
      return a.surrogate_error < b.surrogate_error;
    });
  }

  auto set_result = [&](const std::vector<CardShape>& sh) {
    r.shapes = sh;
    r.cards = cards_of(base, sh);
    r.shape = sh[0];
    r.card = r.cards[0];
    r.groups = groups_for(r.cards);
    r.moduli = lattice_moduli(r.groups);
    const ElementModuli em = element_moduli(r.groups, nu);
    r.bulk_modulus = em.bulk;
    r.spread_modulus = em.spread;
    r.shear_modulus = em.shear;
    r.poisson = body_poisson(r.moduli, r.bulk_modulus, r.shear_modulus);
    r.surrogate = surrogate(r.cards);
    r.surrogate_error = average_relative_error(r.surrogate, r.data, r.first);
  };
  set_result(found.front().shapes);
  r.surrogate_error_before_refine = r.surrogate_error;
  say("surrogate fit: average relative error " + fmt(100 * r.surrogate_error, 4) +
      " %: " + shapes_text(r.shapes));
  if (o.full_iterations < 0) return r;

  // 3. The full body: verify (K > 1: the best few distinct optima), then refine through it.
  // The full body's force on the grid at Poisson ratio `ratio`, and how far it left the
  // homogeneous state (layer spread over half width at the end of the travel). Touches nothing
  // shared: the grid below runs it on several threads.
  struct FullRun {
    std::vector<double> force;
    double spread = 0;
  };
  auto full_at = [&](const std::vector<ConicalCard>& cards, double ratio) {
    BodySpec s = spec;
    s.groups = groups_for(cards);
    const ElementModuli em = element_moduli(s.groups, ratio);
    s.bulk_modulus = em.bulk;
    s.spread_modulus = em.spread;
    s.shear_modulus = em.shear;
    Model m;
    FullRun run{std::vector<double>(n, std::nan("")), 0};
    if (s.groups.empty() || !build_model(s, &m).empty()) return run;
    CompressionStats st;
    const Curve c = compression_curve(m, o.rate, o.max_strain, n, &st);
    for (int k = 0; k < n; ++k) run.force[k] = c[k + 1].force;
    run.spread = st.half_width > 0 ? st.layer_spread / st.half_width : 0;
    return run;
  };
  // A body that left the homogeneous state (options.max_layer_spread) gives no curve (NaN): the
  // fit must not owe its shape to a buckle.
  auto even = [&](const FullRun& run) { return run.spread <= o.max_layer_spread; };
  auto accepted = [&](FullRun run) {
    if (!even(run)) std::fill(run.force.begin(), run.force.end(), std::nan(""));
    return run.force;
  };
  auto full = [&](const std::vector<ConicalCard>& cards) {
    ++r.full_evaluations;
    return accepted(full_at(cards, nu));
  };
  double best_full = std::numeric_limits<double>::infinity();
  std::vector<CardShape> best_shapes = found.front().shapes;
  std::vector<double> best_curve;
  const int verify =
      K == 1 ? static_cast<int>(found.size())
             : std::min<int>(std::max(1, o.verify_candidates), static_cast<int>(found.size()));
  for (int c = 0; c < verify; ++c) {
    const std::vector<double> f = full(cards_of(base, found[c].shapes));
    const double e = average_relative_error(f, r.data, r.first);
    say("full body at surrogate optimum " + std::to_string(c + 1) + " (surrogate " +
        fmt(100 * found[c].surrogate_error, 4) + " %): average relative error " + fmt(100 * e, 4) +
        " %");
    if (e < best_full) {
      best_full = e;
      best_shapes = found[c].shapes;
      best_curve = f;
    }
  }
  // Full-body grid (one card): forces scale with the modulus at fixed shape and Poisson ratio
  // (the volume stiffness and the plate's penalty scale with it), so each shape takes the best
  // modulus in closed form; the best is compressed again at that modulus. With volume stiffness
  // and the scene's Poisson ratio (no `poisson` asked) the grid also spans Poisson ratios from
  // poisson_min up to the scene's. The runs are independent and share out over threads.
  if (K == 1 && o.full_grid > 0) {
    const int g = o.full_grid;
    const int gp = pre ? std::max(1, o.full_grid_pre) : 1;
    const int gn = with_volume && o.poisson < 0 && o.poisson_min < scene_nu
                       ? std::max(1, o.full_grid_poisson)
                       : 1;
    struct GridPoint {
      CardShape shape;
      double nu = 0;
      FullRun run;
    };
    std::vector<GridPoint> points;
    for (int k = 0; k < g * g * gp * gn; ++k) {
      // Poisson ratio outermost (the scene's first), then taper, stroke, pre-compression.
      const int in = k / (g * g * gp), it = k / (g * gp) % g, is = k / gp % g, ip = k % gp;
      CardShape sh = best_shapes[0];
      sh.taper = B.taper_min + (B.taper_max - B.taper_min) * (it + 0.5) / g;
      sh.stroke = smin[0] + (B.stroke_max - smin[0]) * (is + 0.5) / g;
      sh.precompression = ip * L1.pre_max(0, sh.stroke) / gp;
      std::vector<CardShape> one_shape{sh};
      if (!std::isfinite(scaled_error(&one_shape))) continue;  // modulus from the surrogate
      const double ratio =
          gn == 1 ? scene_nu : scene_nu - (scene_nu - o.poisson_min) * in / (gn - 1);
      points.push_back({one_shape[0], ratio, {}});
    }
    parallel_for(static_cast<int>(points.size()), o.threads, [&](int k) {
      points[k].run = full_at(cards_of(base, {points[k].shape}), points[k].nu);
    });
    r.full_evaluations += static_cast<int>(points.size());
    double best_estimate = best_full;
    const GridPoint* grid_best = nullptr;
    for (GridPoint& p : points) {
      std::vector<double>& f = p.run.force;
      const double scale = best_scale(f);
      if (!(scale > 0)) continue;
      for (double& v : f) v *= scale;
      const double e = average_relative_error(f, r.data, r.first);
      const bool kept = even(p.run);
      p.shape.modulus *= scale;
      say("full-body grid: " + (gn > 1 ? "Poisson " + fmt(p.nu, 3) + ", " : std::string()) +
          "taper " + fmt(p.shape.taper, 3) + ", stroke " + fmt(p.shape.stroke, 3) +
          (p.shape.precompression > 0 ? ", pre-compression " + fmt(p.shape.precompression, 3) + " S"
                                      : std::string()) +
          ": average relative error " + fmt(100 * e, 4) + " % (modulus scaled)" +
          (kept ? std::string()
                : ", rejected: left the homogeneous state (layer spread " +
                      fmt(100 * p.run.spread, 3) + " % of the half width)"));
      if (kept && e < best_estimate) {
        best_estimate = e;
        grid_best = &p;
      }
    }
    if (grid_best) {
      const double nu_before = nu;
      nu = grid_best->nu;
      const std::vector<double> f = full(cards_of(base, {grid_best->shape}));
      const double e = average_relative_error(f, r.data, r.first);
      say("full-body grid best: " + shapes_text({grid_best->shape}) +
          (gn > 1 ? ", Poisson " + fmt(nu, 3) : std::string()) + ", average relative error " +
          fmt(100 * e, 4) + " %");
      if (e < best_full) {
        best_full = e;
        best_shapes = {grid_best->shape};
        best_curve = f;
      } else {
        nu = nu_before;
      }
    }
  }
  if (!std::isfinite(best_full))
    say("no full-body run kept its homogeneous state (layer spread above max_layer_spread) or "
        "finished: the full-body error is not defined for this scene and card family");
  set_result(best_shapes);
  r.surrogate_error_before_refine = r.surrogate_error;
  r.full_error_before_refine = best_full;
  const Layout LK{K, K > 1 && o.tie_taper, B, smin, K > 1 && o.isotropic, pre};

  // 4. Output space mapping: the full body differs from the cell surrogate (boundary cells,
  // the cylinder's distorted cells), by a ratio that depends on the strain and only weakly on
  // the cards. Refit the surrogate times the last full-body / surrogate ratio, rerun the full
  // body there, repeat. One full compression per step.
  if (o.space_mapping > 0 && std::isfinite(best_full)) {
    std::vector<CardShape> xk = best_shapes;
    std::vector<double> fk = best_curve;
    int worse = 0;
    for (int step = 1; step <= o.space_mapping && worse < 2; ++step) {
      const std::vector<double> sk = surrogate(cards_of(base, xk));
      std::vector<double> ratio(n, 1.0);
      bool ok = true;
      for (int k = r.first; k < n; ++k) {
        ratio[k] = fk[k] / sk[k];
        ok &= std::isfinite(ratio[k]) && ratio[k] > 0;
      }
      if (!ok) {
        say("space mapping step " + std::to_string(step) +
            ": full body and surrogate not comparable (collapse or NaN), stopped");
        break;
      }
      RelativeResiduals mres = res;
      mres.layout = LK;
      mres.model = [&surrogate, ratio](const std::vector<ConicalCard>& cards) {
        std::vector<double> f = surrogate(cards);
        for (size_t k = 0; k < f.size(); ++k) f[k] *= ratio[k];
        return f;
      };
      std::vector<double> x = encode(xk, LK);
      solve_lm(mres, R, o.max_iterations, true, 1e-6, {}, "", x.data());
      xk = decode(x.data(), LK);
      fk = full(cards_of(base, xk));
      const double e = average_relative_error(fk, r.data, r.first);
      say("space mapping step " + std::to_string(step) + ": full body " + fmt(100 * e, 4) +
          " % at " + shapes_text(xk));
      if (e < best_full) {
        best_full = e;
        best_shapes = xk;
        best_curve = fk;
        worse = 0;
      } else {
        ++worse;
      }
    }
    r.full_error_after_mapping = best_full;
  }
  set_result(best_shapes);
  r.surrogate_error_before_refine = r.surrogate_error;
  r.full = best_curve;
  r.full_error = best_full;
  if (o.full_iterations == 0) return r;
  RelativeResiduals fres = res;
  fres.layout = LK;
  fres.model = full;
  std::vector<double> x = encode(best_shapes, fres.layout);
  solve_lm(fres, R, o.full_iterations, false, 1e-4, o, "full-body LM", x.data());
  const std::vector<CardShape> refined = decode(x.data(), fres.layout);
  const std::vector<double> rf = full(cards_of(base, refined));
  const double re = average_relative_error(rf, r.data, r.first);
  if (re < r.full_error) {
    set_result(refined);
    r.full = rf;
    r.full_error = re;
  }
  say("full body refined: average relative error " + fmt(100 * r.full_error, 4) + " %");
  return r;
}

std::string card_fragment(const std::string& group_name, const SpringCard& card) {
  std::ostringstream os;
  const ConicalCard& c = card.conical;
  os << "group {\n  name: \"" << group_name << "\"\n  card {\n"
     << "    conical { G: " << fmt(c.G, 9) << " d: " << fmt(c.d, 9) << " D1: " << fmt(c.D1, 9)
     << " D2: " << fmt(c.D2, 9) << " L0: " << fmt(c.L0, 9) << " n_a: " << fmt(c.n_a, 9);
  if (c.precompression > 0) os << " precompression: " << fmt(c.precompression, 9);
  os << " }\n"
     << "    stiffness_cap: " << fmt(card.stiffness_cap, 9) << "\n";
  if (card.damping > 0) os << "    damping: " << fmt(card.damping, 9) << "\n";
  if (card.maxwell_k > 0)
    os << "    maxwell_k: " << fmt(card.maxwell_k, 9)
       << "\n    maxwell_tau: " << fmt(card.maxwell_tau, 9) << "\n";
  os << "  }\n}\n";
  return os.str();
}

}  // namespace conica::lab

namespace conica::lab {

std::string group_fragment(const SpringGroupSpec& g) {
  std::string f = card_fragment(g.name, g.card);
  f.resize(f.size() - 2);  // drop the closing "}\n"
  if (g.families != kAllFamilies) {
    std::string list;
    if (g.families & kEdge) list += "EDGE";
    if (g.families & kFaceDiagonal) list += std::string(list.empty() ? "" : ", ") + "FACE_DIAGONAL";
    if (g.families & kBodyDiagonal) list += std::string(list.empty() ? "" : ", ") + "BODY_DIAGONAL";
    f += "  families: [" + list + "]\n";
  }
  for (const std::string& reg : g.regions) f += "  regions: \"" + reg + "\"\n";
  if (g.axis.norm() > 0)
    f += "  axis { x: " + fmt(g.axis.x(), 9) + " y: " + fmt(g.axis.y(), 9) +
         " z: " + fmt(g.axis.z(), 9) + " }\n  max_angle_deg: " + fmt(g.max_angle_deg, 9) + "\n";
  return f + "}\n";
}

}  // namespace conica::lab
