// FitMethod::kStatic (lab/calibration.h): the cell surrogate at a few Poisson ratios, the full
// body by static equilibrium solves, output space mapping between them. Every fit minimises the
// mean absolute relative error, the metric the calibration reports, by iteratively reweighted
// least squares (weights 1 / sqrt(|r|) turn the squares into absolute values).
#include <algorithm>
#include <cmath>

#include "lab/calibration_stages.h"

namespace conica::lab::detail {
namespace {

using Model_fn = std::function<std::vector<double>(const std::vector<ConicalCard>&)>;

// Least squares, then o.reweightings L1 reweightings, from `start` on `model`.
std::vector<CardShape> l1_fit(const Problem& p, const Layout& layout,
                              const std::vector<CardShape>& start, const Model_fn& model) {
  const FitOptions& o = p.options;
  RelativeResiduals res = residuals(p, layout, model);
  std::vector<double> x = encode(start, layout);
  solve_lm(res, p.residuals(), o.max_iterations, true, 1e-6, {}, "", x.data());
  const int n = p.points();
  for (int it = 0; it < o.reweightings; ++it) {
    const std::vector<double> f = model(cards_of(p.base, decode(x.data(), layout)));
    std::vector<double> w(n, 1.0);
    bool ok = true;
    for (int k = p.target.first; k < n; ++k) {
      const double r = (f[k] - p.target.data[k]) / p.target.data[k];
      ok &= std::isfinite(r);
      w[k] = 1 / std::sqrt(std::max(std::abs(r), 1e-3));
    }
    if (!ok) break;
    res.weights = w;
    solve_lm(res, p.residuals(), o.max_iterations, true, 1e-6, {}, "", x.data());
  }
  return decode(x.data(), layout);
}

struct SurrogateOptimum {
  double nu = 0;
  std::vector<CardShape> shapes;
  double error = 0;  // surrogate, mean relative error
};

// The surrogate's best one-card shape at Poisson ratio ev.nu: grid, least squares from the
// pre-compressed and the plain start, each refined in L1; the better kept.
SurrogateOptimum surrogate_at(Evaluator& ev) {
  const Problem& p = ev.problem();
  const InitialGuess guess = initial_guess(ev);
  const CardShape one = fit_one_card(ev, guess);
  const std::vector<Candidate> found = surrogate_candidates(ev, guess, one);
  const Layout layout = p.one_card(p.options.fit_precompression);
  SurrogateOptimum best{ev.nu, found.front().shapes, std::numeric_limits<double>::infinity()};
  for (const Candidate& c : found) {
    const std::vector<CardShape> sh =
        l1_fit(p, layout, c.shapes,
               [&ev](const std::vector<ConicalCard>& cards) { return ev.surrogate(cards); });
    const double e = ev.surrogate_error(sh);
    if (e < best.error) best = {ev.nu, sh, e};
  }
  return best;
}

// One chain through the full body from a surrogate optimum: the full body there, then
// space-mapping steps; the best even full-body fit.
struct Chain {
  SurrogateOptimum start;
  FullBest best;
  int surrogate_evaluations = 0, full_evaluations = 0;
  std::vector<std::string> lines;
};

void run_chain(const Problem& problem, Chain* c) {
  const FitOptions& o = problem.options;
  Problem p = problem;  // its stroke bound rises when the full body collapses
  Evaluator ev(p, c->start.nu);
  std::vector<CardShape> xk = c->start.shapes;
  int mapped = 0;
  for (int step = 0; step <= o.space_mapping + o.stroke_raises; ++step) {
    const FullRun run = ev.full_at(cards_of(p.base, xk), ev.nu);
    ++ev.full_evaluations;
    const bool even = ev.even(run);
    const double e = even ? ev.error(run.force) : std::numeric_limits<double>::infinity();
    c->lines.push_back("Poisson " + fmt(ev.nu, 3) + ", full body (static), step " +
                       std::to_string(step) + ": average relative error " + fmt(100 * e, 4) +
                       " % at " + shapes_text(xk) +
                       (even ? std::string()
                             : " (rejected: left the homogeneous state, layer spread " +
                                   fmt(100 * run.spread, 3) + " % of the half width)"));
    if (e < c->best.error) c->best = {e, xk, run.force};
    if (step == o.space_mapping + o.stroke_raises) break;
    if (!even) {
      // The body collapsed before the end of the travel (with stability_margin off, usually its
      // material losing strong ellipticity, core/stability.h): a longer stroke, the surrogate
      // refitted from scratch.
      if (p.smin[0] >= 0.99 * o.bounds.stroke_max) break;
      p.smin[0] = std::min(0.99 * o.bounds.stroke_max, p.smin[0] * o.stroke_raise);
      c->lines.push_back("Poisson " + fmt(ev.nu, 3) + ": stroke bound raised to " +
                         fmt(p.smin[0], 4));
      Evaluator fresh(p, ev.nu);
      xk = surrogate_at(fresh).shapes;
      ev.surrogate_evaluations += fresh.surrogate_evaluations;
      continue;
    }
    if (mapped++ == o.space_mapping) break;
    const Layout layout = p.one_card(o.fit_precompression);
    const std::vector<double> sk = ev.surrogate(cards_of(p.base, xk));
    std::vector<double> ratio(p.points(), 1.0);
    bool ok = true;
    for (int k = p.target.first; k < p.points(); ++k) {
      ratio[k] = run.force[k] / sk[k];
      ok &= std::isfinite(ratio[k]) && ratio[k] > 0;
    }
    if (!ok) break;
    xk = l1_fit(p, layout, xk, [&ev, ratio](const std::vector<ConicalCard>& cards) {
      std::vector<double> f = ev.surrogate(cards);
      for (size_t k = 0; k < f.size(); ++k) f[k] *= ratio[k];
      return f;
    });
  }
  c->surrogate_evaluations = ev.surrogate_evaluations;
  c->full_evaluations = ev.full_evaluations;
}

}  // namespace

void static_fit(Evaluator& ev, FitResult* r) {
  const Problem& p = ev.problem();
  const FitOptions& o = p.options;
  std::vector<double> nus{ev.nu};
  if (p.volume.with_volume && o.poisson < 0 && o.poisson_grid > 1) {
    nus.clear();
    for (int i = 0; i < o.poisson_grid; ++i)
      nus.push_back(o.poisson_max - (o.poisson_max - o.poisson_min) * i / (o.poisson_grid - 1));
  }
  // One surrogate search per Poisson ratio, in parallel: each on its own evaluator (its own root
  // hints) and a copy of the problem whose progress lines are kept and said in the grid's order,
  // so the result and the log do not depend on the thread count.
  const int n = static_cast<int>(nus.size());
  std::vector<SurrogateOptimum> optima(n);
  std::vector<std::vector<std::string>> lines(n);
  std::vector<int> evaluations(n, 0);
  parallel_for(n, o.threads, [&](int i) {
    FitOptions oi = o;
    oi.progress = [&lines, i](const std::string& line) { lines[i].push_back(line); };
    const Problem q{p.spec, oi, p.cards, p.base, p.geo, p.target, p.volume, p.smin};
    Evaluator e(q, nus[i]);
    optima[i] = surrogate_at(e);
    evaluations[i] = e.surrogate_evaluations;
  });
  for (int i = 0; i < n; ++i) {
    for (const std::string& line : lines[i]) say(o, line);
    ev.surrogate_evaluations += evaluations[i];
    say(o, "surrogate at Poisson " + fmt(nus[i], 3) + ": average relative error " +
               fmt(100 * optima[i].error, 4) + " %: " + shapes_text(optima[i].shapes));
  }
  std::stable_sort(
      optima.begin(), optima.end(),
      [](const SurrogateOptimum& a, const SurrogateOptimum& b) { return a.error < b.error; });
  ev.nu = optima.front().nu;
  describe(ev, optima.front().shapes, r);
  r->surrogate_error_before_refine = r->surrogate_error;
  say(o, "surrogate fit: average relative error " + fmt(100 * r->surrogate_error, 4) +
             " % at Poisson " + fmt(ev.nu, 3) + ": " + shapes_text(r->shapes));
  if (o.full_iterations < 0) return;

  // The best surrogate optima through the full body, one chain per thread.
  const int chains = std::min<int>(std::max(1, o.verify_candidates), optima.size());
  std::vector<Chain> runs(chains);
  for (int c = 0; c < chains; ++c) runs[c].start = optima[c];
  parallel_for(chains, o.threads, [&](int c) { run_chain(p, &runs[c]); });
  const Chain* best = nullptr;
  for (const Chain& c : runs) {
    for (const std::string& line : c.lines) say(o, line);
    ev.surrogate_evaluations += c.surrogate_evaluations;
    ev.full_evaluations += c.full_evaluations;
    if (!best || c.best.error < best->best.error) best = &c;
  }
  if (!std::isfinite(best->best.error)) {
    say(o,
        "no full-body solve kept its homogeneous state (layer spread above max_layer_spread): "
        "the full-body error is not defined for this scene");
    r->full_error = std::numeric_limits<double>::infinity();
    return;
  }
  ev.nu = best->start.nu;
  describe(ev, best->best.shapes, r);
  r->full = best->best.curve;
  r->full_error = best->best.error;
  say(o, "full body (static): average relative error " + fmt(100 * r->full_error, 4) +
             " % at Poisson " + fmt(ev.nu, 3));
}

}  // namespace conica::lab::detail
