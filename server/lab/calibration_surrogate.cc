// Calibration stages on the cell surrogate (lab/calibration_stages.h): the one-card grid, its
// Levenberg-Marquardt fit and the candidates the full body is checked at.
#include <algorithm>
#include <cmath>

#include "lab/calibration_stages.h"

namespace conica::lab::detail {

// One card: grid search over (taper, stroke[, pre-compression]), modulus in closed form.
// Pre-compressions on the grid: fractions of the largest the stroke allows.
InitialGuess initial_guess(Evaluator& ev) {
  const Problem& p = ev.problem();
  const ShapeBounds& B = p.options.bounds;
  const int K = p.cards;
  const std::vector<double>& smin = p.smin;
  const bool pre = p.options.fit_precompression;
  InitialGuess g;
  const int nt = 8, ns = 9, np = pre ? 6 : 1;
  const Layout L1 = p.one_card(pre);
  for (int i = 0; i < nt; ++i)
    for (int j = 0; j < ns; ++j)
      for (int q = 0; q < np; ++q) {
        std::vector<CardShape> sh(K);
        sh[0].modulus = 1e4;
        sh[0].taper = B.taper_min + (B.taper_max - B.taper_min) * (i + 0.5) / nt;
        sh[0].stroke = smin[0] + (B.stroke_max - smin[0]) * (j + 1.0) / ns;
        sh[0].precompression = L1.pre_max(0, sh[0].stroke) * q / np;
        for (int c = 1; c < K; ++c) sh[c] = sh[0];
        const double e = ev.scaled_error(&sh);
        if (e < g.best_error) {
          g.best_error = e;
          g.best = sh[0];
        }
        if (q == 0 && e < g.best_plain_error) {
          g.best_plain_error = e;
          g.best_plain = sh[0];
        }
      }
  say(p.options, "grid search (" + std::to_string(nt * ns * np) + " shapes, one card): start " +
                     shapes_text({g.best}) + ", average relative error " +
                     fmt(100 * g.best_error, 4) + " %");
  return g;
}

namespace {

// Levenberg-Marquardt on the surrogate from `start` in `layout`.
std::vector<CardShape> surrogate_lm(Evaluator& ev, const Layout& layout,
                                    const std::vector<CardShape>& start, const std::string& stage) {
  const Problem& p = ev.problem();
  RelativeResiduals res = residuals(
      p, layout, [&ev](const std::vector<ConicalCard>& cards) { return ev.surrogate(cards); });
  std::vector<double> x = encode(start, layout);
  solve_lm(res, p.residuals(), p.options.max_iterations, true, 1e-6, p.options, stage, x.data());
  return decode(x.data(), layout);
}

}  // namespace

CardShape fit_one_card(Evaluator& ev, const InitialGuess& guess) {
  const Problem& p = ev.problem();
  return surrogate_lm(ev, p.one_card(p.options.fit_precompression), {guess.best},
                      "surrogate LM (one card)")[0];
}

std::vector<Candidate> surrogate_candidates(Evaluator& ev, const InitialGuess& guess,
                                            const CardShape& one, int max_tries) {
  const Problem& p = ev.problem();
  const FitOptions& o = p.options;
  const ShapeBounds& B = o.bounds;
  const int K = p.cards;
  const std::vector<double>& smin = p.smin;
  std::vector<Candidate> found;
  if (K == 1) {
    found.push_back({{one}, 0});
    if (o.fit_precompression) {
      // The plain optimum too: its body may hold up better than the pre-compressed one's (the
      // full body is checked at both, later).
      const CardShape plain = surrogate_lm(ev, p.one_card(false), {guess.best_plain},
                                           "surrogate LM (one card, plain law)")[0];
      found.push_back({{plain}, ev.surrogate_error({plain})});
      found[0].surrogate_error = ev.surrogate_error({one});
    }
    return found;
  }
  // K cards: starts from the one-card optimum, LM from the best few.
  const Layout L = p.all_cards();
  std::vector<Candidate> starts;
  auto add_start = [&](std::vector<CardShape> sh) {
    const double e = ev.scaled_error(&sh);
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
  say(o, "starts: " + std::to_string(starts.size()) + " shapes, best " +
             fmt(100 * starts.front().surrogate_error, 4) + " %");
  const int tries = std::min<int>(max_tries, static_cast<int>(starts.size()));
  for (int t = 0; t < tries; ++t) {
    const std::vector<CardShape> sh = surrogate_lm(
        ev, L, starts[t].shapes,
        "surrogate LM (" + std::to_string(K) + " cards, start " + std::to_string(t + 1) + ")");
    found.push_back({sh, ev.surrogate_error(sh)});
  }
  // The one-card body as a candidate too (the cards may not help in the full body).
  if (!o.isotropic)
    found.push_back(
        {std::vector<CardShape>(K, one), ev.surrogate_error(std::vector<CardShape>(K, one))});
  std::stable_sort(found.begin(), found.end(), [](const Candidate& a, const Candidate& b) {
    return a.surrogate_error < b.surrogate_error;
  });
  return found;
}

}  // namespace conica::lab::detail
