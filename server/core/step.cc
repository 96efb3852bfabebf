// The step as a list of stages (step.h): proxies, forces (springs, elements, contact), integrate,
// hard stop, guard.
#include <Eigen/Cholesky>
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "core/body.h"
#include "core/boundary.h"
#include "core/contact.h"
#include "core/element_terms.h"
#include "core/step_detail.h"
#include "core/volume.h"

namespace conica {
namespace detail {
// The force stages: springs, elements, contact (the active region's springs when it is in use).
void evaluate_forces(const Model& m, State& s, Workspace& ws, bool with_jacobian) {
  const int nn = m.num_nodes();
  lap(s, ws, Stage::kIntegrate);  // what the integrator did before asking for forces
  if (region_in_use(m, s) && !with_jacobian) {
    forces_active(m, s, ws);
    lap(s, ws, Stage::kSprings);
    contact_forces(m, s, ws, false, ws.bounds.far_every > 0 ? &s.region.awake_list : nullptr);
    add_bonded_reactions(m, s, ws);
    lap(s, ws, Stage::kContact);
    return;
  }
  const double mu = m.options.mass_damping;
  if (ws.layout.runs.empty())  // the runs path writes the node terms with the spring forces
    for (int i = 0; i < nn; ++i) ws.force[i] = m.mass[i] * (m.options.gravity - mu * s.v[i]);
  spring_forces(m, s, ws, with_jacobian);
  lap(s, ws, Stage::kSprings);
  element_forces(m, s, ws);
  lap(s, ws, Stage::kElements);
  contact_forces(m, s, ws, with_jacobian);
  add_bonded_reactions(m, s, ws);
  lap(s, ws, Stage::kContact);
}

namespace {

// The active region for this tick (explicit integrators): chosen at the start of a multi-rate
// interval, or every tick when the far field is frozen; a region that costs about a whole step
// hands the tick to the whole body. Returns whether this tick runs multi-rate.
bool choose_region(const Model& m, State& s, Workspace& ws) {
  const bool region = m.options.active_region && m.options.integrator != Integrator::kImplicitEuler;
  // Multi-rate far field: the region is chosen at the start of an interval, the far field steps at
  // its end; in between only the awake nodes change, and only they are saved and checked.
  bool multirate = region && ws.bounds.far_every > 0;
  if (region && (!multirate || s.region.far_phase == 0 || s.region.num_active < 0)) {
    update_region(m, s, ws);
    // A region that costs about a whole step is not worth its bookkeeping: the whole body steps
    // every tick until the region's cost falls well below it (hysteresis). The switch happens at
    // an interval's start, when no far share or impulse is pending.
    if (multirate) {
      s.region.cost = region_cost(m, s, ws);
      const double enter = m.options.active_whole_body_cost;
      s.region.whole_body =
          s.region.cost > (s.region.whole_body ? kRegionResumeFraction * enter : enter);
    }
  }
  if (multirate && s.region.whole_body) {
    multirate = false;
    s.counters.awake_nodes = static_cast<std::uint64_t>(m.num_nodes());
  }
  return multirate;
}

// The last good state, for the guard: only the awake nodes on a multi-rate tick that is not the
// far field's (the others do not move).
void save_good(const State& s, Workspace& ws, bool partial) {
  if (partial) {
    for (int i : s.region.awake_list) {
      ws.good.x[i] = s.x[i];
      ws.good.v[i] = s.v[i];
    }
  } else {
    std::copy(s.x.begin(), s.x.end(), ws.good.x.begin());
    std::copy(s.v.begin(), s.v.end(), ws.good.v.begin());
  }
  if (ws.layout.has_maxwell) std::copy(s.maxwell.begin(), s.maxwell.end(), ws.good.maxwell.begin());
  for (size_t q = 0; q < s.planes.size() && q < ws.good.stick.size(); ++q)
    if (s.planes[q].stick.size() == ws.good.stick[q].size())
      std::copy(s.planes[q].stick.begin(), s.planes[q].stick.end(), ws.good.stick[q].begin());
}

// One substep of the model's integrator, then the hard stop and the Maxwell branches.
void substep(const Model& m, State& s, Workspace& ws) {
  switch (m.options.integrator) {
    case Integrator::kSymplecticEuler:
      integrate_explicit(m, s, ws, true);
      break;
    case Integrator::kExplicitEuler:
      integrate_explicit(m, s, ws, false);
      break;
    case Integrator::kImplicitEuler:
      if (ws.factor)
        integrate_implicit_factored(m, s, ws);
      else
        integrate_implicit(m, s, ws);
      break;
  }
  lap(s, ws, Stage::kIntegrate);
  hard_stop(m, s, ws);
  commit_friction(m, s);
  relax_maxwell(m, s, substep_of(m));
  lap(s, ws, Stage::kHardStop);
}

// The guard: a state with NaN / Inf or a node faster than max_speed returns to the last good one
// with velocities zeroed (partial: the awake nodes, whose border impulses are dropped).
StepStatus guard(const Model& m, State& s, Workspace& ws, bool partial) {
  if (partial ? nodes_ok(m, s, s.region.awake_list) : state_ok(m, s)) return StepStatus::kOk;
  if (partial) {
    for (int i : s.region.awake_list) s.x[i] = ws.good.x[i];
    for (int i : s.region.border) s.region.impulse[i].setZero();
  } else {
    std::copy(ws.good.x.begin(), ws.good.x.end(), s.x.begin());
  }
  std::fill(s.v.begin(), s.v.end(), Vec3::Zero());
  s.has_prev = false;  // BDF2 starts again with backward Euler
  if (ws.layout.has_maxwell)
    std::copy(ws.good.maxwell.begin(), ws.good.maxwell.end(), s.maxwell.begin());
  for (size_t q = 0; q < s.planes.size() && q < ws.good.stick.size(); ++q)
    if (s.planes[q].stick.size() == ws.good.stick[q].size())
      std::copy(ws.good.stick[q].begin(), ws.good.stick[q].end(), s.planes[q].stick.begin());
  ++s.counters.rollbacks;
  return StepStatus::kRolledBack;
}

}  // namespace

}  // namespace detail

using namespace detail;

void compute_forces(const Model& model, State& state, Workspace& ws) {
  ws.lap_ns = now_ns();
  update_proxies(model, state, ws);
  lap(state, ws, Stage::kProxies);
  evaluate_forces(model, state, ws, false);
}

void set_probe(State& state, int probe, const Vec3& center, bool active) {
  state.probes[probe].center = center;
  state.probes[probe].active = active;
}

StepStatus step(const Model& m, State& s, Workspace& ws) {
  ws.lap_ns = now_ns();
  // Prescribed boundaries at the end of this step (core/boundary.h).
  if (has_boundary_motion(m)) apply_boundary_motion(m, s, s.time + m.options.dt);
  update_proxies(m, s, ws);
  lap(s, ws, Stage::kProxies);
  const bool multirate = choose_region(m, s, ws);
  const bool far_tick = multirate && s.region.far_phase == ws.bounds.far_every - 1;
  const bool partial = multirate && !far_tick;
  save_good(s, ws, partial);
  lap(s, ws, Stage::kRegion);
  for (int sub = 0; sub < m.options.substeps; ++sub) substep(m, s, ws);
  if (multirate) far_forces_part(m, s, ws, s.region.far_phase);
  if (far_tick) far_step(m, s, ws);
  if (multirate) s.region.far_phase = (s.region.far_phase + 1) % ws.bounds.far_every;
  lap(s, ws, Stage::kFarField);
  ++s.counters.steps;
  ++s.tick;
  s.time += m.options.dt;
  const StepStatus status = guard(m, s, ws, partial);
  lap(s, ws, Stage::kGuard);
  return status;
}

}  // namespace conica
