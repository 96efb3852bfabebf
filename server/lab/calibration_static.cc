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
  const Layout layout = p.cards > 1 ? p.all_cards() : p.one_card(p.options.fit_precompression);
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
    const Layout layout = p.cards > 1 ? p.all_cards() : p.one_card(o.fit_precompression);
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

// A body check is better when it settles everywhere and the other does not, else by error.
bool better(const BodyCheck& a, const BodyCheck& b) {
  if (a.settled != b.settled) return a.settled;
  return a.error < b.error;
}

std::string check_text(const BodyCheck& c) {
  return (std::isfinite(c.error) ? "average relative error " + fmt(100 * c.error, 4) + " %"
                                 : std::string("no equilibrium at the end of the travel")) +
         " (" + std::to_string(c.increments) + " increments, " + std::to_string(c.steps) +
         " implicit steps, worst out-of-balance " + fmt(c.worst, 2) +
         (c.hard_stops ? ", " + std::to_string(c.hard_stops) + " hard stops" : std::string()) +
         (c.settled ? ")" : ", not settled everywhere)");
}

// The escalation (FitOptions::escalate_above): the one-card optimum through the body; past
// escalate_above or unsettled, the escalate_cards-card surrogate fit from it at its Poisson
// ratio, through the body, its moduli scaled by the body's L1-optimal factor (every force of a
// static body scales with a common factor on every modulus) and checked again; the best body
// kept.
void escalate(Evaluator& ev, const std::vector<SurrogateOptimum>& optima, FitResult* r) {
  const Problem& p = ev.problem();
  const FitOptions& o = p.options;
  const SurrogateOptimum& a = optima.front();
  const BodyCheck first = ev.body_check(cards_of(p.base, a.shapes), a.nu, true);
  ++ev.full_evaluations;
  say(o, "one card through the full body (quasi-static, " + std::to_string(o.body_samples) +
             " increments): " + check_text(first));
  r->full_error_before_refine = first.error;
  r->full = first.force;
  r->full_error = first.error;
  if (first.settled && first.error <= o.escalate_above) return;
  if (o.escalate_cards <= 1) {
    if (!first.settled) {
      const BodyCheck full = ev.body_check(cards_of(p.base, a.shapes), a.nu, false);
      r->full = full.force;
      r->full_error = full.error;
    }
    return;
  }
  say(o, "above " + fmt(100 * o.escalate_above, 3) +
             " % or not settled: " + std::to_string(o.escalate_cards) + " family cards");
  FitOptions ok = o;
  ok.cards = o.escalate_cards;
  const Problem pk{p.spec, ok,       ok.cards, p.base,
                   p.geo,  p.target, p.volume, stroke_bounds(ok.cards, ok)};
  Evaluator e(pk, a.nu);
  InitialGuess g;
  g.best = g.best_plain = a.shapes[0];
  // The K-card optima from several starts reach about the same surrogate error with different
  // diagonal shapes, which the surrogate hardly sees and the body does (one finds equilibrium
  // to 50 %, another not): each goes through the body, the first refined in L1 as well.
  const std::vector<Candidate> found = surrogate_candidates(e, g, a.shapes[0]);
  const Layout layout = pk.all_cards();
  std::vector<std::vector<CardShape>> starts{
      l1_fit(pk, layout, found.front().shapes,
             [&e](const std::vector<ConicalCard>& cards) { return e.surrogate(cards); })};
  for (const Candidate& c : found) starts.push_back(c.shapes);
  const int m = static_cast<int>(starts.size());
  std::vector<BodyCheck> plain(m), scaled(m);
  std::vector<std::vector<CardShape>> scaled_shapes(m);
  parallel_for(m, o.threads, [&](int i) {
    plain[i] = e.body_check(cards_of(p.base, starts[i]), a.nu, true);
    const double scale = l1_scale(plain[i].force, p.target.data, p.target.first);
    if (!plain[i].settled || !(scale > 0)) return;
    scaled_shapes[i] = starts[i];
    for (CardShape& sh : scaled_shapes[i]) sh.modulus *= scale;
    scaled[i] = e.body_check(cards_of(p.base, scaled_shapes[i]), a.nu, true);
  });
  std::vector<CardShape> best_shapes = a.shapes;
  BodyCheck best = first;
  std::vector<CardShape> x;  // the best K-card body (moduli scaled) so far
  BodyCheck bx;
  auto keep = [&](const BodyCheck& b, const std::vector<CardShape>& sh) {
    if (better(b, best)) {
      best = b;
      best_shapes = sh;
    }
  };
  for (int i = 0; i < m; ++i) {
    const std::string name = std::to_string(ok.cards) + " cards, " +
                             (i == 0 ? std::string("L1 optimum") : "start " + std::to_string(i));
    ev.full_evaluations += scaled_shapes[i].empty() ? 1 : 2;
    say(o, name + ": surrogate " + fmt(100 * e.surrogate_error(starts[i]), 4) + " %, body " +
               check_text(plain[i]) +
               (scaled_shapes[i].empty() ? std::string()
                                         : "; moduli scaled: " + check_text(scaled[i])) +
               " at " + shapes_text(starts[i]));
    keep(plain[i], starts[i]);
    if (scaled_shapes[i].empty()) continue;
    keep(scaled[i], scaled_shapes[i]);
    if (x.empty() || better(scaled[i], bx)) {
      x = scaled_shapes[i];
      bx = scaled[i];
    }
  }
  const int n = p.points();
  for (int step = 1; step <= o.escalate_mapping && !x.empty() && bx.settled; ++step) {
    if (best.settled && best.error <= o.escalate_above) break;
    // Output space mapping: the surrogate times the body / surrogate ratio at the increments
    // (linear between them, held before the first) refitted from the best K-card body.
    const std::vector<double> sk = e.surrogate(cards_of(p.base, x));
    std::vector<double> ratio(n, std::nan(""));
    for (int k = 0; k < n; ++k)
      if (std::isfinite(bx.force[k]) && sk[k] > 0) ratio[k] = bx.force[k] / sk[k];
    int last = -1;
    for (int k = 0; k < n; ++k) {
      if (!std::isfinite(ratio[k])) continue;
      for (int j = last + 1; j < k; ++j)
        ratio[j] =
            last < 0 ? ratio[k] : ratio[last] + (ratio[k] - ratio[last]) * (j - last) / (k - last);
      last = k;
    }
    if (last < 0) break;
    for (int j = last + 1; j < n; ++j) ratio[j] = ratio[last];
    x = l1_fit(pk, layout, x, [&e, ratio](const std::vector<ConicalCard>& cards) {
      std::vector<double> f = e.surrogate(cards);
      for (size_t k = 0; k < f.size(); ++k) f[k] *= ratio[k];
      return f;
    });
    const BodyCheck b = e.body_check(cards_of(p.base, x), a.nu, true);
    ++ev.full_evaluations;
    say(o, std::to_string(ok.cards) + " cards, space mapping " + std::to_string(step) + ": body " +
               check_text(b) + " at " + shapes_text(x));
    keep(b, x);
    const double scale = l1_scale(b.force, p.target.data, p.target.first);
    if (!b.settled || !(scale > 0)) break;
    for (CardShape& sh : x) sh.modulus *= scale;
    bx = e.body_check(cards_of(p.base, x), a.nu, true);
    ++ev.full_evaluations;
    say(o, std::to_string(ok.cards) + " cards, space mapping " + std::to_string(step) +
               ", moduli scaled: body " + check_text(bx));
    keep(bx, x);
  }
  ev.surrogate_evaluations += e.surrogate_evaluations;
  if (!best.settled) {
    // Nothing settles everywhere: the kept body's error as the command measures it.
    best = e.body_check(cards_of(p.base, best_shapes), a.nu, false);
    ++ev.full_evaluations;
  }
  describe(ev, best_shapes, r);
  r->full = best.force;
  r->full_error = best.error;
  say(o, "kept " + std::to_string(best_shapes.size()) + " card(s): full body " + check_text(best));
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
  if (o.escalate_above > 0 && o.full_iterations >= 0) {
    escalate(ev, optima, r);
    return;
  }
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
