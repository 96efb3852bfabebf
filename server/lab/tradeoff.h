// Speed against accuracy: the same experiment run with each integrator x substeps x spring law x
// resolution, timed per tick and compared with a converged reference; the Pareto front of step
// time against error; and the planner that picks the cheapest setting meeting an error tolerance
// within a tick budget. Core only: no file I/O, no logging (CSV is parsed from and written to
// strings).
//
// Experiments (force per tick, N):
//  - compression: a box lattice between frictionless rigid plates. The base is clamped, the top
//    face's nodes are held in z at the top plate and free to slide in x and y; the plate moves
//    down at a constant rate to a fixed engineering strain, then holds. Force = the z-force the
//    springs put on the top face (compression positive). No penalty stiffness enters, so every
//    setting compresses exactly the same body.
//  - indentation: probe 0 moves from `at` along `axis` to `depth` at a constant rate, then
//    holds. Force = the force on the probe (3 components).
// Error of a run against its reference (same experiment, same spring law):
//   error = max_t |F(t) - F_ref(t)| / max_t |F_ref(t)|
// the largest force difference over the whole loading curve (every tick, 3-vector norm),
// relative to the reference's peak force: a relative L-infinity norm over the curve.
#pragma once

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "core/body.h"
#include "core/model.h"

namespace conica::lab {

// What one run produced.
struct Trace {
  std::vector<Vec3> force;      // (ticks) N, see above
  double tick_us_median = 0;    // us, median wall time of one tick (all its substeps)
  double cpu_us_mean = 0;       // us, thread CPU time per tick, mean over the run
  std::uint64_t rollbacks = 0;  // guard trips
  bool finite = true;           // every force finite
};

// Compression of `model` built by compression_body: the top face (nodes at the highest rest z,
// held in z) driven to `strain` (engineering, of the body height) in `ramp_s` seconds, then held
// until `ticks` ticks have run. The top moves once per tick.
Trace run_compression(const Model& model, double strain, double ramp_s, long ticks);

// Indentation by probe 0 of `model`: centre at `at` (m) at t = 0, moved along the unit `axis` to
// `depth` (m) in `ramp_s` seconds, then held until `ticks` ticks have run.
Trace run_indentation(const Model& model, const Vec3& at, const Vec3& axis, double depth,
                      double ramp_s, long ticks);

// The compression body: a box of `size` (m, min corner at the origin) split into `cells`, with
// the spring groups, density, mapping and solver options of `material` (its mesh, selectors,
// probes and plates are dropped). Base (z = 0) clamped, top face (z = size.z) held in z.
BodySpec compression_body(const BodySpec& material, const Vec3& size,
                          const std::array<int, 3>& cells);

// The same spec with every conical card replaced by its Hooke twin: k = the card's K0 (N/m),
// length = its free length L0, same damping and Maxwell branch.
BodySpec hooke_twin(const BodySpec& spec);

// max_t |f(t) - ref(t)| / max_t |ref(t)|, over the common length. NaN if any force is not
// finite; 0 when the reference is identically zero and f equals it.
double force_error(const std::vector<Vec3>& f, const std::vector<Vec3>& ref);

// Spike-robust error: sqrt(sum_t |f(t) - ref(t)|^2) / sqrt(sum_t |ref(t)|^2), the RMS of the
// per-tick difference over the reference's RMS (a relative L2 norm over the curve). A short
// contact spike of a few ticks moves it by about sqrt(ticks in the spike / all ticks) of its
// height instead of by its full height. NaN if any force is not finite.
double force_rms_error(const std::vector<Vec3>& f, const std::vector<Vec3>& ref);

// Maps `nodes` onto the frame of `target` by their principal axes: centroids matched, principal
// axes aligned (of the four proper sign choices the one with the smallest mean nearest-node
// distance), scaled by the mean ratio of the principal standard deviations. For comparing two
// meshes of one organ given in different frames and units. Returns the mean nearest-node
// distance (m) from `target`'s nodes to the mapped ones.
double register_principal_axes(std::vector<Vec3>* nodes, const std::vector<Vec3>& target);

// One setting of the sweep and what it measured: one CSV row.
struct TradeoffRow {
  std::string scene;       // experiment: "compression" or "indentation"
  std::string resolution;  // "20mm", "liver2", ...
  int nodes = 0, springs = 0;
  std::string integrator;  // "symplectic", "explicit", "implicit"
  int newton = 0, cg = 0;  // implicit budgets per step (0 for explicit integrators)
  int substeps = 1;        // steps per 1 ms tick
  std::string law;         // "conical" or "hooke"
  double step_us = 0;      // us, median wall time per tick
  double error = 0;        // relative, see above (NaN when a force went non-finite)
  bool stable = true;      // no rollback, finite, peak force at most 2x the reference's
  double cpu_us = 0;       // us, mean thread CPU time per tick
  std::uint64_t rollbacks = 0;
  double rms_error = std::numeric_limits<double>::quiet_NaN();  // force_rms_error (NaN: not
                                                                // in the data)
};
// The error the Pareto front and chart use: rms_error when known, else error.
double front_error(const TradeoffRow& row);

// "scene,resolution,nodes,springs,integrator,newton,cg,substeps,law,step_us,error,stable,cpu_us,
// rollbacks,rms_error\n"
std::string tradeoff_csv_header();
std::string to_csv(const TradeoffRow& row);  // one line with '\n'
// Parses a CSV with that header (column order free; extra columns ignored). On error returns
// false and says where in *error ("line 7: column 'error': not a number: x").
bool parse_tradeoff_csv(const std::string& text, std::vector<TradeoffRow>* rows,
                        std::string* error);

// Indices of the stable rows with a finite front_error that no other stable row beats on both
// step time and front_error (<= on both, < on one), sorted by step time.
std::vector<int> pareto_front(const std::vector<TradeoffRow>& rows);

// The planner. Candidates: stable rows of `scene` with `law`. A candidate's cost for the target
// scene is its measured step time times `cost_scale` (the target's measured step time over the
// data's time for the same setting at the finest resolution, or the spring-count ratio when the
// data has no such setting); its error is the measured error at its resolution.
struct PlanRequest {
  std::string scene;        // "compression" or "indentation"
  std::string law;          // "conical" or "hooke"
  double tolerance = 0.05;  // relative force error
  double budget_us = 1000;  // us per tick
  double cost_scale = 1;    // target tick time / data tick time
};

struct PlanCandidate {
  int row = -1;        // index into the rows
  double cost_us = 0;  // predicted for the target scene
  double error = 0;
};

struct Plan {
  bool found = false;
  PlanCandidate chosen;                   // when found: the cheapest meeting both limits
  std::vector<PlanCandidate> runners_up;  // the next cheapest that meet both (up to 3)
  // When nothing meets both: the cheapest meeting the tolerance (over budget) and the most
  // accurate within the budget (over tolerance), when they exist.
  std::vector<PlanCandidate> closest;
  int candidates = 0;  // rows considered
};

// Precondition: tolerance > 0, budget_us > 0, cost_scale > 0.
Plan plan(const std::vector<TradeoffRow>& rows, const PlanRequest& request);

}  // namespace conica::lab
