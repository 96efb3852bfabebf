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
//
// Pre-compression (FitOptions::fit_precompression, on by default): a fourth number per card,
// p = delta0 / S in [0, 1): the card's spring sits in the body compressed by delta0 and the column
// law becomes sigma(eps) = (Pt / L0^2) [f(p + eps / s; rho) - f(p; rho)], which stiffens from
// zero strain once p is past the transition (the plain law is linear over the first quarter of
// its stroke at least). What one curve fixes: the curve, the modulus at rest E_c k_t(delta0) / K0
// and the strain left to the solid height, s (1 - p), kept above the largest strain of the
// card's springs; taper, stroke and p trade off along a valley (p comes back within a few
// hundredths of S from a noiseless model curve, test RecoversAKnownPrecompression), as taper
// and stroke already did for the plain law. With several cards the isotropy tie below holds for
// the moduli at rest.
//
// Several cards (FitOptions::cards = K). The scene's conical group is split by lattice family
// (K = 2: edges | face and body diagonals; K = 3: edges | face diagonals | body diagonals), each
// part with its own card, i.e. its own (E_c, taper, stroke): springs of different families in
// parallel, with different transition points, whose sum stiffens smoothly. Every part is still a
// conical spring. What the extra cards add: the families see different strains under uniaxial
// compression (vertical edges the full strain e, face diagonals about (1 - nu) e / 2, body
// diagonals about (1 - 2 nu) e / 3, horizontal edges are stretched), so a card per family can
// place stiffening onsets at several strains; and the diagonal moduli set the lattice's shear
// stiffness (C44 = C12 for pair springs), which decides when the homogeneous state buckles.
// What trades off: one uniaxial curve fixes the uniaxial modulus but not how it splits over the
// families (the split moves the lateral contraction, which is not measured), and within a family
// taper and stroke trade off as for one card. With tie_taper the cards share one taper (2K + 1
// numbers instead of 3K). The lattice's linear moduli (C11, C12, C44) are reported so that the
// split can be judged (isotropy of a cubic pair-spring lattice: C11 - C12 = 2 C44, i.e.
// 4 E_edge = E_face + 8/9 E_body with the family moduli defined below).
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "core/body.h"
#include "lab/compression.h"

namespace conica::lab {

// The identifiable parameters of a conical card (see above), and its pre-compression.
struct CardShape {
  double modulus = 0;         // E_c = K0 / L0, Pa
  double taper = 0;           // rho = D1 / D2, in (0, 1)
  double stroke = 0;          // s = S / L0, in (0, 1]
  double precompression = 0;  // p = delta0 / S, in [0, 1): the card's precompression is p S
};
CardShape shape_of(const ConicalCard& card);
// `base` with D1, d, G and precompression set from `shape`; D2, L0, n_a kept. The result may be
// invalid for shapes out of range (check with validate()).
ConicalCard card_with_shape(const ConicalCard& base, const CardShape& shape);

// Bounds of the search (a shape outside them is never tried).
struct ShapeBounds {
  double taper_min = 0.02, taper_max = 0.95;
  double stroke_min = 0.1, stroke_max = 1.0;  // a card's stroke is also kept above the
                                              // largest strain of its springs in the fit range
  double precompression_max = 0.9;  // p = delta0 / S; the stroke left, (1 - p) s, is also kept
                                    // above the largest strain of the card's springs
};

// Family masks (SpringFamily bits) of the cards of a K-card fit, K = 1..3.
std::vector<int> card_families(int cards);
// "edges", "face-diagonals", "body-diagonals", "diagonals", "all" (for group names).
std::string families_name(int families);

// Linear moduli of a box lattice under the strain mapping (Pa), from the groups' cards and
// families (cubic symmetry; groups with regions or an axis are not allowed and give NaN).
// Per cell each spring of direction d and card modulus E_c = K0 / L0 adds E_c / 28 d_i d_j d_k d_l:
// C11 = (4 E_e + 2 E_f + 4/9 E_b) / 28, C12 = C44 = (E_f + 4/9 E_b) / 28.
struct LatticeModuli {
  double c11 = 0, c12 = 0, c44 = 0;
  double young = 0;       // uniaxial modulus along a cube axis, lateral contraction free
  double poisson = 0;     // lateral contraction ratio along a cube axis
  double anisotropy = 0;  // Zener ratio 2 C44 / (C11 - C12): 1 is isotropic
};
LatticeModuli lattice_moduli(const std::vector<SpringGroupSpec>& groups);

// Small-strain Poisson ratio of a body of lattice `m` with volume stiffness kappa (Pa, added to
// its bulk modulus; core/volume.h), from the isotropic averages K = (C11 + 2 C12) / 3 + kappa and
// G = (C11 - C12 + 3 C44) / 5 (Voigt): nu = (3 K - 2 G) / (2 (3 K + G)).
// mu (Pa): shear stiffness added to G (core/volume.h).
double body_poisson(const LatticeModuli& m, double kappa, double mu = 0);
// The kappa (Pa, >= 0) that gives lattice `m` with added shear stiffness mu the Poisson ratio nu
// (< 1/2): 0 when the springs alone already reach it.
double bulk_for_poisson(const LatticeModuli& m, double nu, double mu = 0);
// The lattice's isotropic (Voigt) shear modulus (C11 - C12 + 3 C44) / 5, Pa.
double lattice_shear(const LatticeModuli& m);

// The column floor: the smallest average relative error (over grid points first..) that any
// sum of conical laws in parallel can reach on a force curve, every law acting as a column along
// the load (spring strain = body strain, no lateral coupling) and none past its stroke in the
// fitted range (stroke >= 1.02 max strain). A conical law is linear for at least the first
// quarter of its stroke, so every such sum is linear up to a quarter of the largest strain:
// a curve that stiffens from the start cannot be followed there. Computed over a basis of
// tapers x strokes (the bounds' ranges) with non-negative moduli, the L1 error minimised by
// iteratively reweighted non-negative least squares (Lawson-Hanson).
// With `precompressed` the basis also holds pre-compressed laws (P(delta0 + delta) - P(delta0),
// delta0 = p S with p over [0, precompression_max], the stroke left (1 - p) S still >= 1.02 x the
// largest strain): they start in their nonlinear phase, so the quarter-stroke linear start above
// no longer binds.
struct ColumnFloor {
  double error = -1;              // fraction; -1: not computed
  std::vector<CardShape> shapes;  // the laws with a nonzero modulus (modulus: share in Pa of
                                  // column stress per unit strain)
  std::vector<double> force;      // the best sum on the grid, N
};
// `strain`: engineering strains of the grid (ascending); `force`: measured force there (N);
// `area`: the body's cross-section (m^2), only to report the moduli in Pa.
ColumnFloor column_floor(const std::vector<double>& strain, const std::vector<double>& force,
                         int first, double area, const ShapeBounds& bounds = {},
                         bool precompressed = false);

// How calibrate() goes through the full body.
enum class FitMethod {
  // The cell surrogate fitted at a few Poisson ratios (poisson_grid), the best one's card
  // compressed in the full body by static equilibrium solves (static_compression_curve), then
  // output space mapping: the surrogate times the full-body / surrogate ratio per grid point
  // refitted and the full body solved again (space_mapping steps), the best full-body curve
  // kept. Every fit minimises the mean absolute relative error (the reported metric) by
  // iteratively reweighted least squares. One card. A few full-body solves in all.
  kStatic,
  // The surrogate optima, then a grid of full-body compressions at the plate rate `rate` with
  // the scene's integrator (full_grid, full_grid_pre, full_grid_poisson) and Levenberg-Marquardt
  // through it (full_iterations): hundreds of dynamic runs.
  kGrid,
};

struct FitOptions {
  FitMethod method = FitMethod::kGrid;
  int cards = 1;              // conical cards, one per family part (see above), 1..3
  bool tie_taper = false;     // the cards share one taper
  bool isotropic = true;      // K > 1: the family moduli satisfy the isotropy condition
                              // 4 E_edge = E_face + 8/9 E_body (K - 1 moduli free instead of K)
  int verify_candidates = 3;  // K > 1: full-body check of this many distinct surrogate optima
                              // (K = 1 with fit_precompression: the pre-compressed and the plain
                              // optimum are both checked),
                              // the best full-body one is kept (full_iterations >= 0)
  double max_strain = 0.5;    // fit up to this engineering strain of the body
  int points = 50;            // displacement grid: points equal steps up to max_strain
  double skip_strain = 0.03;  // the error and residuals leave out grid points below this strain
                              // (the seating toe of a test, where the load is near zero)
  int max_iterations = 100;   // Levenberg-Marquardt on the surrogate
  int full_iterations = 3;    // Levenberg-Marquardt through the full body (0: verify only;
                              // < 0: no full-body run at all)
  int full_grid = 4;          // one card: before the full-body refinement, a grid of full_grid
                              // tapers x full_grid strokes (plain law) is compressed in the full
                              // body, each modulus scaled in closed form, and the best shape kept
                              // as the start when it beats the surrogate optima (0: none). The
                              // surrogate's optimum can sit where the law is linear over the range
                              // (taper and stroke then have no gradient) while the full body,
                              // softer than the cell at large strain, needs the stiffening.
  int full_grid_pre = 3;      // pre-compressions of that grid: 0 and, with fit_precompression,
                              // full_grid_pre - 1 more up to its bound, evenly (1: plain law only)
  int space_mapping = 0;      // output space mapping steps after the full-body check: the
                              // surrogate times the measured full-body / surrogate force ratio
                              // (per grid point) is refitted, and the full body rerun at the new
                              // optimum; one full compression per step (0: none). On the
                              // phantom cylinder it does not converge: the full body's late
                              // collapse makes the ratio depend strongly on the cards.
  bool column_floor = true;   // compute the column floor (see above) of the data, without and
                              // with pre-compressed laws
  bool fit_precompression = true;  // fit each card's pre-compression p = delta0 / S too (a
                                   // fourth number per card); false: p = 0, the plain law
  int full_grid_poisson = 3;       // Poisson ratios of that grid, evenly from poisson_min to the
                              // scene's own (1: the scene's only). Only with volume stiffness and
                              // no `poisson` given: a force curve fixes the body's Poisson ratio
                              // only through the geometric stiffening it brings (an
                              // incompressible body stiffens in compression by itself), which
                              // trades off with the coils' stiffening, so it is searched with the
                              // shape and the best is kept (the fitted body's ratio is reported).
  double poisson_min = 0.41;       // lowest Poisson ratio of that grid
  double max_layer_spread = 0.02;  // a full-body run whose node layers spread by more than
                                   // this fraction of the half width at the end of the travel
                                   // (lab/compression.h layer_spread: it leaned, buckled or its
                                   // layers alternate) has left the homogeneous state, and its
                                   // curve is not used (the fit would owe its shape to it)
  int threads = 0;                 // full-body grid runs in parallel (0: one per hardware thread)
  double rate = 500e-3 / 60;       // m/s, plate speed of the full-body compression
  double poisson = -1;  // the body's small-strain Poisson ratio kept while the cards change,
                        // by the volume stiffness (bulk_for_poisson); < 0: the scene's own
                        // (its cards, bulk_modulus and shear_modulus) and, through the full
                        // body, the best of full_grid_poisson ratios up to it; with no
                        // bulk_modulus in the scene none is added. A scene's shear_modulus
                        // keeps its ratio to the lattice's shear modulus.
  // kStatic: Poisson ratios of the surrogate search, evenly from poisson_max down to
  // poisson_min (the scene's ratio when the scene has no volume stiffness or `poisson` is given).
  int poisson_grid = 5;
  double poisson_max = 0.49;
  int reweightings = 3;         // kStatic: L1 reweightings after each least-squares fit
  double stroke_margin = 1.02;  // a card's stroke is at least this times its springs' largest
                                // strain in the fit range (kStatic uses static_stroke_margin)
  double static_stroke_margin = 1.05;  // kept from when the full bodies' collapse was put down
                                       // to the rim cells' coils (it was the material's lost
                                       // ellipticity: stability_margin)
  // The fitted material stays strongly elliptic (core/stability.h) under uniaxial compression to
  // this times max_strain: where the cell with the cards and the scene's shear share would lose
  // it (its compressed springs' sideways softening beats its shear stiffness, and a body buckles
  // there), the shear term is raised to the least that keeps it. Only for scenes with a shear
  // term; 0: off (the scene's shear share only).
  double stability_margin = 1.02;
  // kStatic, the escalation: the one-card optimum is compressed through the full body as
  // `conica-lab compress --quasi-static --samples body_samples` compresses it (BodyCheck in
  // lab/calibration_stages.h); when its error there is above escalate_above or an increment
  // finds no equilibrium, the escalate_cards-card fit (edges | diagonals families, see above)
  // from it at its Poisson ratio is checked through the full body, then with its moduli scaled
  // by the body's L1-optimal factor, and the best body that settles everywhere is kept (the
  // one-card fit when none beats it). A card that passes is the one-card fit unchanged; the
  // result's full_error is the body check's. 0 (or full_iterations < 0): no full-body check
  // (the surrogate's card).
  double escalate_above = 0;
  int escalate_cards = 3;
  int escalate_mapping = 2;  // output space-mapping steps on the body after that (each one
                             // K-card refit and two body checks), while above escalate_above
  int body_samples = 25;
  double static_tolerance = 1e-5;
  int stroke_raises = 1;       // kStatic: a full body that collapses before the end of the travel
  double stroke_raise = 1.08;  // raises the stroke bound by this factor, at most this often      //
                               // relative plate force change ending a static solve
  ShapeBounds bounds;
  std::function<void(const std::string&)> progress;  // one line per stage / iteration
};

struct FitResult {
  CardShape shape;
  ConicalCard card;                     // the fitted card of the first part (K = 1: the only one)
  std::vector<CardShape> shapes;        // (K) per card
  std::vector<ConicalCard> cards;       // (K)
  std::vector<SpringGroupSpec> groups;  // the fitted groups: the scene's conical group split by
                                        // family, each with its fitted card, in scene order
  LatticeModuli moduli;                 // of the fitted groups
  double bulk_modulus = 0;              // Pa, volume stiffness of the fitted body
  double spread_modulus = 0;      // Pa, its Gauss-point spread stiffness (the scene's ratio to
                                  // bulk_modulus kept)
  double shear_modulus = 0;       // Pa, its shear stiffness (the scene's ratio to the lattice's
                                  // shear modulus kept)
  double shear_stiffening = 0;    // its shear term's stiffening (the scene's, core/volume.h)
  double poisson = 0;             // its small-strain Poisson ratio (body_poisson)
  std::vector<double> grid;       // (points) plate travel, m
  std::vector<double> data;       // (points) mean measured force, N
  std::vector<double> surrogate;  // (points) cell model force, N
  std::vector<double> full;       // (points) full-body force, N (empty without a full run)
  int first = 0;                  // first grid index in the error (skip_strain)
  double surrogate_error = 0;     // average relative error of the surrogate, fraction
  double full_error = -1;         // of the full body, fraction (-1: not run)
  double surrogate_error_before_refine = -1;  // surrogate error at the surrogate optimum
  double full_error_before_refine = -1;       // full-body error at the surrogate optimum
  double full_error_after_mapping = -1;       // full-body error after space mapping (-1: none)
  ColumnFloor floor;                // of the data (options.column_floor), plain conical laws
  ColumnFloor floor_precompressed;  // the same with pre-compressed laws in the basis
  int evaluations = 0;              // surrogate curves computed
  int full_evaluations = 0;         // full-body compressions run
  std::string error;                // why the fit could not run (empty: it ran)
};

// The common factor s on a model curve that minimises the mean relative error against data
// over i >= first (a weighted median); NaN when no point has a positive finite ratio.
double l1_scale(const std::vector<double>& model, const std::vector<double>& data, int first);

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

// Force predicted by the cell surrogate with `groups` in place of the spec's groups.
std::vector<double> surrogate_force(const BodySpec& spec,
                                    const std::vector<SpringGroupSpec>& groups,
                                    const std::vector<double>& grid);

// The spec's groups with its first conical group split into the parts of card_families(cards),
// each with the card `cards[i]` (same regions, axis, cap, damping). Empty on error (a part that
// selects no family).
std::vector<SpringGroupSpec> split_groups(const BodySpec& spec,
                                          const std::vector<ConicalCard>& cards,
                                          std::string* error = nullptr);

// Fits the conical card(s) of `spec` (its first conical group, split into options.cards family
// parts; the spec must have a top plate, see ensure_top_plate) to the mean of `curves`: for one
// card a grid search over (taper, stroke) with the modulus in closed form; for K cards automatic
// starts from the one-card optimum (diagonal strokes and modulus splits on a grid, scale in
// closed form); Levenberg-Marquardt (Ceres) on the cell surrogate from the best starts; then a
// full-body compression to verify (K > 1: the best verify_candidates surrogate optima, keeping
// the best in the full body) and, with full_iterations > 0, Levenberg-Marquardt through the
// full body. The stages, in order, are in lab/calibration_stages.h. No I/O: the curves come from
// io/curve_reader.h, the fitted groups go out through io/scene_writer.h.
FitResult calibrate(const BodySpec& spec, const std::vector<Curve>& curves,
                    const FitOptions& options);

}  // namespace conica::lab
