#include "net/probe_contact.h"

#include <cmath>

namespace conica::net {

void probe_contact(const Model& model, const State& state, int k, const Vec3& center,
                   double radius, ProbeState* probe) {
  probe->force.setZero();
  probe->stiffness.setZero();
  probe->contacts = 0;
  const double R = radius > 0 ? radius : model.probes[k].radius;
  const double kc = model.probes[k].stiffness;
  const double R2 = R * R;
  const int nn = model.num_nodes();
  for (int i = 0; i < nn; ++i) {
    const Vec3 u = state.x[i] - center;
    const double r2 = u.squaredNorm();
    if (r2 >= R2) continue;
    const double r = std::sqrt(r2);
    // A node at the exact centre is pushed along +z, as in the step: bounded, never NaN.
    const bool centred = !(r > 1e-12 * R);
    const Vec3 n = centred ? Vec3::UnitZ() : Vec3(u / r);
    probe->force -= kc * (R - r) * n;
    const Mat3 nnT = n * n.transpose();
    probe->stiffness += kc * (-nnT + (centred ? 0.0 : (R - r) / r) * (Mat3::Identity() - nnT));
    ++probe->contacts;
  }
}

}  // namespace conica::net
