#include "net/probe_contact.h"

#include "core/step.h"

namespace conica::net {

void probe_contact(const Model& model, const State& state, int k, const Vec3& center, double radius,
                   ProbeState* probe) {
  conica::probe_contact(model, state.x, k, center, radius, probe);
}

}  // namespace conica::net
