// Internals shared by the translation units of the step (step.cc, implicit.cc); not an API.
#pragma once

#include "core/step.h"

namespace conica::detail {

// Time step of one substep, s.
inline double substep_of(const Model& m) { return m.options.dt / m.options.substeps; }

// Forces on every node at (state.x, state.v) into ws.force, as compute_forces. With
// `with_jacobian`, every spring's direction, length, load and tangent are kept per spring and
// contact leaves its normals in ws.contact_n (what the implicit system is built from).
void evaluate_forces(const Model& m, State& s, Workspace& ws, bool with_jacobian);

// Projects springs shorter than their hard-stop length back to it (step.h).
void apply_hard_stop(const Model& m, State& s, Workspace& ws);

// One backward Euler substep (implicit.cc).
void integrate_implicit(const Model& m, State& s, Workspace& ws);

}  // namespace conica::detail
