// Integrate and guard stages of the explicit integrators (step.h); backward Euler is implicit.cc.
#include <Eigen/Cholesky>
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "core/body.h"
#include "core/contact.h"
#include "core/step_detail.h"
#include "core/volume.h"

namespace conica {
namespace detail {
namespace {

// One explicit step of every node, branch-free: a = F w / m on free axes (fixed axes and fully
// fixed nodes have free = 0 or 1/m = 0, so they do not move).
[[gnu::noinline]] void advance_nodes(int nn, double h, bool symplectic, const double* __restrict F,
                                     const double* __restrict inv_mass,
                                     const double* __restrict free, double* __restrict X,
                                     double* __restrict V) {
  for (int i = 0; i < nn; ++i) {
    for (int c = 0; c < 3; ++c) {
      const int k = 3 * i + c;
      const double a = F[k] * inv_mass[i] * free[k];
      if (symplectic) {
        V[k] += h * a;               // eq. (22)
        X[k] += h * V[k] * free[k];  // eq. (23)
      } else {
        X[k] += h * V[k] * free[k];
        V[k] += h * a;
      }
    }
  }
}

// Non-finite coordinates (x * 0 is NaN for NaN and Inf) and nodes faster than sqrt(vmax2).
[[gnu::noinline]] void scan_state(int nn, const double* __restrict X, const double* __restrict V,
                                  double vmax2, int* nonfinite, int* fast) {
  int bad = 0, quick = 0;
  for (int k = 0; k < 3 * nn; ++k) bad += !(X[k] * 0.0 == 0.0) + !(V[k] * 0.0 == 0.0);
  for (int i = 0; i < nn; ++i)
    quick +=
        V[3 * i] * V[3 * i] + V[3 * i + 1] * V[3 * i + 1] + V[3 * i + 2] * V[3 * i + 2] > vmax2;
  *nonfinite = bad;
  *fast = quick;
}

}  // namespace

void relax_maxwell(const Model& m, State& s, double h) {
  for (const SpringGroup& g : m.groups) {
    if (!(g.card.maxwell_k > 0)) continue;
    const double decay = std::exp(-h / g.card.maxwell_tau);
    for (int k = g.begin; k < g.end; ++k) {
      const double d = m.deflection_scale[k] *
                       (m.rest_length[k] - (s.x[m.spring_j[k]] - s.x[m.spring_i[k]]).norm());
      s.maxwell[k] = d + (s.maxwell[k] - d) * decay;
    }
  }
}

void integrate_explicit(const Model& m, State& s, Workspace& ws, bool symplectic) {
  const double h = detail::substep_of(m);
  evaluate_forces(m, s, ws, false);
  semi_implicit_contact(m, s, ws, h);
  const int nn = m.num_nodes();
  if (!region_in_use(m, s)) {
    advance_nodes(nn, h, symplectic, ws.force.front().data(), m.inv_mass.data(),
                  m.free_axes.front().data(), s.x.front().data(), s.v.front().data());
    return;
  }
  if (ws.bounds.far_every > 0) {
    // Multi-rate: the border keeps the impulse of the awake springs for its next far step.
    for (int i : s.region.border) s.region.impulse[i] += h * ws.force[i];
    for (int i : s.region.awake_list) {
      if (m.fixed[i] == 7) continue;
      const Vec3 a = (ws.force[i] * m.inv_mass[i]).cwiseProduct(m.free_axes[i]);
      if (symplectic) {
        s.v[i] += h * a;
        s.x[i] += h * s.v[i];
      } else {
        s.x[i] += h * s.v[i];
        s.v[i] += h * a;
      }
    }
    return;
  }
  for (int i = 0; i < nn; ++i) {
    if (m.fixed[i] == 7 || !s.region.awake[i]) continue;
    const Vec3 a = (ws.force[i] * m.inv_mass[i]).cwiseProduct(m.free_axes[i]);
    if (symplectic) {
      s.v[i] += h * a;       // eq. (22)
      s.x[i] += h * s.v[i];  // eq. (23)
    } else {
      s.x[i] += h * s.v[i];
      s.v[i] += h * a;
    }
  }
}

bool state_ok(const Model& m, State& s) {
  const double vmax2 = m.options.max_speed * m.options.max_speed;
  int nonfinite = 0, fast = 0;
  scan_state(m.num_nodes(), s.x.front().data(), s.v.front().data(), vmax2, &nonfinite, &fast);
  const bool finite = nonfinite == 0, slow = fast == 0;
  if (!finite) ++s.counters.nan_events;
  if (finite && !slow) ++s.counters.speed_events;
  return finite && slow;
}

// The guard over the listed nodes only.
bool nodes_ok(const Model& m, State& s, const std::vector<int>& nodes) {
  const double vmax2 = m.options.max_speed * m.options.max_speed;
  bool finite = true, slow = true;
  for (int i : nodes) {
    finite &= s.x[i].allFinite() && s.v[i].allFinite();
    slow &= !(s.v[i].squaredNorm() > vmax2);
  }
  if (!finite) ++s.counters.nan_events;
  if (finite && !slow) ++s.counters.speed_events;
  return finite && slow;
}

}  // namespace detail

}  // namespace conica
