// Internals shared by the stages of the step (one file each, see step.h); not an API.
//   springs.cc         spring geometry, law, dampers, Maxwell branches -> ws.force
//   element_terms.cc   volume, spread and shear terms of the elements -> ws.force (element_terms.h)
//   contact_stage.cc   probes (node law, surface proxies) and planes -> ws.force, layer blocks
//   region.cc          the active region and the multi-rate far field (state in State::region)
//   integrate.cc       explicit integrators and the guard; implicit.cc: backward Euler
//   hard_stop.cc       the solid-height projection
//   compile.cc         the Workspace: what is derived from the Model, and scratch
//   step.cc            step() as the list of stages
#pragma once

#include <bit>
#include <chrono>
#include <cstdint>
#include <limits>
#include <vector>

#include "core/step.h"

namespace conica::detail {

// Time step of one substep, s.
inline double substep_of(const Model& m) { return m.options.dt / m.options.substeps; }
// Whether the next implicit step from s is a BDF2 step (SolverOptions::bdf2 with the previous
// step in the state), and the step its system is solved with: the substep, or 2 / 3 of it.
inline bool bdf2_step(const Model& m, const State& s) {
  return m.options.bdf2 && s.has_prev && s.x_prev.size() == s.x.size();
}
inline double implicit_h(const Model& m, const State& s) {
  return bdf2_step(m, s) ? substep_of(m) * (2.0 / 3.0) : substep_of(m);
}
// Where a BDF2 step of node i starts, as backward Euler of step 2h / 3 (core/implicit.cc):
// x^ - x_n = (x_n - x_n-1) / 3 and v^ = (4 v_n - v_n-1) / 3 (all axes).
inline Vec3 bdf2_start_shift(const State& s, int i) { return (s.x[i] - s.x_prev[i]) / 3.0; }
inline Vec3 bdf2_start_velocity(const State& s, int i) {
  return (4.0 * s.v[i] - s.v_prev[i]) / 3.0;
}

// The smallest room (length - min_length) of a set of springs is reduced as the int64 bit
// patterns of the doubles: for rooms >= 0 their order is the doubles' order, any negative room
// gives a negative pattern (that is all the hard-stop test needs: "none may be short"), and an
// integer min vectorises where a floating-point one would need -ffinite-math-only. NaN patterns
// are large: ignored here, caught by the guard after the step.
inline constexpr std::int64_t kNoRoom = std::numeric_limits<std::int64_t>::max();
inline double room_of(std::int64_t bits) {
  return bits == kNoRoom ? std::numeric_limits<double>::infinity() : std::bit_cast<double>(bits);
}

// Stage timing: the time since the last lap (ws.lap_ns) is added to `stage`'s counter, so laps
// taken one after the other attribute every nanosecond of a tick to exactly one stage.
inline std::uint64_t now_ns() {
  return static_cast<std::uint64_t>(std::chrono::duration_cast<std::chrono::nanoseconds>(
                                        std::chrono::steady_clock::now().time_since_epoch())
                                        .count());
}
inline void lap(State& s, Workspace& ws, Stage stage) {
  const std::uint64_t t = now_ns();
  s.counters.stage_ns[static_cast<int>(stage)] += t - ws.lap_ns;
  ws.lap_ns = t;
}

// The card's viscous terms (step.h): damper c delta_dot and Maxwell branch k_m (delta - e_m).
inline double viscous_load(const SpringCard& card, double deflection_rate, double deflection,
                           double maxwell) {
  return card.damping * deflection_rate + card.maxwell_k * (deflection - maxwell);
}

// One spring's load P and tangent dP/d(delta) by its group's card (law, damper, Maxwell branch) at
// deflection `delta` with rate `rate` (card units), e_m = `maxwell`: what every scalar spring path
// evaluates (the chunked path runs the same law in batches and adds viscous_load).
struct SpringLoad {
  double load, tangent;
};
inline SpringLoad spring_load(const SpringGroup& g, double delta, double rate, double maxwell) {
  SpringLoad r{g.card.hooke_k * delta, g.card.hooke_k};
  if (g.law) {
    const LawSample e = g.law->evaluate(delta);
    r.load = e.force;
    r.tangent = e.stiffness;
  }
  if (g.viscous) {
    r.load += viscous_load(g.card, rate, delta, maxwell);
    r.tangent += g.card.maxwell_k;
  }
  return r;
}

// Forces on every node at (state.x, state.v) into ws.force, as compute_forces. With
// `with_jacobian`, every spring's direction, length, load and tangent are kept per spring and
// contact leaves its normals in ws.contact.n (what the implicit system is built from).
void evaluate_forces(const Model& m, State& s, Workspace& ws, bool with_jacobian);

// Springs (springs.cc).
// A structure-of-arrays copy of x into ws.springs.px, py, pz (the positions of this geometry).
void copy_positions(const std::vector<Vec3>& x, Workspace& ws);
// Every spring's direction at the positions of the last geometry.
void refresh_directions(const Model& m, Workspace& ws);
// Geometry, loads and forces of one chunk of springs in runs with force scales a, summed into
// ws.springs.fx, fy, fz or into out[0..2]; the chunk's smallest room into *slack.
void chunk_forces(const Model& m, const State& s, Workspace& ws, const SpringLayout::Chunk& c,
                  bool keep, const double* __restrict a, std::int64_t* slack,
                  double* const* out = nullptr);
// Every spring's force summed into ws.force (which holds the node terms already); `keep`: every
// spring's values kept per spring (the implicit system needs them).
void spring_forces(const Model& m, const State& s, Workspace& ws, bool keep);

// Elements: core/element_terms.h.

// Contact (contact_stage.cc).
// The node law of probe k at `center` against positions x (every node or the listed ones):
// the probe's force, stiffness and contacts; with a workspace also the nodes' forces and, with
// the Jacobian, their scaled normals (for the implicit system of step h_system, s; 0: the
// substep).
void node_probe_contact(const Model& m, const std::vector<Vec3>& x, int k, const Vec3& center,
                        ProbeState* p, Workspace* ws = nullptr, bool with_jacobian = false,
                        const std::vector<int>* nodes = nullptr, double h_system = 0);
// Probes and planes against the body: forces into ws.force, layer blocks, plane normals.
void contact_forces(const Model& m, State& s, Workspace& ws, bool with_jacobian,
                    const std::vector<int>* nodes = nullptr);
// A frictional plate's tangential force on a node stretched d (m, along the plate) from its stick
// point, with penalty kp (N/m) and cone limit = mu kp depth (N): f_t = -limit tanh(kp |d| / limit)
// d / |d|, the penalty kp d for small stretches, saturating at the limit (a smooth stick-slip
// transition, so Newton does not chatter between stick and slip); past a stretch of
// kFrictionSlipStretch limit / kp the node slides (commit_friction drags its stick point) and the
// force stays at tanh(kFrictionSlipStretch) = 0.9993 of the limit. *stiffness = -df_t/dd on the
// plate, without the coupling to the depth (-d(limit)/d(depth) tanh(.) u n^T: not symmetric, and
// the implicit system is solved by conjugate gradients).
inline constexpr double kFrictionSlipStretch = 4.0;
Vec3 plate_friction_force(const Vec3& d, double kp, double limit, const Mat3& tangential,
                          Mat3* stiffness);
// Frictional planes: each node's stick point after a substep, by the return mapping at the
// substep's end positions (a node that slid drags it along, one that left the plate drops it).
void commit_friction(const Model& m, State& s);
// The proxy stage: every surface-contact probe's proxy toward its device target.
void update_proxies(const Model& m, State& s, Workspace& ws);
// Explicit integrators: nodes in contact advance with m (m I + h^2 B)^-1 (f - h B (v - v_proxy)).
void semi_implicit_contact(const Model& m, const State& s, Workspace& ws, double h);

// Active region (region.cc).
bool region_in_use(const Model& m, const State& s);
void forces_active(const Model& m, State& s, Workspace& ws);
double region_cost(const Model& m, const State& s, const Workspace& ws);
void update_region(const Model& m, State& s, Workspace& ws);
void far_forces_part(const Model& m, State& s, Workspace& ws, int phase);
void far_step(const Model& m, State& s, Workspace& ws);

// Hard stop (hard_stop.cc).
// Projects springs shorter than their hard-stop length back to it (step.h).
void hard_stop(const Model& m, State& s, Workspace& ws);
void hard_stop_project(const Model& m, State& s, Workspace& ws);

// Integrate and guard (integrate.cc, implicit.cc).
void relax_maxwell(const Model& m, State& s, double h);
void integrate_explicit(const Model& m, State& s, Workspace& ws, bool symplectic);
// One backward Euler substep (implicit.cc).
void integrate_implicit(const Model& m, State& s, Workspace& ws);
// The same with the sparse factor preconditioner (ws.factor, LinearSolver::kFactorCG).
void integrate_implicit_factored(const Model& m, State& s, Workspace& ws);
// y = A p, the backward Euler system A = M (1 + h mu) - h^2 (df/dx + df/dv / h) at (s.x, s.v) as
// the Newton iteration builds it (component-major vectors of 3 num_nodes entries, free axes).
void system_product(const Model& m, State& s, Workspace& ws, double h, const double* p, double* y);
// The system's values at (s.x, s.v) for step h without the product: masses, forces with the
// Jacobian, spring coefficients and the element terms' blocks (what SystemFactor::assemble reads).
void prepare_system_at(const Model& m, State& s, Workspace& ws, double h);
// The guard over every node, or over the listed ones; counts what it finds.
bool state_ok(const Model& m, State& s);
bool nodes_ok(const Model& m, State& s, const std::vector<int>& nodes);

}  // namespace conica::detail
