// The contact stage alone, for one probe against the current node positions: what the server
// answers a probe update with between ticks, so a client gets the force at its new pose at once
// instead of a tick later. It is the core's contact stage (conica::probe_contact in core/step.h,
// the law documented there); tests/net/probe_contact_test.cc checks it against compute_forces().
// Cost: one pass over the nodes, no allocation.
#pragma once

#include "core/model.h"

namespace conica::net {

// Fills probe->force, ->stiffness and ->contacts for a sphere of radius `radius` (m; <= 0: the
// model's) centred at `center` (m), with the model's penalty for probe `k`.
void probe_contact(const Model& model, const State& state, int k, const Vec3& center, double radius,
                   ProbeState* probe);

}  // namespace conica::net
