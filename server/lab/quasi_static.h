// Quasi-static loading of a body: the boundary is moved in increments and the body is brought to
// elastic equilibrium after each one, so a force curve does not depend on a rate, inertia or
// damping. The one quasi-static solver of the lab: `conica-lab compress --bonded` /
// `--quasi-static` / `--static`, `conica-lab indent`, the calibration's full-body runs
// (static_compression_curve) and the tests compared with continuum references
// (docs/validation.md). Core only: no I/O, no logging.
//
// Each equilibrium iteration is one implicit (backward Euler) step from rest velocities with a
// long time step: its Newton iterations solve K dx = f with the small mass term M / h^2 as a
// regulariser (pseudo-transient continuation; it also keeps a body's free rigid rotation about
// the load axis bounded). Card damping and Maxwell branches are left out: they change the path
// to an equilibrium, not the elastic equilibrium (the long-term response). An increment starts
// from the last one's displacement extrapolated linearly; it has settled when
//  - Settle::kOutOfBalance: the out-of-balance force on the free nodes (root of the sum of
//    squares over free axes) is below `tolerance` times the reaction, or
//  - Settle::kReactionSteady: the reaction changes by less than `tolerance` (relative) between
//    two iterations (cheaper with inexact Newton steps; the calibration's choice).
// Frictional plates (PlaneSpec::friction) map every iteration's slip from the stick points of the
// last equilibrium and keep the ones where the increment settles (the friction law is
// path-dependent: the increments are its load steps).
// An increment that does not settle within max_iterations is redone from the last equilibrium in
// 2, 4, ... max_parts parts; if it still does not, it is counted as unconverged.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "core/body.h"
#include "core/model.h"
#include "lab/compression.h"

namespace conica {
struct Workspace;
}

namespace conica::lab {

enum class Settle { kOutOfBalance, kReactionSteady };

struct QuasiStaticOptions {
  int samples = 20;  // increments (equal travel), each a curve point
  Settle settle = Settle::kOutOfBalance;
  double tolerance = 1e-4;   // of the settle criterion (relative)
  int max_iterations = 300;  // equilibrium iterations per increment (or part) at most
  int max_parts = 16;        // an unsettled increment is redone in 2, 4, ... max_parts parts
  double dt = 1.0;           // s, the implicit step of an iteration (a regulariser only)
  int newton_iterations = 4;
  int cg_iterations = 400;
  double cg_tolerance = 1e-10;  // relative residual of each Newton step's conjugate gradient
  // Stop at the first increment that finds no equilibrium (QuasiStaticStats::failed_at): the
  // curve ends with it, instead of spending the iteration budget on every increment past it.
  bool stop_at_failure = false;
  // Called after each increment with its number (1-based), travel u (m), final settle value
  // (relative), whether it settled and the implicit steps taken so far: for a progress line.
  std::function<void(int, double, double, bool, long)> progress;
};

// An increment whose settle criterion ends above this did not find an equilibrium at all (a body
// that collapsed or blew up), rather than settling a little short of the tolerance.
inline constexpr double kQuasiStaticFailure = 1e-2;

struct QuasiStaticStats {
  long steps = 0;  // implicit steps taken in all
  int increments = 0;
  int unconverged = 0;        // increments that did not settle, even in max_parts parts
  double worst_residual = 0;  // largest final value of the settle criterion over the increments
  // m, travel of the first increment left out of balance by more than kQuasiStaticFailure of the
  // reaction (-1: none): no equilibrium there, so the curve past it is no result.
  double failed_at = -1;
  std::uint64_t rollbacks = 0;  // guard trips
  std::uint64_t hard_stops = 0;
  double step_seconds = 0;      // s, wall time spent in step() in all
  std::vector<Vec3> positions;  // m, at the end
};

// Sets the boundary of `state` to travel u (m) from rest.
using LoadFn = std::function<void(const Model&, State&, double u)>;
// The reaction (N, positive against the travel) after a force pass.
using ReactionFn = std::function<double(const Model&, const State&, const Workspace&)>;
// Called with the state at the end of every increment (e.g. to record a penetration).
using IncrementFn = std::function<void(const Model&, const State&)>;
// Called after every increment (after the IncrementFn): true ends the loading there; the curve's
// points past it are left at zero and stats count the increments taken.
using StopFn = std::function<bool()>;

// The curve of reaction against travel from 0 to `travel` (m) in options.samples increments
// (samples + 1 points, the first at 0). The model's integrator settings are replaced by the
// quasi-static ones above and its cards lose damping and Maxwell branches; its elements, springs,
// contacts and hard stop are kept.
Curve quasi_static_curve(const Model& model, const LoadFn& load, const ReactionFn& reaction,
                         double travel, const QuasiStaticOptions& options,
                         QuasiStaticStats* stats = nullptr, const IncrementFn& increment = {},
                         const StopFn& stop = {});

// Plane 0 (the moving plate, ensure_top_plate) bonded to the body's face under it and placed on
// it, and the opposite face clamped: a bonded compression. Returns what is wrong, empty on
// success.
std::string bond_compression_plates(BodySpec* spec);

// Compression by plane 0 (plate travel u along its normal) between its starting offset (the
// body's face) and the rest, with the force on it: a LoadFn and a ReactionFn for it.
LoadFn plate_load(const Model& model);
ReactionFn plate_reaction();

// A flat rigid punch of `radius` (m) on the body's top face (highest z), centred on the face's
// bounding box and pressing along -z: every node of each element face on the top plane whose
// centre lies within the radius of its axis (at rest) is driven in z (punch_bonded: held in x and
// y too, no slip): whole faces, as `fem-reference` drives its quadratic faces, so both press the
// same area (on a lattice coarse against the radius, a smaller one than the disc; *area, m^2,
// when given). The base (lowest z) is clamped (base_bonded) or held in z only, with a node near
// its centre held in x and y and one beside it in y against rigid motion. Adds the selectors to
// `spec` and the punch nodes to *punch. Returns what is wrong (no face under the punch), empty
// on success.
// PunchRule::kNodes drives the top nodes within the radius instead (the faces between them
// rigid, the ring of faces around ramping down: a smaller punch on a coarse lattice; the two
// rules meet as the lattice is refined).
enum class PunchRule { kFaces, kNodes };
std::string add_flat_punch(BodySpec* spec, double radius, bool punch_bonded, bool base_bonded,
                           std::vector<int>* punch, double* area = nullptr,
                           PunchRule rule = PunchRule::kFaces);

// The punch's load (travel u down) and reaction (N, upward force of the body on the punch).
LoadFn punch_load(const std::vector<int>& punch);
ReactionFn punch_reaction(const std::vector<int>& punch);

// A frictionless flat punch of `radius` (m) pressed `depth` (m) into the body of `spec` with its
// base bonded (add_flat_punch with `rule`), in one quasi-static increment settled to 1e-6 of the
// reaction: the small-strain indentation of the validation cases.
struct PunchPress {
  double force = 0;        // N, the body's reaction on the punch
  double area = 0;         // m^2, what the punch drives (add_flat_punch)
  std::vector<Vec3> rest;  // m, the nodes at rest
  std::vector<Vec3> x;     // m, and pressed
};
// Returns what is wrong (the punch, the model, no convergence), empty on success.
std::string press_flat_punch(BodySpec spec, double radius, double depth, PunchRule rule,
                             PunchPress* out);

}  // namespace conica::lab
