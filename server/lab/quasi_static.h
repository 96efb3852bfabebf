// Quasi-static loading of a body: the boundary is moved in increments and the body is brought to
// equilibrium after each one, so a force curve does not depend on a rate, inertia or damping.
// Used by `conica-lab compress --bonded` / `--quasi-static` and `conica-lab indent`, the tests
// that are compared with continuum references (docs/validation.md). Core only: no I/O, no
// logging.
//
// Each equilibrium iteration is one implicit (backward Euler) step from rest velocities with a
// long time step: its Newton iterations solve K dx = f with the small mass term M / h^2 as a
// regulariser. An increment starts from the last one's displacement extrapolated linearly, and is
// converged when the out-of-balance force on the free nodes is below `tolerance` times the
// reaction (root of the sum of squares over free axes).
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

struct QuasiStaticOptions {
  int samples = 20;          // increments (equal travel), each a curve point
  double tolerance = 1e-4;   // out-of-balance force / reaction for an increment to converge
  int max_iterations = 300;  // equilibrium iterations per increment at most
  double dt = 1.0;           // s, the implicit step of an iteration (a regulariser only)
  int newton_iterations = 4;
  int cg_iterations = 400;
};

struct QuasiStaticStats {
  long steps = 0;  // implicit steps taken in all
  int increments = 0;
  int unconverged = 0;          // increments that hit max_iterations
  double worst_residual = 0;    // largest final out-of-balance / reaction over the increments
  std::uint64_t rollbacks = 0;  // guard trips
  std::uint64_t hard_stops = 0;
  std::vector<Vec3> positions;  // m, at the end
};

// Sets the boundary of `state` to travel u (m) from rest.
using LoadFn = std::function<void(const Model&, State&, double u)>;
// The reaction (N, positive against the travel) after a force pass.
using ReactionFn = std::function<double(const Model&, const State&, const Workspace&)>;

// The curve of reaction against travel from 0 to `travel` (m) in options.samples increments
// (samples + 1 points, the first at 0). The model's integrator settings are replaced by the
// quasi-static ones above; its elements, springs, contacts and hard stop are kept.
Curve quasi_static_curve(const Model& model, const LoadFn& load, const ReactionFn& reaction,
                         double travel, const QuasiStaticOptions& options,
                         QuasiStaticStats* stats = nullptr);

// Plane 0 (the moving plate, ensure_top_plate) bonded to the body's face under it and placed on
// it, and the opposite face clamped: a bonded compression. Returns what is wrong, empty on
// success.
std::string bond_compression_plates(BodySpec* spec);

// Compression by plane 0 (plate travel u along its normal) between its starting offset (the
// body's face) and the rest, with the force on it: a LoadFn and a ReactionFn for it.
LoadFn plate_load(const Model& model);
ReactionFn plate_reaction();

// A flat rigid punch of `radius` (m) on the body's top face (highest z), centred on the face's
// bounding box and pressing along -z: the top nodes within the radius of its axis (at rest) are
// driven in z (punch_bonded: held in x and y too, no slip). The base (lowest z) is clamped
// (base_bonded) or held in z only, with a node near its centre held in x and y and one beside it
// in y against rigid motion. Adds the selectors to `spec` and the punch nodes to *punch.
// Returns what is wrong (no node under the punch), empty on success.
std::string add_flat_punch(BodySpec* spec, double radius, bool punch_bonded, bool base_bonded,
                           std::vector<int>* punch);

// The punch's load (travel u down) and reaction (N, upward force of the body on the punch).
LoadFn punch_load(const std::vector<int>& punch);
ReactionFn punch_reaction(const std::vector<int>& punch);

}  // namespace conica::lab
