// The fitting machinery of the calibration (lab/calibration_stages.h): the card's identifiable
// shape, the lattice's moduli, the surrogate and full-body evaluations the stages count, and
// Levenberg-Marquardt on them.
#include <ceres/ceres.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/stability.h"
#include "lab/calibration.h"
#include "lab/calibration_stages.h"
#include "lab/quasi_static.h"

namespace conica::lab {
namespace detail {
namespace {

double sigmoid(double x) { return 1.0 / (1.0 + std::exp(-x)); }
double logit(double p) { return std::log(p / (1.0 - p)); }
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

}  // namespace

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

std::vector<double> cell_surrogate(const std::vector<SpringGroupSpec>& groups, Mapping mapping,
                                   const BodyGeometry& geo, const std::vector<double>& grid,
                                   double bulk_modulus, double shear_modulus,
                                   double shear_stiffening) {
  Model cell;
  if (!make_uniaxial_cell(groups, mapping, 0.01, &cell, bulk_modulus, shear_modulus,
                          shear_stiffening)
           .empty())
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

bool RelativeResiduals::operator()(double const* const* x, double* r) const {
  const std::vector<ConicalCard> cards = cards_of(base, decode(x[0], layout));
  for (const ConicalCard& c : cards)
    if (!validate(c).empty()) return false;
  const std::vector<double> f = model(cards);
  for (size_t k = first; k < data->size(); ++k) {
    if (!std::isfinite(f[k])) return false;
    r[k - first] = (f[k] - (*data)[k]) / (*data)[k];
    if (!weights.empty()) r[k - first] *= weights[k];
  }
  return true;
}

RelativeResiduals residuals(
    const Problem& problem, const Layout& layout,
    std::function<std::vector<double>(const std::vector<ConicalCard>&)> model) {
  RelativeResiduals res;
  res.model = std::move(model);
  res.base = problem.base;
  res.data = &problem.target.data;
  res.first = problem.target.first;
  res.layout = layout;
  return res;
}

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

std::vector<SpringGroupSpec> Evaluator::groups(const std::vector<ConicalCard>& cards) const {
  return split_groups(p_.spec, cards);
}

// The scene's shear stiffness keeps its ratio to the lattice's shear modulus, raised where the
// material would lose strong ellipticity before options.stability_margin x max_strain (then the
// least shear modulus that keeps it, a root found on the cell; every modulus scaled by a common
// factor scales it too, so forces stay proportional to that factor).
// hint: the last root (0: none), bracketed first and updated; stretch: the cell's lateral
// stretches at the stability strain last solved (the next solve's start), updated.
static double shear_for(const Problem& p, const std::vector<SpringGroupSpec>& groups, double ratio,
                        double* hint, Vec3* stretch) {
  if (!(p.spec.shear_modulus > 0)) return 0.0;
  const LatticeModuli lat = lattice_moduli(groups);
  const double mu0 = p.volume.shear_ratio * lattice_shear(lat);
  const double strain = p.options.stability_margin * p.options.max_strain;
  if (!(strain > 0) || !(strain < 1)) return mu0;
  auto bulk = [&](double mu) {
    return p.volume.with_volume ? bulk_for_poisson(lat, ratio, mu) : 0.0;
  };
  Model cell;
  if (!make_uniaxial_cell(groups, p.spec.mapping, 0.01, &cell, bulk(mu0), mu0,
                          p.spec.shear_stiffening)
           .empty())
    return mu0;
  // The softest wave's modulus at that strain: smooth and increasing in mu. Each solve of the
  // lateral stretches starts from the last one's.
  auto wave = [&](double mu) {
    cell.shear_modulus = mu;
    cell.bulk_modulus = bulk(mu);
    return uniaxial_softest_wave(cell, Vec3::UnitZ(), strain, 10, 400, stretch).modulus;
  };
  double lo = 0, glo = 0, hi = 0, ghi = 0;
  bool bracketed = false;
  if (*hint > mu0) {
    // The modulus rises with mu: a bracket of 1e-3 about the last root, when it holds this one.
    lo = *hint * (1 - 1e-3);
    hi = *hint * (1 + 1e-3);
    if (lo > mu0) {
      glo = wave(lo);
      if (std::isfinite(glo) && !(glo > 0)) {
        ghi = wave(hi);
        bracketed = ghi > 0;
      }
    }
  }
  if (!bracketed) {
    lo = mu0;
    glo = wave(mu0);
    if (glo > 0 || !std::isfinite(glo)) return mu0;
    hi = 2 * mu0;
    ghi = wave(hi);
    for (int k = 0; k < 8 && !(ghi > 0); ++k) {
      lo = hi;
      glo = ghi;
      hi *= 2;
      ghi = wave(hi);
    }
    if (!(ghi > 0) || !std::isfinite(glo)) return hi;  // no shear share keeps it
  }
  // The root of the modulus in mu (Illinois regula falsi), to 1e-10 relative: a smooth function
  // of the cards, as the fit's finite-difference Jacobians need.
  int side = 0;
  for (int it = 0; it < 60 && hi - lo > 1e-10 * hi; ++it) {
    const double mu = (lo * ghi - hi * glo) / (ghi - glo);
    const double g = wave(mu);
    if (!std::isfinite(g)) break;
    if (g > 0) {
      hi = mu;
      ghi = g;
      if (side == 1) glo *= 0.5;
      side = 1;
    } else {
      lo = mu;
      glo = g;
      if (side == -1) ghi *= 0.5;
      side = -1;
    }
    if (std::abs(g) <= 1e-12 * mu) return *hint = mu;
  }
  return *hint = hi;
}

// Volume stiffness: the scene's Poisson ratio (or the asked one) kept as the cards change, so
// that kappa scales with the spring moduli and forces stay proportional to a common factor.
double Evaluator::bulk_for(const std::vector<SpringGroupSpec>& groups, double ratio) const {
  return element_moduli(groups, ratio).bulk;
}

ElementModuli Evaluator::element_moduli(const std::vector<SpringGroupSpec>& groups,
                                        double ratio) const {
  double hint = 0;
  Vec3 stretch = Vec3::Ones();
  return element_moduli(groups, ratio, &hint, &stretch);
}

ElementModuli Evaluator::element_moduli(const std::vector<SpringGroupSpec>& groups, double ratio,
                                        double* shear_hint, Vec3* stretch_hint) const {
  const double shear = shear_for(p_, groups, ratio, shear_hint, stretch_hint);
  const double bulk =
      p_.volume.with_volume ? bulk_for_poisson(lattice_moduli(groups), ratio, shear) : 0.0;
  return ElementModuli{bulk, p_.volume.spread_ratio * bulk, shear};
}

std::vector<double> Evaluator::surrogate(const std::vector<ConicalCard>& cards) {
  ++surrogate_evaluations;
  const std::vector<SpringGroupSpec> g = groups(cards);
  const ElementModuli em = element_moduli(g, nu, &shear_hint_, &stretch_hint_);
  return cell_surrogate(g, p_.spec.mapping, p_.geo, p_.target.grid, em.bulk, em.shear,
                        p_.spec.shear_stiffening);
}

BodySpec Evaluator::body_of(const std::vector<ConicalCard>& cards, double ratio) const {
  BodySpec s = p_.spec;
  s.groups = groups(cards);
  const ElementModuli em = element_moduli(s.groups, ratio);
  s.bulk_modulus = em.bulk;
  s.spread_modulus = em.spread;
  s.shear_modulus = em.shear;
  return s;
}

FullRun Evaluator::full_at(const std::vector<ConicalCard>& cards, double ratio) const {
  const int n = p_.points();
  const BodySpec s = body_of(cards, ratio);
  Model m;
  FullRun run{std::vector<double>(n, std::nan("")), 0};
  if (s.groups.empty() || !build_model(s, &m).empty()) return run;
  CompressionStats st;
  const Curve c =
      p_.options.method == FitMethod::kStatic
          ? static_compression_curve(m, p_.options.max_strain, n, &st, p_.options.static_tolerance)
          : compression_curve(m, p_.options.rate, p_.options.max_strain, n, &st);
  for (int k = 0; k < n; ++k) run.force[k] = c[k + 1].force;
  run.spread = st.half_width > 0 ? st.layer_spread / st.half_width : 0;
  return run;
}

BodyCheck Evaluator::body_check(const std::vector<ConicalCard>& cards, double ratio,
                                bool stop_unsettled) const {
  const int n = p_.points();
  const int samples = p_.options.body_samples;
  BodyCheck out;
  out.force.assign(n, std::nan(""));
  if (samples < 1 || n % samples != 0) return out;
  const BodySpec s = body_of(cards, ratio);
  Model m;
  if (s.groups.empty() || !build_model(s, &m).empty() || m.planes.empty()) return out;
  // The plate and the solve as `conica-lab compress --quasi-static` sets them.
  m.planes[0].stiffness = std::max(m.planes[0].stiffness, rigid_plate_stiffness(m, false));
  QuasiStaticOptions qo;
  qo.samples = samples;
  qo.tolerance = 1e-4;
  qo.stop_at_failure = true;
  if (stop_unsettled) {
    // A screening run: an increment that has not settled in 50 iterations is taken as unsettled
    // (one that settles takes 1-3 on these bodies, and then the run is the command's).
    qo.max_iterations = 50;
    qo.max_parts = 1;
  }
  bool unsettled = false;
  qo.progress = [&unsettled](int, double, double, bool settled, long) {
    if (!settled) unsettled = true;
  };
  QuasiStaticStats qs;
  const Curve c = quasi_static_curve(m, plate_load(m), plate_reaction(),
                                     p_.options.max_strain * plate_height(m), qo, &qs, {},
                                     [&] { return stop_unsettled && unsettled; });
  const int stride = n / samples;
  const int got = std::min(qs.increments, static_cast<int>(c.size()) - 1);
  for (int j = 1; j <= got; ++j) out.force[stride * j - 1] = c[j].force;
  out.increments = qs.increments;
  out.steps = qs.steps;
  out.worst = qs.worst_residual;
  out.hard_stops = qs.hard_stops;
  // A spring at its solid height is a body that collapsed somewhere, not an equilibrium of the
  // card's law (its stroke bound is meant to keep every spring short of it).
  out.settled = got == samples && !unsettled && qs.unconverged == 0 && qs.hard_stops == 0;
  if (got < samples || qs.failed_at >= 0) return out;
  double sum = 0;
  int count = 0;
  for (int j = 1; j <= samples; ++j) {
    const int k = stride * j - 1;
    if (k < p_.target.first) continue;
    sum += std::abs(out.force[k] - p_.target.data[k]) / std::abs(p_.target.data[k]);
    ++count;
  }
  if (count > 0) out.error = sum / count;
  return out;
}

std::vector<double> Evaluator::full(const std::vector<ConicalCard>& cards, double ratio) {
  ++full_evaluations;
  FullRun run = full_at(cards, ratio);
  if (!even(run)) std::fill(run.force.begin(), run.force.end(), std::nan(""));
  return run.force;
}

double Evaluator::best_scale(const std::vector<double>& f) const {
  const std::vector<double>& data = p_.target.data;
  double a = 0, b = 0;
  for (int k = p_.target.first; k < p_.points(); ++k) {
    const double q = f[k] / data[k];
    if (!std::isfinite(q)) return 0.0;
    a += q;
    b += q * q;
  }
  return b > 0 ? a / b : 0.0;
}

double Evaluator::scaled_error(std::vector<CardShape>* sh) {
  const std::vector<ConicalCard> cards = cards_of(p_.base, *sh);
  for (const ConicalCard& c : cards)
    if (!validate(c).empty()) return std::numeric_limits<double>::infinity();
  std::vector<double> f = surrogate(cards);
  const double scale = best_scale(f);
  if (!(scale > 0)) return std::numeric_limits<double>::infinity();
  for (double& v : f) v *= scale;
  for (CardShape& s : *sh) s.modulus *= scale;
  return error(f);
}

double Evaluator::error(const std::vector<double>& f) const {
  return average_relative_error(f, p_.target.data, p_.target.first);
}
}  // namespace detail

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

double l1_scale(const std::vector<double>& model, const std::vector<double>& data, int first) {
  // sum_k |s q_k - 1| with q_k = model / data is minimised by the median of 1 / q_k weighted by
  // q_k.
  std::vector<std::pair<double, double>> v;
  double total = 0;
  for (size_t k = first; k < data.size() && k < model.size(); ++k) {
    const double q = model[k] / data[k];
    if (!std::isfinite(q) || !(q > 0)) continue;
    v.push_back({1 / q, q});
    total += q;
  }
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  double acc = 0;
  for (const auto& [s, w] : v) {
    acc += w;
    if (acc >= 0.5 * total) return s;
  }
  return v.back().first;
}

double average_relative_error(const std::vector<double>& model, const std::vector<double>& data,
                              int first) {
  double sum = 0;
  int n = 0;
  for (size_t k = first; k < data.size() && k < model.size(); ++k, ++n)
    sum += std::abs(model[k] - data[k]) / std::abs(data[k]);
  return n ? sum / n : std::numeric_limits<double>::quiet_NaN();
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

}  // namespace conica::lab
