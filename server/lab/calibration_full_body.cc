// Calibration stages through the full body (lab/calibration_stages.h): the check at the
// surrogate optima, the one-card grid of full compressions, output space mapping and the
// Levenberg-Marquardt refinement.
#include <algorithm>
#include <cmath>

#include "lab/calibration_stages.h"

namespace conica::lab::detail {

FullBest verify_full_body(Evaluator& ev, const std::vector<Candidate>& found) {
  const Problem& p = ev.problem();
  FullBest best;
  best.shapes = found.front().shapes;
  const int verify = p.cards == 1 ? static_cast<int>(found.size())
                                  : std::min<int>(std::max(1, p.options.verify_candidates),
                                                  static_cast<int>(found.size()));
  for (int c = 0; c < verify; ++c) {
    const std::vector<double> f = ev.full(cards_of(p.base, found[c].shapes));
    const double e = ev.error(f);
    say(p.options, "full body at surrogate optimum " + std::to_string(c + 1) + " (surrogate " +
                       fmt(100 * found[c].surrogate_error, 4) + " %): average relative error " +
                       fmt(100 * e, 4) + " %");
    if (e < best.error) {
      best.error = e;
      best.shapes = found[c].shapes;
      best.curve = f;
    }
  }
  return best;
}

// Full-body grid (one card): forces scale with the modulus at fixed shape and Poisson ratio
// (the volume stiffness and the plate's penalty scale with it), so each shape takes the best
// modulus in closed form; the best is compressed again at that modulus. With volume stiffness
// and the scene's Poisson ratio (no `poisson` asked) the grid also spans Poisson ratios from
// poisson_min up to the scene's. The runs are independent and share out over threads.
GridOutcome full_body_grid(Evaluator& ev, const FullBest& start) {
  const Problem& p = ev.problem();
  const FitOptions& o = p.options;
  const ShapeBounds& B = o.bounds;
  const std::vector<double>& smin = p.smin;
  const bool pre = o.fit_precompression;
  const double scene_nu = p.volume.scene_nu;
  const Layout L1 = p.one_card(pre);
  GridOutcome out{start, ev.nu};
  const int g = o.full_grid;
  const int gp = pre ? std::max(1, o.full_grid_pre) : 1;
  const int gn = p.volume.with_volume && o.poisson < 0 && o.poisson_min < scene_nu
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
    CardShape sh = start.shapes[0];
    sh.taper = B.taper_min + (B.taper_max - B.taper_min) * (it + 0.5) / g;
    sh.stroke = smin[0] + (B.stroke_max - smin[0]) * (is + 0.5) / g;
    sh.precompression = ip * L1.pre_max(0, sh.stroke) / gp;
    std::vector<CardShape> one_shape{sh};
    if (!std::isfinite(ev.scaled_error(&one_shape))) continue;  // modulus from the surrogate
    const double ratio = gn == 1 ? scene_nu : scene_nu - (scene_nu - o.poisson_min) * in / (gn - 1);
    points.push_back({one_shape[0], ratio, {}});
  }
  parallel_for(static_cast<int>(points.size()), o.threads, [&](int k) {
    points[k].run = ev.full_at(cards_of(p.base, {points[k].shape}), points[k].nu);
  });
  ev.full_evaluations += static_cast<int>(points.size());
  double best_estimate = start.error;
  const GridPoint* grid_best = nullptr;
  for (GridPoint& q : points) {
    std::vector<double>& f = q.run.force;
    const double scale = ev.best_scale(f);
    if (!(scale > 0)) continue;
    for (double& v : f) v *= scale;
    const double e = ev.error(f);
    const bool kept = ev.even(q.run);
    q.shape.modulus *= scale;
    say(o, "full-body grid: " + (gn > 1 ? "Poisson " + fmt(q.nu, 3) + ", " : std::string()) +
               "taper " + fmt(q.shape.taper, 3) + ", stroke " + fmt(q.shape.stroke, 3) +
               (q.shape.precompression > 0
                    ? ", pre-compression " + fmt(q.shape.precompression, 3) + " S"
                    : std::string()) +
               ": average relative error " + fmt(100 * e, 4) + " % (modulus scaled)" +
               (kept ? std::string()
                     : ", rejected: left the homogeneous state (layer spread " +
                           fmt(100 * q.run.spread, 3) + " % of the half width)"));
    if (kept && e < best_estimate) {
      best_estimate = e;
      grid_best = &q;
    }
  }
  if (grid_best) {
    const double nu = grid_best->nu;
    const std::vector<double> f = ev.full(cards_of(p.base, {grid_best->shape}), nu);
    const double e = ev.error(f);
    say(o, "full-body grid best: " + shapes_text({grid_best->shape}) +
               (gn > 1 ? ", Poisson " + fmt(nu, 3) : std::string()) + ", average relative error " +
               fmt(100 * e, 4) + " %");
    if (e < out.best.error) {
      out.best = {e, {grid_best->shape}, f};
      out.nu = nu;
    }
  }
  return out;
}

// Output space mapping: the full body differs from the cell surrogate (boundary cells, the
// cylinder's distorted cells), by a ratio that depends on the strain and only weakly on the
// cards. Refit the surrogate times the last full-body / surrogate ratio, rerun the full body
// there, repeat. One full compression per step.
FullBest space_mapping(Evaluator& ev, const FullBest& start) {
  const Problem& p = ev.problem();
  const int n = p.points();
  const Layout LK = p.all_cards();
  FullBest best = start;
  std::vector<CardShape> xk = start.shapes;
  std::vector<double> fk = start.curve;
  int worse = 0;
  for (int step = 1; step <= p.options.space_mapping && worse < 2; ++step) {
    const std::vector<double> sk = ev.surrogate(cards_of(p.base, xk));
    std::vector<double> ratio(n, 1.0);
    bool ok = true;
    for (int k = p.target.first; k < n; ++k) {
      ratio[k] = fk[k] / sk[k];
      ok &= std::isfinite(ratio[k]) && ratio[k] > 0;
    }
    if (!ok) {
      say(p.options, "space mapping step " + std::to_string(step) +
                         ": full body and surrogate not comparable (collapse or NaN), stopped");
      break;
    }
    RelativeResiduals mres = residuals(p, LK, [&ev, ratio](const std::vector<ConicalCard>& cards) {
      std::vector<double> f = ev.surrogate(cards);
      for (size_t k = 0; k < f.size(); ++k) f[k] *= ratio[k];
      return f;
    });
    std::vector<double> x = encode(xk, LK);
    solve_lm(mres, p.residuals(), p.options.max_iterations, true, 1e-6, {}, "", x.data());
    xk = decode(x.data(), LK);
    fk = ev.full(cards_of(p.base, xk));
    const double e = ev.error(fk);
    say(p.options, "space mapping step " + std::to_string(step) + ": full body " + fmt(100 * e, 4) +
                       " % at " + shapes_text(xk));
    if (e < best.error) {
      best = {e, xk, fk};
      worse = 0;
    } else {
      ++worse;
    }
  }
  return best;
}

FullBest refine_full_body(Evaluator& ev, const std::vector<CardShape>& from) {
  const Problem& p = ev.problem();
  const Layout LK = p.all_cards();
  RelativeResiduals fres =
      residuals(p, LK, [&ev](const std::vector<ConicalCard>& cards) { return ev.full(cards); });
  std::vector<double> x = encode(from, LK);
  solve_lm(fres, p.residuals(), p.options.full_iterations, false, 1e-4, p.options, "full-body LM",
           x.data());
  FullBest refined;
  refined.shapes = decode(x.data(), LK);
  refined.curve = ev.full(cards_of(p.base, refined.shapes));
  refined.error = ev.error(refined.curve);
  return refined;
}

}  // namespace conica::lab::detail
