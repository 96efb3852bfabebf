// The contact stage alone, for one probe against the current node positions: what the server
// answers a probe update with between ticks, so a client gets the force at its new pose at once
// instead of a tick later. The same law as the step's contact stage (core/step.h), per node
// inside the sphere of radius R around c (u = x - c, r = |u|):
//   surface node, outward normal n:  s = a + sqrt(a^2 - r^2 + R^2), a = u.n;  f_node = -k_c s n
//   interior node:                   f_node = k_c (R - r) u / r
//   probe force F = -sum f_node; stiffness dF/dc with nodes held (exact).
// tests/net/probe_contact_test.cc checks it against compute_forces() so the two cannot drift.
// Cost: one pass over the nodes, no allocation.
#pragma once

#include "core/model.h"

namespace conica::net {

// Fills probe->force, ->stiffness and ->contacts for a sphere of radius `radius` (m; <= 0: the
// model's) centred at `center` (m), with the model's penalty for probe `k`.
void probe_contact(const Model& model, const State& state, int k, const Vec3& center, double radius,
                   ProbeState* probe);

}  // namespace conica::net
