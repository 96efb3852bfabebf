// The contact stage alone, for one probe against the current node positions: what the server
// answers a probe update with between ticks, so a client gets the force at its new pose at once
// instead of a tick later. Same law as the step's contact stage (core/step.h):
//   per node inside the sphere (r = |x - c| < R, n = (x - c) / r):  f_node = k_c (R - r) n
//   probe force  F = -sum f_node
//   stiffness    dF/dc = sum k_c [ -n n^T + (R - r)/r (I - n n^T) ]   (nodes held)
// Cost: one pass over the nodes, no allocation.
#pragma once

#include "core/model.h"

namespace conica::net {

// Fills probe->force, ->stiffness and ->contacts for a sphere of radius `radius` (m; <= 0: the
// model's) centred at `center` (m), with the model's penalty for probe `k`.
void probe_contact(const Model& model, const State& state, int k, const Vec3& center,
                   double radius, ProbeState* probe);

}  // namespace conica::net
