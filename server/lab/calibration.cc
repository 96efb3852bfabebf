#include "lab/calibration.h"

#include <ceres/ceres.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>

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

// Unconstrained coordinates of a shape: (ln E_c, logit of taper in its bounds, logit of stroke).
CardShape decode(const double* x, const ShapeBounds& b) {
  CardShape s;
  s.modulus = std::exp(x[0]);
  s.taper = b.taper_min + (b.taper_max - b.taper_min) * sigmoid(x[1]);
  s.stroke = b.stroke_min + (b.stroke_max - b.stroke_min) * sigmoid(x[2]);
  return s;
}
void encode(const CardShape& s, const ShapeBounds& b, double* x) {
  auto inside = [](double p) { return std::clamp(p, 1e-6, 1 - 1e-6); };
  x[0] = std::log(s.modulus);
  x[1] = logit(inside((s.taper - b.taper_min) / (b.taper_max - b.taper_min)));
  x[2] = logit(inside((s.stroke - b.stroke_min) / (b.stroke_max - b.stroke_min)));
}

std::vector<SpringGroupSpec> with_card(const std::vector<SpringGroupSpec>& groups,
                                       const ConicalCard& card) {
  std::vector<SpringGroupSpec> out = groups;
  for (auto& g : out)
    if (g.card.law == LawKind::kConical) g.card.conical = card;
  return out;
}

struct BodyGeometry {
  double height = 0;  // m, along the plate normal
  double area = 0;    // m^2
};

std::vector<double> surrogate_impl(const std::vector<SpringGroupSpec>& groups, Mapping mapping,
                                   const BodyGeometry& geo, const ConicalCard& card,
                                   const std::vector<double>& grid) {
  Model cell;
  if (!make_uniaxial_cell(with_card(groups, card), mapping, 0.01, &cell).empty())
    return std::vector<double>(grid.size(), std::numeric_limits<double>::quiet_NaN());
  std::vector<double> strains(grid.size());
  for (size_t k = 0; k < grid.size(); ++k) strains[k] = grid[k] / geo.height;
  std::vector<double> f = cell_stress_curve(cell, strains);
  for (double& v : f) v *= geo.area;
  return f;
}

// Residuals (model - data) / data over grid indices >= first, for Ceres.
struct RelativeResiduals {
  std::function<std::vector<double>(const ConicalCard&)> model;
  ConicalCard base;
  ShapeBounds bounds;
  const std::vector<double>* data = nullptr;
  int first = 0;
  int* evaluations = nullptr;

  bool operator()(double const* const* x, double* r) const {
    const ConicalCard card = card_with_shape(base, decode(x[0], bounds));
    if (!validate(card).empty()) return false;
    const std::vector<double> f = model(card);
    ++*evaluations;
    for (size_t k = first; k < data->size(); ++k) {
      if (!std::isfinite(f[k])) return false;
      r[k - first] = (f[k] - (*data)[k]) / (*data)[k];
    }
    return true;
  }
};

class Progress : public ceres::IterationCallback {
 public:
  Progress(const FitOptions& o, std::string stage, int n, const double* x, const ShapeBounds& b)
      : o_(o), stage_(std::move(stage)), n_(n), x_(x), b_(b) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    if (o_.progress) {
      const CardShape sh = decode(x_, b_);
      o_.progress(stage_ + " iteration " + std::to_string(s.iteration) + ": rms relative error " +
                  fmt(100 * std::sqrt(2 * s.cost / n_), 4) + " %, E_c " + fmt(sh.modulus, 5) +
                  " Pa, taper " + fmt(sh.taper, 4) + ", stroke " + fmt(sh.stroke, 4) +
                  (s.step_is_successful ? "" : " (step rejected)"));
    }
    return ceres::SOLVER_CONTINUE;
  }

 private:
  const FitOptions& o_;
  std::string stage_;
  int n_;
  const double* x_;
  ShapeBounds b_;
};

// Levenberg-Marquardt from x (updated in place).
void solve_lm(RelativeResiduals res, int num_residuals, int iterations, bool central,
              double relative_step, const FitOptions& o, const std::string& stage, double* x) {
  ceres::Problem problem;
  ceres::NumericDiffOptions nd;
  nd.relative_step_size = relative_step;
  ceres::DynamicCostFunction* cost;
  if (central) {
    auto* c = new ceres::DynamicNumericDiffCostFunction<RelativeResiduals, ceres::CENTRAL>(
        new RelativeResiduals(std::move(res)), ceres::TAKE_OWNERSHIP, nd);
    cost = c;
  } else {
    auto* c = new ceres::DynamicNumericDiffCostFunction<RelativeResiduals, ceres::FORWARD>(
        new RelativeResiduals(std::move(res)), ceres::TAKE_OWNERSHIP, nd);
    cost = c;
  }
  cost->AddParameterBlock(3);
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
  Progress cb(o, stage, num_residuals, x, o.bounds);
  so.callbacks.push_back(&cb);
  so.update_state_every_iteration = true;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  if (o.progress)
    o.progress(stage + ": " + summary.message + " (" + std::to_string(summary.iterations.size()) +
               " iterations)");
}

}  // namespace

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
  return {law.k0() / card.L0, card.D1 / card.D2, law.stroke() / card.L0};
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

std::vector<double> surrogate_force(const BodySpec& spec, const ConicalCard& card,
                                    const std::vector<double>& grid) {
  Model m;
  if (!build_model(spec, &m).empty() || m.planes.empty())
    return std::vector<double>(grid.size(), std::numeric_limits<double>::quiet_NaN());
  return surrogate_impl(spec.groups, spec.mapping, {plate_height(m), cross_section(m)}, card, grid);
}

FitResult calibrate(const BodySpec& spec, const std::vector<Curve>& curves,
                    const FitOptions& o) {
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
  Model body;
  if (std::string e = build_model(spec, &body); !e.empty() || body.planes.empty()) {
    r.error = e.empty() ? "the scene has no plate" : e;
    return r;
  }
  const BodyGeometry geo{plate_height(body), cross_section(body)};
  const ConicalCard base = conical->card.conical;
  say("body: height " + fmt(geo.height * 1e3) + " mm, cross-section " + fmt(geo.area * 1e6) +
      " mm^2, " + std::to_string(body.num_nodes()) + " nodes, " +
      std::to_string(body.num_springs()) + " springs");

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
  say("data: " + std::to_string(curves.size()) + " curve(s) averaged on " + std::to_string(n) +
      " points up to " + fmt(r.grid.back() * 1e3) + " mm (strain " + fmt(o.max_strain) +
      "), error over points from " + fmt(r.grid[r.first] * 1e3) + " mm (strain >= " +
      fmt(o.skip_strain) + ")");

  auto surrogate = [&](const ConicalCard& card) {
    ++r.evaluations;
    return surrogate_impl(spec.groups, spec.mapping, geo, card, r.grid);
  };
  // Best modulus for given curve shape: forces are proportional to E_c at fixed (taper, stroke).
  auto best_scale = [&](const std::vector<double>& f) {
    double a = 0, b = 0;
    for (int k = r.first; k < n; ++k) {
      const double q = f[k] / r.data[k];
      a += q;
      b += q * q;
    }
    return b > 0 ? a / b : 0.0;
  };

  // 1. Grid search over (taper, stroke), modulus in closed form.
  const ShapeBounds& B = o.bounds;
  CardShape best{1e4, 0.25, 0.9};
  double best_err = std::numeric_limits<double>::infinity();
  const int nt = 8, ns = 9;
  for (int i = 0; i < nt; ++i)
    for (int j = 0; j < ns; ++j) {
      CardShape sh;
      sh.modulus = 1e4;
      sh.taper = B.taper_min + (B.taper_max - B.taper_min) * (i + 0.5) / nt;
      sh.stroke = B.stroke_min + (B.stroke_max - B.stroke_min) * (j + 1.0) / ns;
      const ConicalCard c = card_with_shape(base, sh);
      if (!validate(c).empty()) continue;
      std::vector<double> f = surrogate(c);
      const double scale = best_scale(f);
      if (!(scale > 0)) continue;
      for (double& v : f) v *= scale;
      sh.modulus *= scale;
      const double e = average_relative_error(f, r.data, r.first);
      if (e < best_err) {
        best_err = e;
        best = sh;
      }
    }
  say("grid search (" + std::to_string(nt * ns) + " shapes): start E_c " + fmt(best.modulus, 5) +
      " Pa, taper " + fmt(best.taper, 4) + ", stroke " + fmt(best.stroke, 4) +
      ", average relative error " + fmt(100 * best_err, 4) + " %");

  // 2. Levenberg-Marquardt on the surrogate.
  double x[3];
  encode(best, B, x);
  RelativeResiduals res;
  res.model = surrogate;
  res.base = base;
  res.bounds = B;
  res.data = &r.data;
  res.first = r.first;
  int lm_calls = 0;  // evaluations are counted in `surrogate` / `full`
  res.evaluations = &lm_calls;
  solve_lm(res, n - r.first, o.max_iterations, true, 1e-6, o, "surrogate LM", x);
  r.shape = decode(x, B);
  r.card = card_with_shape(base, r.shape);
  r.surrogate = surrogate(r.card);
  r.surrogate_error = r.surrogate_error_before_refine =
      average_relative_error(r.surrogate, r.data, r.first);
  say("surrogate fit: average relative error " + fmt(100 * r.surrogate_error, 4) + " %");
  if (o.full_iterations < 0) return r;

  // 3. The full body: verify, then refine through it.
  auto full = [&](const ConicalCard& card) {
    BodySpec s = spec;
    s.groups = with_card(spec.groups, card);
    Model m;
    if (!build_model(s, &m).empty()) return std::vector<double>(n, std::nan(""));
    ++r.full_evaluations;
    const Curve c = compression_curve(m, o.rate, o.max_strain, n);
    std::vector<double> f(n);
    for (int k = 0; k < n; ++k) f[k] = c[k + 1].force;
    return f;
  };
  r.full = full(r.card);
  r.full_error = r.full_error_before_refine = average_relative_error(r.full, r.data, r.first);
  say("full body at the surrogate optimum: average relative error " + fmt(100 * r.full_error, 4) +
      " %");
  if (o.full_iterations == 0) return r;
  RelativeResiduals fres = res;
  fres.model = full;
  solve_lm(fres, n - r.first, o.full_iterations, false, 1e-4, o, "full-body LM", x);
  const CardShape refined = decode(x, B);
  const ConicalCard rc = card_with_shape(base, refined);
  const std::vector<double> rf = full(rc);
  const double re = average_relative_error(rf, r.data, r.first);
  if (re < r.full_error) {
    r.shape = refined;
    r.card = rc;
    r.full = rf;
    r.full_error = re;
    r.surrogate = surrogate(rc);
    r.surrogate_error = average_relative_error(r.surrogate, r.data, r.first);
  }
  say("full body refined: average relative error " + fmt(100 * r.full_error, 4) + " %");
  return r;
}

std::string card_fragment(const std::string& group_name, const SpringCard& card) {
  std::ostringstream os;
  const ConicalCard& c = card.conical;
  os << "group {\n  name: \"" << group_name << "\"\n  card {\n"
     << "    conical { G: " << fmt(c.G, 9) << " d: " << fmt(c.d, 9) << " D1: " << fmt(c.D1, 9)
     << " D2: " << fmt(c.D2, 9) << " L0: " << fmt(c.L0, 9) << " n_a: " << fmt(c.n_a, 9) << " }\n"
     << "    stiffness_cap: " << fmt(card.stiffness_cap, 9) << "\n";
  if (card.damping > 0) os << "    damping: " << fmt(card.damping, 9) << "\n";
  if (card.maxwell_k > 0)
    os << "    maxwell_k: " << fmt(card.maxwell_k, 9) << "\n    maxwell_tau: "
       << fmt(card.maxwell_tau, 9) << "\n";
  os << "  }\n}\n";
  return os.str();
}

}  // namespace conica::lab
