// calibrate() (lab/calibration.h) as its pipeline of stages (lab/calibration_stages.h), and the
// stages that set the problem up: the body, the target curve, its column floors, the volume
// rule and the stroke bounds.
#include <cmath>

#include "lab/calibration_stages.h"

namespace conica::lab {
namespace detail {

Prepared prepare_body(const BodySpec& spec, const std::vector<Curve>& curves, const FitOptions& o) {
  Prepared out;
  const SpringGroupSpec* conical = nullptr;
  for (const auto& g : spec.groups)
    if (g.card.law == LawKind::kConical && !conical) conical = &g;
  if (!conical) {
    out.error = "the scene has no conical spring group to fit";
    return out;
  }
  if (spec.mapping != Mapping::kStrain) {
    out.error = "calibration needs the strain mapping (a raw-mapped body depends on resolution)";
    return out;
  }
  if (curves.empty() || o.points < 4 || !(o.max_strain > 0 && o.max_strain < 1)) {
    out.error = "need at least one curve, points >= 4 and 0 < max_strain < 1";
    return out;
  }
  if (o.cards < 1 || o.cards > 3) {
    out.error = "cards must be 1, 2 or 3";
    return out;
  }
  const int K = o.cards;
  out.base = conical->card.conical;
  if (std::string e; split_groups(spec, std::vector<ConicalCard>(K, out.base), &e).empty()) {
    out.error = e;
    return out;
  }
  Model body;
  if (std::string e = build_model(spec, &body); !e.empty() || body.planes.empty()) {
    out.error = e.empty() ? "the scene has no plate" : e;
    return out;
  }
  out.geo = {plate_height(body), cross_section(body)};
  say(o, "body: height " + fmt(out.geo.height * 1e3) + " mm, cross-section " +
             fmt(out.geo.area * 1e6) + " mm^2, " + std::to_string(body.num_nodes()) + " nodes, " +
             std::to_string(body.num_springs()) + " springs; " + std::to_string(K) + " card(s)" +
             (K > 1 && o.tie_taper ? ", one shared taper" : ""));
  return out;
}

// Common grid and the mean measured curve.
Target build_target(const std::vector<Curve>& curves, const BodyGeometry& geo,
                    const FitOptions& o) {
  Target t;
  const int n = o.points;
  t.grid.resize(n);
  for (int k = 0; k < n; ++k) t.grid[k] = o.max_strain * geo.height * (k + 1) / n;
  if (!mean_curve(curves, t.grid, &t.data, &t.error)) return t;
  t.first = 0;
  while (t.first < n && t.grid[t.first] < o.skip_strain * geo.height * (1 - 1e-12)) ++t.first;
  if (n - t.first < 4) {
    t.error = "fewer than 4 grid points above skip_strain";
    return t;
  }
  for (int k = t.first; k < n; ++k)
    if (!(t.data[k] > 0)) {
      t.error = "measured force <= 0 at " + fmt(t.grid[k] * 1e3) + " mm";
      return t;
    }
  return t;
}

Floors column_floors(const Target& t, const BodyGeometry& geo, const FitOptions& o) {
  Floors out;
  const int n = static_cast<int>(t.grid.size());
  std::vector<double> strain(n);
  for (int k = 0; k < n; ++k) strain[k] = t.grid[k] / geo.height;
  out.plain = column_floor(strain, t.data, t.first, geo.area, o.bounds);
  out.precompressed = column_floor(strain, t.data, t.first, geo.area, o.bounds, true);
  for (const ColumnFloor* f : {&out.plain, &out.precompressed}) {
    say(o, std::string("column floor") + (f == &out.plain ? "" : ", pre-compressed laws too") +
               ": the best sum of conical laws in parallel along the load (none past its "
               "stroke) has average relative error " +
               fmt(100 * f->error, 4) + " % (" + std::to_string(f->shapes.size()) +
               " laws: " + shapes_text(f->shapes) + ")");
  }
  return out;
}

// Volume stiffness: the scene's Poisson ratio (or the asked one) kept as the cards change, so
// that kappa scales with the spring moduli and forces stay proportional to a common factor.
VolumeRule volume_rule(const BodySpec& spec, const FitOptions& o) {
  VolumeRule v;
  const LatticeModuli scene_moduli = lattice_moduli(spec.groups);
  v.shear_ratio = spec.shear_modulus / lattice_shear(scene_moduli);
  v.with_volume = o.poisson >= 0 || spec.bulk_modulus > 0;
  v.scene_nu = o.poisson >= 0 ? o.poisson
                              : body_poisson(scene_moduli, spec.bulk_modulus, spec.shear_modulus);
  if (v.with_volume && !(v.scene_nu < 0.5))
    v.error = "Poisson ratio must be < 0.5 (got " + fmt(v.scene_nu) + ")";
  v.spread_ratio = spec.bulk_modulus > 0 ? spec.spread_modulus / spec.bulk_modulus : 0.0;
  return v;
}

// Stroke bounds per card: a family's springs must not reach their stroke (the hard stop) in
// the fitted range; their compressive strain is at most the body's for edges, half of it for
// face diagonals and a third for body diagonals (lateral expansion only lowers them).
std::vector<double> stroke_bounds(int K, const FitOptions& o) {
  const ShapeBounds& B = o.bounds;
  std::vector<double> smin(K);
  for (int c = 0; c < K; ++c) {
    const int f = card_families(K)[c];
    const double share = (f & kEdge) ? 1.0 : (f & kFaceDiagonal) ? 0.5 : 1.0 / 3;
    const double margin = o.method == FitMethod::kStatic ? o.static_stroke_margin : o.stroke_margin;
    smin[c] = std::min(B.stroke_max * 0.99, std::max(B.stroke_min, margin * share * o.max_strain));
  }
  return smin;
}

void describe(Evaluator& ev, const std::vector<CardShape>& sh, FitResult* r) {
  r->shapes = sh;
  r->cards = cards_of(ev.problem().base, sh);
  r->shape = sh[0];
  r->card = r->cards[0];
  r->groups = ev.groups(r->cards);
  r->moduli = lattice_moduli(r->groups);
  const ElementModuli em = ev.element_moduli(r->groups, ev.nu);
  r->bulk_modulus = em.bulk;
  r->spread_modulus = em.spread;
  r->shear_modulus = em.shear;
  r->shear_stiffening = ev.problem().spec.shear_stiffening;
  r->poisson = body_poisson(r->moduli, r->bulk_modulus, r->shear_modulus);
  r->surrogate = ev.surrogate(r->cards);
  r->surrogate_error = ev.error(r->surrogate);
}

}  // namespace detail

FitResult calibrate(const BodySpec& spec, const std::vector<Curve>& curves, const FitOptions& o) {
  using namespace detail;
  FitResult r;
  const Prepared body = prepare_body(spec, curves, o);
  if (!body.error.empty()) {
    r.error = body.error;
    return r;
  }
  const Target target = build_target(curves, body.geo, o);
  r.grid = target.grid;
  r.data = target.data;
  r.first = target.first;
  if (!target.error.empty()) {
    r.error = target.error;
    return r;
  }
  if (o.column_floor) {
    const Floors floors = column_floors(target, body.geo, o);
    r.floor = floors.plain;
    r.floor_precompressed = floors.precompressed;
  }
  const int n = o.points;
  say(o, "data: " + std::to_string(curves.size()) + " curve(s) averaged on " + std::to_string(n) +
             " points up to " + fmt(r.grid.back() * 1e3) + " mm (strain " + fmt(o.max_strain) +
             "), error over points from " + fmt(r.grid[r.first] * 1e3) +
             " mm (strain >= " + fmt(o.skip_strain) + ")");
  const VolumeRule volume = volume_rule(spec, o);
  if (!volume.error.empty()) {
    r.error = volume.error;
    return r;
  }
  const Problem problem{spec,     o,      o.cards, body.base,
                        body.geo, target, volume,  stroke_bounds(o.cards, o)};
  // The body's Poisson ratio: the scene's (or the asked one) until the full-body grid picks one.
  Evaluator ev(problem, volume.scene_nu);
  auto counted = [&] {
    r.evaluations = ev.surrogate_evaluations;
    r.full_evaluations = ev.full_evaluations;
    return r;
  };
  if (volume.with_volume)
    say(o, "volume stiffness: Poisson ratio " + fmt(ev.nu, 4) +
               " kept while fitting (bulk modulus at the scene's card " +
               fmt(ev.bulk_for(spec.groups, ev.nu), 5) + " Pa)");

  if (o.method == FitMethod::kStatic) {
    static_fit(ev, &r);
    return counted();
  }
  // The cell surrogate: one card from a grid, then the candidates for the full body.
  const InitialGuess guess = initial_guess(ev);
  const CardShape one = fit_one_card(ev, guess);
  const std::vector<Candidate> found = surrogate_candidates(ev, guess, one);
  describe(ev, found.front().shapes, &r);
  r.surrogate_error_before_refine = r.surrogate_error;
  say(o, "surrogate fit: average relative error " + fmt(100 * r.surrogate_error, 4) +
             " %: " + shapes_text(r.shapes));
  if (o.full_iterations < 0) return counted();

  // The full body: verify (K > 1: the best few distinct optima), then refine through it.
  FullBest best = verify_full_body(ev, found);
  if (o.cards == 1 && o.full_grid > 0) {
    const GridOutcome grid = full_body_grid(ev, best);
    best = grid.best;
    ev.nu = grid.nu;
  }
  if (!std::isfinite(best.error))
    say(o,
        "no full-body run kept its homogeneous state (layer spread above max_layer_spread) or "
        "finished: the full-body error is not defined for this scene and card family");
  describe(ev, best.shapes, &r);
  r.surrogate_error_before_refine = r.surrogate_error;
  r.full_error_before_refine = best.error;
  if (o.space_mapping > 0 && std::isfinite(best.error)) {
    best = space_mapping(ev, best);
    r.full_error_after_mapping = best.error;
  }
  describe(ev, best.shapes, &r);
  r.surrogate_error_before_refine = r.surrogate_error;
  r.full = best.curve;
  r.full_error = best.error;
  if (o.full_iterations == 0) return counted();
  const FullBest refined = refine_full_body(ev, best.shapes);
  if (refined.error < r.full_error) {
    describe(ev, refined.shapes, &r);
    r.full = refined.curve;
    r.full_error = refined.error;
  }
  say(o, "full body refined: average relative error " + fmt(100 * r.full_error, 4) + " %");
  return counted();
}

}  // namespace conica::lab
