// The proxy stage alone, for one probe against the current node positions: what the server
// answers a probe update with between ticks, so a client gets the force at its new pose at once
// instead of a tick later. It is the core's proxy stage (conica::probe_contact in core/step.h,
// the contact documented in core/contact.h); tests/net/probe_contact_test.cc checks it against
// compute_forces(). It moves probe->proxy: the next tick starts from it.
// Cost: one pass over the surface triangles, then the few within the tool's reach.
#pragma once

#include "core/model.h"

namespace conica::net {

// Moves probe `k`'s proxy toward the device target `center` (m) for a tool of radius `radius`
// (m; <= 0: the probe's) and fills probe->force, ->stiffness and ->contacts.
void probe_contact(const Model& model, const State& state, int k, const Vec3& center, double radius,
                   ProbeState* probe);

}  // namespace conica::net
