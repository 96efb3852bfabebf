// Compression experiments on a body: the unconfined uniaxial compression test of the Ecoflex
// phantoms (shared/data/phantoms) run on a model. Core only: no I/O, no logging.
//
// Two ways to compress:
//  - compression_curve: the body between rigid plates, the top plate (the model's plane 0) moved
//    at a constant rate with the model's own integrator and time step, force read from the
//    plate. This is the experiment as it happens, with inertia, damping and contact penalties.
//  - cell_stress_curve: the homogenised (Cauchy-Born) uniaxial stress of the lattice: one cell
//    deformed affinely, diag(lambda, lambda, 1 - e), lambda such that the lateral traction is
//    zero. A hexahedral lattice is a Bravais lattice (every node sees the same neighbourhood), so
//    the affine deformation is an equilibrium of a box between frictionless plates at any strain,
//    and the body's force is this stress times its cross-section, as long as the homogeneous
//    state is stable. A surrogate that costs microseconds, used by the calibration.
#pragma once

#include <cstdint>
#include <vector>

#include "core/body.h"
#include "core/model.h"

namespace conica::lab {

// One point of a force-displacement curve.
struct CurvePoint {
  double displacement = 0;  // m, plate travel from first contact, compression positive
  double force = 0;         // N, on the plate, compression positive
};
using Curve = std::vector<CurvePoint>;

// Drops the points of `curve` at or past plate travel `failed_at` (m; < 0: none), keeping the
// first: what a run that failed there may still report.
void cut_at_failure(Curve* curve, double failed_at);

// Adds a top plate touching the body's highest node (normal -z) when `spec` has no plane.
// Returns true when it added one.
bool ensure_top_plate(BodySpec* spec);

// Penalty stiffness (N/m per node) that makes a plate rigid against `model`'s springs: 1e4 x
// their mean axial stiffness (each card's K0, plus its Maxwell branch when `with_maxwell`),
// capped for explicit integrators so that omega h <= 1 on the lightest node.
double rigid_plate_stiffness(const Model& model, bool with_maxwell);

// Height of the body along plane 0's normal (m): the spread of n.x over the rest nodes.
// Precondition: the model has a plane.
double plate_height(const Model& model);

// Rest volume of the body's elements over plate_height (m^2): the mean cross-section.
double cross_section(const Model& model);

struct CompressionStats {
  long steps = 0;               // steps taken
  double dt = 0;                // s, per step
  double plate_stiffness = 0;   // N/m per node, as used
  double max_penetration = 0;   // m, deepest node behind the moving plate at a sample
  std::uint64_t rollbacks = 0;  // guard trips (should be 0)
  // m, plate travel where the run failed (compression_curve; -1: it did not): the first guard
  // trip (the body held at a last good state while the plate moved on) or the first step with a
  // node behind the rigid plate by more than kBlowUpPenetration of the body's height (a blow-up
  // the guard let through). The curve past it is no result.
  double failed_at = -1;
  std::uint64_t hard_stops = 0;
  double step_seconds = 0;      // s, mean wall time of step() alone
  std::vector<Vec3> positions;  // m, node positions at the end of the travel
  double layer_spread = 0;      // m, layer_spread() at the end of the travel
  double half_width = 0;        // m, the rest body's largest distance from its axis
};

// How far a compressed prism has left the homogeneous state: nodes grouped into layers by rest
// height along plane 0's normal (to 1 um), each layer's largest distance from the axis (the
// normal through the rest centroid) at positions `x`; returns the largest minus the smallest
// (m). Between frictionless plates a homogeneous body's layers all spread alike (0); a body
// that leans, buckles or whose layers alternately bulge and narrow does not.
double layer_spread(const Model& model, const std::vector<Vec3>& x);

// A node this far behind a rigid compression plate, as a fraction of the body's height, means the
// run blew up (the plate's penetration in a sound run is a few micrometres).
inline constexpr double kBlowUpPenetration = 0.01;

// Moves plane 0 of `model` from the body's top (first contact) into the body at `rate` (m/s)
// until the plate has travelled to_strain * plate_height, stepping with the model's integrator
// at its own time step. Returns samples + 1 points at equal plate travel (the first at 0),
// force = -n . (force on the plate), linearly interpolated between steps.
// A plate penalty below 1e4 times the mean axial spring stiffness is raised to it (the scene
// default is sized for explicit stability, far too soft to act as a rigid plate), for explicit
// integrators no further than omega h = 1 on the lightest node: the plate then penetrates the
// body by a fraction of its travel, reported in stats (small with the implicit solver).
// served: a multi-rate model (solver body_rate_hz > 0) is stepped as the server's body thread
// steps it (core/multirate.h): body_model's step of 1 / body_rate_hz, its Newton cap and
// tolerance, and its factor renewed by step_body's rule; the compression through exactly the
// served configuration.
// Precondition: the model has a plane; rate > 0; 0 < to_strain < 1; samples >= 1.
Curve compression_curve(const Model& model, double rate, double to_strain, int samples,
                        CompressionStats* stats = nullptr, bool served = false);

// The same test quasi-statically, through the lab's quasi-static solver (lab/quasi_static.h):
// the frictionless plate is set at each of `samples` equal steps of travel up to to_strain *
// plate_height and the body brought to elastic equilibrium there, starting from the last one
// (continuation in strain, each solve warm-started and extrapolated). Each solve is a sequence
// of backward Euler steps of dt = `dt_s` (two Newton iterations each, the conjugate gradient to a
// relative residual of 1e-4 at least) repeated until the plate force changes by less than
// `tolerance` (relative) between two steps (Settle::kReactionSteady), at most `max_steps` times
// per increment, an unsettled increment redone in smaller parts. The plate is made rigid as in
// compression_curve. Returns samples + 1 points (the first at 0); stats->steps counts every step
// taken. A static answer has no rate: the plates of the phantom tests move at 10 mm/min, slow
// enough for the silicone's viscous terms to be left out (the calibration fits its elastic card
// to them).
// Precondition: the model has a plane; 0 < to_strain < 1; samples >= 1.
Curve static_compression_curve(const Model& model, double to_strain, int samples,
                               CompressionStats* stats = nullptr, double tolerance = 1e-5,
                               int max_steps = 15, double dt_s = 1.0);

// Stability of the body along its quasi-static compression (core/stability.h,
// equilibrium_stability): plane 0 moved as in static_compression_curve, in `samples` equal
// increments to to_strain, and at each increment's equilibrium the count of the body's modes
// along which its energy falls. A body whose material keeps strong ellipticity can still buckle
// as a whole between the plates (its faces sliding sideways on frictionless plates, a short
// column's shear buckling) or at its surface; past that strain a dynamic or served run leaves the
// homogeneous path and a quasi-static one follows a branch that no real run takes.
struct CompressionEquilibria {
  double stable_to = 0;     // the largest strain checked with no such mode before any had one
  double unstable_at = -1;  // the first strain where one was found (-1: none up to to_strain)
  int modes = 0;            // how many there
  int checked = 0;          // increments checked
  bool factored = true;     // every check's factor succeeded
};
CompressionEquilibria compression_equilibria(const Model& model, double to_strain, int samples);

// The lattice cell of `groups` (a 1 x 1 x 1 hexahedron of side `side`, all 28 springs, the
// given mapping, volume and shear stiffness bulk_modulus and shear_modulus in Pa, the shear
// term's stiffening shear_stiffening (dimensionless, core/volume.h); a uniform
// deformation leaves the Gauss-point spread at zero), its base held along z, one corner pinned
// against rigid motion. Returns the build error, empty on success.
std::string make_uniaxial_cell(const std::vector<SpringGroupSpec>& groups, Mapping mapping,
                               double side, Model* cell, double bulk_modulus = 0,
                               double shear_modulus = 0, double shear_stiffening = 0);

// Homogenised engineering stress (Pa, compression positive, over the rest cross-section) of the
// cell at each compressive engineering strain in `strains` (ascending, each in [0, 1)): the cell
// deformed affinely, the lateral stretch solved (secant) for zero lateral traction. Assumes the
// cell's spring groups respect the cubic symmetry in x and y (true for one card).
std::vector<double> cell_stress_curve(const Model& cell, const std::vector<double>& strains);

}  // namespace conica::lab
