#include "net/probe_contact.h"

#include <algorithm>
#include <cmath>

namespace conica::net {

void probe_contact(const Model& model, const State& state, int k, const Vec3& center, double radius,
                   ProbeState* probe) {
  probe->force.setZero();
  probe->stiffness.setZero();
  probe->contacts = 0;
  const double R = radius > 0 ? radius : model.probes[k].radius;
  const double kc = model.probes[k].stiffness;
  const double R2 = R * R;
  const int nn = model.num_nodes();
  const bool normals = static_cast<int>(model.normal.size()) == nn;
  for (int i = 0; i < nn; ++i) {
    const Vec3 u = state.x[i] - center;
    const double r2 = u.squaredNorm();
    if (r2 >= R2) continue;
    if (normals && model.normal[i].squaredNorm() > 0) {
      // Surface node: pushed out of the sphere inward along its normal.
      const Vec3& n = model.normal[i];
      const double a = u.dot(n);
      const double sq = std::sqrt(std::max(a * a - r2 + R2, 1e-12 * R2));
      probe->force += kc * (a + sq) * n;
      const Vec3 dsdu = n + (a * n - u) / sq;
      probe->stiffness += -kc * n * dsdu.transpose();
    } else {
      // Interior node: radially out; a node at the exact centre goes along +z (never NaN).
      const double r = std::sqrt(r2);
      const bool centred = !(r > 1e-12 * R);
      const Vec3 n = centred ? Vec3::UnitZ() : Vec3(u / r);
      probe->force -= kc * (R - r) * n;
      const Mat3 nnT = n * n.transpose();
      probe->stiffness += kc * (-nnT + (centred ? 0.0 : (R - r) / r) * (Mat3::Identity() - nnT));
    }
    ++probe->contacts;
  }
}

}  // namespace conica::net
