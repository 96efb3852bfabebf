#include "net/probe_contact.h"

#include "core/step.h"

namespace conica::net {

void probe_contact(const Model& model, const State& state, int k, const Vec3& center, double radius,
                   ProbeState* probe) {
  // The triangles near the tool, kept per thread so a reply allocates nothing once warm.
  thread_local ContactCandidates candidates;
  candidates.reserve(model);
  conica::probe_contact(model, state.x, k, center, radius, probe, &candidates);
}

}  // namespace conica::net
