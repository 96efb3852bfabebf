// Fitting a body's conical spring card to measured force-displacement curves (the Ecoflex
// phantom compression tests of shared/data/phantoms, or any curve of the same form).
//
// Identifiability. Under the strain mapping a body's stress depends on a card only through its
// column law sigma(eps) = P(L0 eps) / L0^2. In the law's own units
//     P / Pt = f(delta / S; rho),   rho = D1 / D2,   Pt = G d^4 S / (64 n_a r2^3)
// (the transition delta_t / S = (1 + rho)(1 + rho^2) / 4 and the whole nonlinear branch depend on
// rho alone), so sigma(eps) = (Pt / L0^2) f(eps L0 / S; rho) has exactly three free numbers:
//     modulus  E_c = K0 / L0 (Pa)  the column's linear-phase stiffness: G and d enter only as G d^4
//     taper    rho = D1 / D2       the shape of the stiffening: where along the stroke it starts
//                                  and how fast it grows
//     stroke   s   = S / L0        the column strain at which the card bottoms
// Any two cards with the same (E_c, rho, s) give the same body, whatever their G, d, n_a, D2 or
// L0. The fit therefore varies (E_c, rho, s) and keeps D2, L0, n_a and stiffness_cap of the
// scene's card: D1 = rho D2; d from the solid height Ls = (1 - s) L0 = sqrt((n_a d)^2 -
// (r2 - r1)^2) (Type I; s = 1 is the Type I/II boundary); G from K0 = E_c L0. At fixed (rho, s)
// every force is proportional to E_c, which gives the starting modulus in closed form.
#pragma once

#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "core/body.h"
#include "lab/compression.h"

namespace conica::lab {

// Parses a compression test CSV (header lines, then a column header naming `Compression (mm)`
// and `Load (N)`, then numbers) into displacement (m) and force (N), keeping the loading branch
// (up to the largest compression). Returns false with a message on malformed input.
bool parse_force_curve(std::string_view text, Curve* out, std::string* error);

// The identifiable parameters of a conical card (see above).
struct CardShape {
  double modulus = 0;  // E_c = K0 / L0, Pa
  double taper = 0;    // rho = D1 / D2, in (0, 1)
  double stroke = 0;   // s = S / L0, in (0, 1]
};
CardShape shape_of(const ConicalCard& card);
// `base` with D1, d and G set from `shape`; D2, L0, n_a kept. The result may be invalid for
// shapes out of range (check with validate()).
ConicalCard card_with_shape(const ConicalCard& base, const CardShape& shape);

// Bounds of the search (a shape outside them is never tried).
struct ShapeBounds {
  double taper_min = 0.02, taper_max = 0.95;
  double stroke_min = 0.2, stroke_max = 1.0;
};

struct FitOptions {
  double max_strain = 0.5;   // fit up to this engineering strain of the body
  int points = 50;           // displacement grid: points equal steps up to max_strain
  double skip_strain = 0.03; // the error and residuals leave out grid points below this strain
                             // (the seating toe of a test, where the load is near zero)
  int max_iterations = 100;  // Levenberg-Marquardt on the surrogate
  int full_iterations = 3;   // Levenberg-Marquardt through the full body (0: verify only;
                             // < 0: no full-body run at all)
  double rate = 500e-3 / 60; // m/s, plate speed of the full-body compression
  ShapeBounds bounds;
  std::function<void(const std::string&)> progress;  // one line per stage / iteration
};

struct FitResult {
  CardShape shape;
  ConicalCard card;               // the fitted card (of every conical group)
  std::vector<double> grid;       // (points) plate travel, m
  std::vector<double> data;       // (points) mean measured force, N
  std::vector<double> surrogate;  // (points) cell model force, N
  std::vector<double> full;       // (points) full-body force, N (empty without a full run)
  int first = 0;                  // first grid index in the error (skip_strain)
  double surrogate_error = 0;     // average relative error of the surrogate, fraction
  double full_error = -1;         // of the full body, fraction (-1: not run)
  double surrogate_error_before_refine = -1;  // surrogate error at the surrogate optimum
  double full_error_before_refine = -1;       // full-body error at the surrogate optimum
  int evaluations = 0;            // surrogate curves computed
  int full_evaluations = 0;       // full-body compressions run
  std::string error;              // why the fit could not run (empty: it ran)
};

// The paper's metric: mean over i >= first of |model_i - data_i| / data_i.
double average_relative_error(const std::vector<double>& model, const std::vector<double>& data,
                              int first);

// Mean of the curves' forces at each displacement of `grid` (linear interpolation). Returns
// false when a curve does not reach the end of the grid.
bool mean_curve(const std::vector<Curve>& curves, const std::vector<double>& grid,
                std::vector<double>* mean, std::string* error);

// Force of `spec`'s body predicted by the cell surrogate at plate travel `grid` (m), with every
// conical group's card replaced by `card`: cell stress times the body's cross-section.
std::vector<double> surrogate_force(const BodySpec& spec, const ConicalCard& card,
                                    const std::vector<double>& grid);

// Fits the conical card of `spec` (every conical group gets the fitted card; the spec must have
// a top plate, see ensure_top_plate) to the mean of `curves`: a grid search over (taper, stroke)
// with the modulus in closed form, Levenberg-Marquardt (Ceres) on the cell surrogate, then a
// full-body compression to verify and, with full_iterations > 0, Levenberg-Marquardt through
// the full body from the surrogate's optimum.
FitResult calibrate(const BodySpec& spec, const std::vector<Curve>& curves,
                    const FitOptions& options);

// The card as a scene fragment: group { name: "..." card { conical { ... } stiffness_cap: ... } }.
std::string card_fragment(const std::string& group_name, const SpringCard& card);

}  // namespace conica::lab
