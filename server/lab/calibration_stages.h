// Internal to conica_lab_lib: calibrate() (lab/calibration.h) as a pipeline of named stages,
// each a function from its inputs to its outputs, and the fitting machinery they share.
//
//   prepare_body -> build_target -> column_floors -> volume_rule -> stroke_bounds
//     -> initial_guess (one-card grid) -> fit_one_card (surrogate LM)
//     -> surrogate_candidates (K cards: starts and LM; one card: the plain law too)
//     -> verify_full_body -> full_body_grid (one card) -> space_mapping -> refine_full_body
//
// calibration_pipeline.cc runs them in this order; the stages of the cell surrogate are in
// calibration_surrogate.cc, those through the full body in calibration_full_body.cc, the
// evaluations they count in calibration_fit.cc. Reading curves and writing cards is not here
// (server/io: curve_reader.h, scene_writer.h).
#pragma once

#include <cstdint>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "lab/calibration.h"

namespace conica::lab::detail {

// "%.*g" of v.
std::string fmt(double v, int precision = 6);
// "E_c ... Pa, taper ..., stroke ...[, pre-compression ... S]; ..." for progress lines.
std::string shapes_text(const std::vector<CardShape>& shapes);
// options.progress(line) when set.
void say(const FitOptions& options, const std::string& line);
// Runs fn(0) .. fn(n - 1) on up to `threads` threads (0: one per hardware thread), each index
// once; fn must not touch shared state.
void parallel_for(int n, int threads, const std::function<void(int)>& fn);

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
std::vector<CardShape> decode(const double* x, const Layout& layout);
std::vector<double> encode(const std::vector<CardShape>& shapes, const Layout& layout);

struct BodyGeometry {
  double height = 0;  // m, along the plate normal
  double area = 0;    // m^2
};

// The cell surrogate's force (N) at plate travel `grid` (m) of a body of `geo` with `groups`.
std::vector<double> cell_surrogate(const std::vector<SpringGroupSpec>& groups, Mapping mapping,
                                   const BodyGeometry& geo, const std::vector<double>& grid,
                                   double bulk_modulus, double shear_modulus,
                                   double shear_stiffening);
std::vector<ConicalCard> cards_of(const ConicalCard& base, const std::vector<CardShape>& shapes);

// --- Stage 1, prepare_body: the spec and options checked, the body built once.
struct Prepared {
  ConicalCard base;  // the card of the scene's first conical group
  BodyGeometry geo;
  std::string error;  // empty: the fit can run
};
Prepared prepare_body(const BodySpec& spec, const std::vector<Curve>& curves,
                      const FitOptions& options);

// --- Stage 2, build_target: the common grid and the mean measured curve on it.
struct Target {
  std::vector<double> grid;  // (points) plate travel, m
  std::vector<double> data;  // (points) mean measured force, N
  int first = 0;             // first grid index in the error (skip_strain)
  std::string error;
};
Target build_target(const std::vector<Curve>& curves, const BodyGeometry& geo,
                    const FitOptions& options);

// --- Stage 3, column_floors: the data's floors without and with pre-compressed laws.
struct Floors {
  ColumnFloor plain, precompressed;
};
Floors column_floors(const Target& target, const BodyGeometry& geo, const FitOptions& options);

// --- Stage 4, volume_rule: how the volume and shear stiffness follow the cards.
struct VolumeRule {
  bool with_volume = false;  // a bulk modulus is kept at a Poisson ratio
  double scene_nu = 0;       // the scene's Poisson ratio (or the asked one)
  double shear_ratio = 0;    // scene shear_modulus / its lattice's shear modulus
  double spread_ratio = 0;   // scene spread_modulus / bulk_modulus
  std::string error;
};
VolumeRule volume_rule(const BodySpec& spec, const FitOptions& options);

// --- Stage 5, stroke_bounds: a family's springs must not reach their stroke in the fitted range.
std::vector<double> stroke_bounds(int cards, const FitOptions& options);

// What the stages after the fifth read: the body, its target and the rules above.
struct Problem {
  const BodySpec& spec;
  const FitOptions& options;
  int cards = 1;
  ConicalCard base;
  BodyGeometry geo;
  const Target& target;
  VolumeRule volume;
  std::vector<double> smin;  // (cards) stroke lower bounds
  int points() const { return static_cast<int>(target.grid.size()); }
  int residuals() const { return points() - target.first; }
  // The layout of the one-card fit (pre: with its pre-compression) and of the K-card fit.
  Layout one_card(bool pre) const { return {1, false, options.bounds, {smin[0]}, false, pre}; }
  Layout all_cards() const {
    return {cards, cards > 1 && options.tie_taper, options.bounds,
            smin,  cards > 1 && options.isotropic, options.fit_precompression};
  }
};

// The element terms of a body with some groups as its springs (BodySpec fields).
struct ElementModuli {
  double bulk, spread, shear;
};
// A full-body compression on the grid and how far it left the homogeneous state (layer spread
// over half width at the end of the travel).
struct FullRun {
  std::vector<double> force;
  double spread = 0;
};

// A full-body compression solved as `conica-lab compress --quasi-static --samples N` solves it
// (N = options.body_samples increments, each brought to an out-of-balance force below 1e-4 of
// the reaction, stopping at the first with no equilibrium), and its error as that command
// reports it: against the target at the increments' strains from skip_strain on.
struct BodyCheck {
  std::vector<double> force;  // (points) N at the increments' grid indices, NaN elsewhere
  double error = std::numeric_limits<double>::infinity();  // inf: the body stopped short
  bool settled = false;  // every increment reached equilibrium (to the tolerance) with no
                         // spring at its solid height (no hard stop)
  double worst = 0;      // largest out-of-balance left, of the reaction
  int increments = 0;    // taken
  long steps = 0;        // implicit steps
  std::uint64_t hard_stops = 0;
};

// The model curves of candidate cards, counted: the cell surrogate and the full body, at the
// body's Poisson ratio `nu` (the scene's until the full-body grid picks one).
class Evaluator {
 public:
  Evaluator(const Problem& problem, double nu) : p_(problem), nu(nu) {}
  const Problem& problem() const { return p_; }

  std::vector<SpringGroupSpec> groups(const std::vector<ConicalCard>& cards) const;
  // The problem's body with these cards and the element moduli they give at Poisson ratio.
  BodySpec body_of(const std::vector<ConicalCard>& cards, double ratio) const;
  double bulk_for(const std::vector<SpringGroupSpec>& groups, double ratio) const;
  // Safe to call from several threads at once (full_at's grid): its root is found afresh;
  // surrogate() brackets it about the last one (shear_hint_).
  ElementModuli element_moduli(const std::vector<SpringGroupSpec>& groups, double ratio) const;

  std::vector<double> surrogate(const std::vector<ConicalCard>& cards);  // counted
  // The full body at Poisson ratio `ratio`; touches nothing shared (runs on several threads).
  FullRun full_at(const std::vector<ConicalCard>& cards, double ratio) const;
  // A run that left the homogeneous state (options.max_layer_spread).
  bool even(const FullRun& run) const { return run.spread <= p_.options.max_layer_spread; }
  // The full body's force at `ratio` (counted); NaN for a run that is not even: the fit must
  // not owe its shape to a buckle.
  std::vector<double> full(const std::vector<ConicalCard>& cards, double ratio);
  std::vector<double> full(const std::vector<ConicalCard>& cards) { return full(cards, nu); }
  // The body check above at Poisson ratio `ratio` (touches nothing shared); with
  // stop_unsettled, a screening run: an increment is given 50 iterations and no split, and the
  // run ends at the first that does not settle (a run that settles everywhere is the same).
  BodyCheck body_check(const std::vector<ConicalCard>& cards, double ratio,
                       bool stop_unsettled) const;

  // Best common scale of the moduli for force curve f: at fixed tapers and strokes, forces are
  // proportional to a common factor on every E_c.
  double best_scale(const std::vector<double>& f) const;
  // Surrogate error of shapes with the moduli scaled in closed form (shapes updated).
  double scaled_error(std::vector<CardShape>* shapes);
  // The paper's metric against the target.
  double error(const std::vector<double>& f) const;
  double surrogate_error(const std::vector<CardShape>& shapes) {
    return error(surrogate(cards_of(p_.base, shapes)));
  }

 private:
  const Problem& p_;
  // The last stable shear modulus found (shear_for): the next card is close to the last one, so
  // its root is bracketed about this first (the same root, to the same tolerance, in fewer
  // steps). Used by surrogate() only, which is never called from two threads on one Evaluator.
  double shear_hint_ = 0;
  Vec3 stretch_hint_ = Vec3::Ones();  // the cell's lateral stretches at that root
  ElementModuli element_moduli(const std::vector<SpringGroupSpec>& groups, double ratio,
                               double* shear_hint, Vec3* stretch_hint) const;

 public:
  double nu;
  int surrogate_evaluations = 0;
  int full_evaluations = 0;
};

// Residuals (model - data) / data over the target's grid indices >= first, for Ceres.
struct RelativeResiduals {
  std::function<std::vector<double>(const std::vector<ConicalCard>&)> model;
  ConicalCard base;
  Layout layout;
  const std::vector<double>* data = nullptr;
  int first = 0;
  std::vector<double> weights;  // per grid index (empty: all 1): residuals times these

  bool operator()(double const* const* x, double* r) const;
};
RelativeResiduals residuals(
    const Problem& problem, const Layout& layout,
    std::function<std::vector<double>(const std::vector<ConicalCard>&)> model);

// Levenberg-Marquardt from x (updated in place); progress lines to options.progress.
void solve_lm(RelativeResiduals res, int num_residuals, int iterations, bool central,
              double relative_step, const FitOptions& options, const std::string& stage, double* x);

// --- Stage 6, initial_guess: one card, a grid over (taper, stroke[, pre-compression]), the
// modulus in closed form.
struct InitialGuess {
  CardShape best{1e4, 0.25, 0.9};  // the best shape on the grid
  CardShape best_plain = best;     // the best with pre-compression 0
  double best_error = std::numeric_limits<double>::infinity();
  double best_plain_error = std::numeric_limits<double>::infinity();
};
InitialGuess initial_guess(Evaluator& ev);

// --- Stage 7, fit_one_card: Levenberg-Marquardt on the surrogate from the grid's best.
CardShape fit_one_card(Evaluator& ev, const InitialGuess& guess);

// --- Stage 8, surrogate_candidates: the surrogate optima the full body is checked at, best
// first (one card: the one-card optimum and, with pre-compression, the plain law's; K cards:
// starts from the one-card optimum, LM from the best few).
struct Candidate {
  std::vector<CardShape> shapes;
  double surrogate_error = 0;
};
// (K cards: least squares from the best `tries` starts.)
std::vector<Candidate> surrogate_candidates(Evaluator& ev, const InitialGuess& guess,
                                            const CardShape& one, int tries = 4);

// The result fields of a fitted body with `shapes` (cards, groups, moduli, volume terms, its
// surrogate curve and error) at the evaluator's Poisson ratio.
void describe(Evaluator& ev, const std::vector<CardShape>& shapes, FitResult* r);

// The best full-body fit so far.
struct FullBest {
  double error = std::numeric_limits<double>::infinity();
  std::vector<CardShape> shapes;
  std::vector<double> curve;
};

// --- Stage 9, verify_full_body: the full body at the surrogate optima (K > 1: the best
// verify_candidates), the best kept.
FullBest verify_full_body(Evaluator& ev, const std::vector<Candidate>& found);

// --- Stage 10, full_body_grid (one card, full_grid > 0): a grid of shapes (and Poisson ratios)
// compressed in the full body with the modulus scaled in closed form; its best replaces `best`
// when it is better, with its Poisson ratio.
struct GridOutcome {
  FullBest best;
  double nu = 0;
};
GridOutcome full_body_grid(Evaluator& ev, const FullBest& best);

// --- Stage 11, space_mapping (space_mapping > 0): the surrogate times the measured full-body /
// surrogate ratio refitted, the full body rerun there.
FullBest space_mapping(Evaluator& ev, const FullBest& best);

// --- Stage 12, refine_full_body (full_iterations > 0): Levenberg-Marquardt through the full
// body from the best shapes. Returns the refined shapes, their curve and error.
FullBest refine_full_body(Evaluator& ev, const std::vector<CardShape>& from);

// --- FitMethod::kStatic (calibration_static.cc): the whole fit after the problem is set up;
// fills r (cards, groups, moduli, volume terms, curves and errors) and sets ev.nu to the
// fitted body's Poisson ratio.
void static_fit(Evaluator& ev, FitResult* r);

}  // namespace conica::lab::detail
