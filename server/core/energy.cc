// Stored and kinetic energy (step.h).
#include <Eigen/Cholesky>
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "core/body.h"
#include "core/contact.h"
#include "core/element_terms.h"
#include "core/step_detail.h"

namespace conica {

using namespace detail;

double potential_energy(const Model& m, const State& s) {
  double e = 0;
  for (const SpringGroup& g : m.groups) {
    for (int k = g.begin; k < g.end; ++k) {
      const double l = (s.x[m.spring_j[k]] - s.x[m.spring_i[k]]).norm();
      const double a = m.force_scale[k], b = m.deflection_scale[k];
      const double d = b * (m.rest_length[k] - l);
      const double law_e = g.law ? g.law->energy(d) : 0.5 * g.card.hooke_k * d * d;
      const double dm = d - s.maxwell[k];
      e += (a / b) * (law_e + 0.5 * g.card.maxwell_k * dm * dm);
    }
  }
  for_each_term(m, [&](auto term) { e += term.energy(m, s.x); });
  for (size_t q = 0; q < m.probes.size(); ++q) {
    const ProbeState& p = s.probes[q];
    if (!p.active || m.probes[q].contact != ContactModel::kNodes) continue;
    const double R = probe_radius(m, static_cast<int>(q), p);
    const double kc = m.probes[q].stiffness;
    for (int i = 0; i < m.num_nodes(); ++i) {
      Vec3 f, dir;
      Mat3 dfdc;
      double depth;  // the law's depth, with the cap the force has (node_contact)
      if (node_contact(s.x[i], m.normal[i], p.center, R, kc, &f, &dfdc, &dir, &depth))
        e += 0.5 * kc * depth * depth;
    }
  }
  for (size_t q = 0; q < m.probes.size(); ++q) {
    const ProbeState& p = s.probes[q];
    if (!p.active || !p.proxy_placed || m.probes[q].contact != ContactModel::kSurface) continue;
    ToolContact c;
    const double R = probe_radius(m, static_cast<int>(q), p);
    tool_contact(m, static_cast<int>(q), R, p.proxy, s.x, nullptr, 0, &c);
    // The layer and the virtual coupling between the device and the proxy.
    e += c.energy + coupling(m, static_cast<int>(q), R).energy(p.proxy - p.center);
  }
  for (size_t q = 0; q < m.planes.size(); ++q) {
    const PlaneState& pl = s.planes[q];
    const Vec3& n = m.planes[q].normal;
    const double kp = m.planes[q].stiffness, mu = m.planes[q].friction;
    for (size_t i = 0; i < s.x.size(); ++i) {
      const double depth = pl.offset - n.dot(s.x[i]);
      if (depth <= 0) continue;
      e += 0.5 * kp * depth * depth;
      // A frictional plate's tangential penalty (its return-mapped stretch, as the force pass).
      if (pl.stick.empty() || m.fixed[i] == 7) continue;
      Vec3 d = s.x[i] - pl.slide - pl.stick[i];
      d -= n.dot(d) * n;
      // int_0^|d| limit tanh(kp r / limit) dr, limit = mu kp depth (core/step_detail.h).
      const double limit = mu * kp * depth;
      if (limit > 0)
        e += limit * limit / kp *
             std::log(std::cosh(std::min(kp * d.norm() / limit, detail::kFrictionSlipStretch)));
    }
  }
  const int nn = m.num_nodes();
  for (int i = 0; i < nn; ++i)
    e -= m.mass[i] * m.options.gravity.cwiseProduct(m.free_axes[i]).dot(s.x[i] - m.rest[i]);
  return e;
}

double kinetic_energy(const Model& m, const State& s) {
  double e = 0;
  for (int i = 0; i < m.num_nodes(); ++i) e += 0.5 * m.mass[i] * s.v[i].squaredNorm();
  return e;
}

}  // namespace conica
