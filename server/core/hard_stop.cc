// Hard-stop stage: no spring shorter than its solid height (step.h).
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

// Nodes that moved by more than `reach` since the positions (px, py, pz).
[[gnu::noinline]] int count_moved(int nn, const double* __restrict X, const double* __restrict px,
                                  const double* __restrict py, const double* __restrict pz,
                                  double reach) {
  const double r2 = reach * reach;
  int n = 0;
  for (int i = 0; i < nn; ++i) {
    const double dx = X[3 * i] - px[i], dy = X[3 * i + 1] - py[i], dz = X[3 * i + 2] - pz[i];
    n += dx * dx + dy * dy + dz * dz > r2;
  }
  return n;
}

// Counts springs shorter than their hard-stop length, measured along the direction they had at
// the last force evaluation (u.d_old), so that a spring that inverted within one step is caught.
[[gnu::noinline]] int count_short(int ns, const double* __restrict X, const int* __restrict si,
                                  const int* __restrict sj, const double* __restrict ux,
                                  const double* __restrict uy, const double* __restrict uz,
                                  const double* __restrict lmin) {
  int n = 0;
  for (int k = 0; k < ns; ++k) {
    const int i = 3 * si[k], j = 3 * sj[k];
    const double dx = X[j] - X[i], dy = X[j + 1] - X[i + 1], dz = X[j + 2] - X[i + 2];
    n += (dx * ux[k] + dy * uy[k] + dz * uz[k]) < lmin[k];
  }
  return n;
}

}  // namespace

// Projects springs shorter than their minimum length back to it (mass-weighted) and removes the
// approaching part of their relative velocity.
void hard_stop(const Model& m, State& s, Workspace& ws) {
  if (region_in_use(m, s) && m.options.integrator != Integrator::kImplicitEuler) {
    // Only springs with an awake end can have moved.
    int n = 0;
    for (int q = 0; q < s.region.num_active; ++q) {
      const int k = s.region.active[q];
      n += (s.x[m.spring_j[k]] - s.x[m.spring_i[k]]).dot(ws.springs.dir(k)) <
           ws.layout.min_length[k];
    }
    if (n > 0) hard_stop_project(m, s, ws);
    return;
  }
  // Measured along its direction at the last geometry, a spring is no shorter than its length
  // then minus the motion of its two ends since: with no node moved by half the smallest room,
  // none can be short.
  ws.springs.hard_stop_near =
      !(ws.springs.slack > 0) ||
      count_moved(m.num_nodes(), s.x.front().data(), ws.springs.px.data(), ws.springs.py.data(),
                  ws.springs.pz.data(), 0.5 * ws.springs.slack) > 0;
  if (!ws.springs.hard_stop_near) return;
  if (!ws.springs.directions_kept) refresh_directions(m, ws);
  if (count_short(m.num_springs(), s.x.front().data(), m.spring_i.data(), m.spring_j.data(),
                  ws.springs.ux.data(), ws.springs.uy.data(), ws.springs.uz.data(),
                  ws.layout.min_length.data()) > 0)
    hard_stop_project(m, s, ws);
}

void hard_stop_project(const Model& m, State& s, Workspace& ws) {
  const int ns = m.num_springs();
  for (int k = 0; k < ns; ++k) {
    const int i = m.spring_i[k], j = m.spring_j[k];
    const Vec3 d = ws.springs.dir(k);  // direction before the step: robust to inversion
    const Vec3 u = s.x[j] - s.x[i];
    const double l = u.dot(d);
    const double lmin = ws.layout.min_length[k];
    if (l >= lmin) continue;
    const double wi = m.inv_mass[i], wj = m.inv_mass[j], w = wi + wj;
    if (w <= 0) continue;
    const double gap = lmin - l;
    s.x[i] -= ((wi / w) * gap * d).cwiseProduct(m.free_axes[i]);
    s.x[j] += ((wj / w) * gap * d).cwiseProduct(m.free_axes[j]);
    const double vrel = d.dot(s.v[j] - s.v[i]);
    if (vrel < 0) {
      s.v[i] += ((wi / w) * vrel * d).cwiseProduct(m.free_axes[i]);
      s.v[j] -= ((wj / w) * vrel * d).cwiseProduct(m.free_axes[j]);
    }
    ++s.counters.hard_stops;
  }
}

}  // namespace detail

}  // namespace conica
