// Spring stage: geometry, card law, dampers and Maxwell branches of every spring, their forces
// summed into ws.force (step.h). Springs in runs go chunk by chunk through vectorised kernels.
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

// End-to-end vectors of every spring gathered from node-major positions X (num_nodes x 3) into
// (dx, dy, dz), for springs not in runs; normalise_chunk then turns them into geometry. Kept out
// of line so the compiler sees raw doubles, not Eigen storage, and emits gathers.
[[gnu::noinline]] void gather_vectors(int ns, const double* __restrict X, const int* __restrict si,
                                      const int* __restrict sj, double* __restrict dx,
                                      double* __restrict dy, double* __restrict dz) {
  for (int k = 0; k < ns; ++k) {
    const int i = 3 * si[k], j = 3 * sj[k];
    dx[k] = X[j] - X[i];
    dy[k] = X[j + 1] - X[i + 1];
    dz[k] = X[j + 2] - X[i + 2];
  }
}

// Geometry of springs in runs, in two passes per chunk: each run's end-to-end vectors are copied
// as contiguous streams of the structure-of-arrays positions (node i + t to j + t), then one
// loop over the whole chunk normalises them. Short runs (a lattice's rows) then cost only the
// cheap copy, and the square roots and divisions run in one long vectorised loop.
[[gnu::noinline]] void run_vectors(int n, const double* __restrict xi, const double* __restrict yi,
                                   const double* __restrict zi, const double* __restrict xj,
                                   const double* __restrict yj, const double* __restrict zj,
                                   double* __restrict dx, double* __restrict dy,
                                   double* __restrict dz) {
  for (int t = 0; t < n; ++t) {
    dx[t] = xj[t] - xi[t];
    dy[t] = yj[t] - yi[t];
    dz[t] = zj[t] - zi[t];
  }
}

// Turns the vectors (ux, uy, uz) of n springs into unit directions, lengths and deflections, and
// returns the smallest room to the hard stop (as bits, see kNoRoom).
[[gnu::noinline]] std::int64_t normalise_chunk(int n, const double* __restrict l0,
                                               const double* __restrict b,
                                               const double* __restrict lmin, double* __restrict ux,
                                               double* __restrict uy, double* __restrict uz,
                                               double* __restrict len, double* __restrict defl) {
  std::int64_t slack = kNoRoom;
  for (int t = 0; t < n; ++t) {
    const double dx = ux[t], dy = uy[t], dz = uz[t];
    const double l = std::sqrt(dx * dx + dy * dy + dz * dz);
    // A zero-length spring gets a zero direction and so no force: bounded, never NaN.
    const double inv = 1.0 / std::max(l, 1e-300);
    ux[t] = dx * inv;
    uy[t] = dy * inv;
    uz[t] = dz * inv;
    len[t] = l;
    defl[t] = b[t] * (l0[t] - l);
    slack = std::min(slack, std::bit_cast<std::int64_t>(l - lmin[t]));
  }
  return slack;
}

// Adds sign * a P d of a run of springs to the node forces f (already offset to the run's first
// node on that side). The two ends are separate calls, so every call writes one stream.
[[gnu::noinline]] void scatter_run(int n, double sign, const double* __restrict a,
                                   const double* __restrict load, const double* __restrict ux,
                                   const double* __restrict uy, const double* __restrict uz,
                                   double* __restrict fx, double* __restrict fy,
                                   double* __restrict fz) {
  for (int t = 0; t < n; ++t) {
    const double c = sign * a[t] * load[t];
    fx[t] += c * ux[t];
    fy[t] += c * uy[t];
    fz[t] += c * uz[t];
  }
}

// Both ends at once, for a run whose two node ranges [i, i + n) and [j, j + n) do not overlap.
[[gnu::noinline]] void scatter_run_pair(int n, const double* __restrict a,
                                        const double* __restrict load, const double* __restrict ux,
                                        const double* __restrict uy, const double* __restrict uz,
                                        double* __restrict fxi, double* __restrict fyi,
                                        double* __restrict fzi, double* __restrict fxj,
                                        double* __restrict fyj, double* __restrict fzj) {
  for (int t = 0; t < n; ++t) {
    const double c = a[t] * load[t];
    const double gx = c * ux[t], gy = c * uy[t], gz = c * uz[t];
    fxi[t] -= gx;
    fyi[t] -= gy;
    fzi[t] -= gz;
    fxj[t] += gx;
    fyj[t] += gy;
    fzj[t] += gz;
  }
}

// Node forces of the runs path: F = m (g - mu v) + (fx, fy, fz), F and V node-major (x, y, z).
[[gnu::noinline]] void node_forces(int nn, const double* __restrict mass,
                                   const double* __restrict V, const double* __restrict fx,
                                   const double* __restrict fy, const double* __restrict fz,
                                   const double* g, double mu, double* __restrict F) {
  const double gx = g[0], gy = g[1], gz = g[2];
  for (int i = 0; i < nn; ++i) {
    F[3 * i] = mass[i] * (gx - mu * V[3 * i]) + fx[i];
    F[3 * i + 1] = mass[i] * (gy - mu * V[3 * i + 1]) + fy[i];
    F[3 * i + 2] = mass[i] * (gz - mu * V[3 * i + 2]) + fz[i];
  }
}

// Per-spring values of springs [k0, k1), each pointer at spring k0's entry.
struct SpringValues {
  double *ux, *uy, *uz, *length, *deflection, *load, *tangent;
};

// Loads of springs [k0, k1) of group g from their deflections: card law, damper, Maxwell branch.
void group_loads(const Model& m, const State& s, const SpringGroup& g, int k0, int k1,
                 const SpringValues& v) {
  const int n = k1 - k0;
  if (g.law) {
    g.law->evaluate_batch(v.deflection, v.load, v.tangent, n);
  } else {
    const double hk = g.card.hooke_k;
    for (int t = 0; t < n; ++t) {
      v.load[t] = hk * v.deflection[t];
      v.tangent[t] = hk;
    }
  }
  if (!g.viscous) return;
  for (int t = 0; t < n; ++t) {
    const int k = k0 + t;
    const Vec3 d(v.ux[t], v.uy[t], v.uz[t]);
    const double ldot = d.dot(s.v[m.spring_j[k]] - s.v[m.spring_i[k]]);
    const double ddot = -m.deflection_scale[k] * ldot;
    v.load[t] += viscous_load(g.card, ddot, v.deflection[t], s.maxwell[k]);
    v.tangent[t] += g.card.maxwell_k;
  }
}

SpringValues values_at(Workspace& ws, int k) {
  return {ws.springs.ux.data() + k,         ws.springs.uy.data() + k,
          ws.springs.uz.data() + k,         ws.springs.length.data() + k,
          ws.springs.deflection.data() + k, ws.springs.load.data() + k,
          ws.springs.tangent.data() + k};
}

}  // namespace

// Keeps a structure-of-arrays copy of x (the positions of this geometry, for the hard-stop test).
void copy_positions(const std::vector<Vec3>& x, Workspace& ws) {
  const int nn = static_cast<int>(x.size());
  for (int i = 0; i < nn; ++i) {
    ws.springs.px[i] = x[i].x();
    ws.springs.py[i] = x[i].y();
    ws.springs.pz[i] = x[i].z();
  }
}

// Directions of every spring at the positions of the last geometry (px, py, pz), for a hard stop
// after a step that kept them only chunk by chunk.
void refresh_directions(const Model& m, Workspace& ws) {
  const int ns = m.num_springs();
  for (int k = 0; k < ns; ++k) {
    const int i = m.spring_i[k], j = m.spring_j[k];
    // The arithmetic of normalise_chunk, so that a direction is the same bits whether the force
    // pass kept it or it is refreshed here (a replay must not depend on which path ran).
    const double dx = ws.springs.px[j] - ws.springs.px[i], dy = ws.springs.py[j] - ws.springs.py[i],
                 dz = ws.springs.pz[j] - ws.springs.pz[i];
    const double l = std::sqrt(dx * dx + dy * dy + dz * dz);
    const double inv = 1.0 / std::max(l, 1e-300);
    ws.springs.ux[k] = dx * inv;
    ws.springs.uy[k] = dy * inv;
    ws.springs.uz[k] = dz * inv;
  }
  ws.springs.directions_kept = true;
}

// Geometry, loads and forces (summed into ws.springs.fx, fy, fz, or into out[0..2] when given) of
// one chunk of springs in runs, with force scales a (per spring); values kept per spring or only in
// the chunk buffers.
void chunk_forces(const Model& m, const State& s, Workspace& ws, const SpringLayout::Chunk& c,
                  bool keep, const double* __restrict a, std::int64_t* slack, double* const* out) {
  double* const fx = out ? out[0] : ws.springs.fx.data();
  double* const fy = out ? out[1] : ws.springs.fy.data();
  double* const fz = out ? out[2] : ws.springs.fz.data();
  const SpringValues v =
      keep ? values_at(ws, c.k0)
           : SpringValues{ws.springs.chunk_ux.data(),         ws.springs.chunk_uy.data(),
                          ws.springs.chunk_uz.data(),         ws.springs.chunk_length.data(),
                          ws.springs.chunk_deflection.data(), ws.springs.chunk_load.data(),
                          ws.springs.chunk_tangent.data()};
  for (int q = c.first_run; q < c.last_run; ++q) {
    const SpringLayout::Run& r = ws.layout.runs[q];
    const int t = r.k - c.k0;
    run_vectors(r.n, ws.springs.px.data() + r.i, ws.springs.py.data() + r.i,
                ws.springs.pz.data() + r.i, ws.springs.px.data() + r.j, ws.springs.py.data() + r.j,
                ws.springs.pz.data() + r.j, v.ux + t, v.uy + t, v.uz + t);
  }
  *slack = std::min(
      *slack, normalise_chunk(c.k1 - c.k0, m.rest_length.data() + c.k0,
                              m.deflection_scale.data() + c.k0, ws.layout.min_length.data() + c.k0,
                              v.ux, v.uy, v.uz, v.length, v.deflection));
  group_loads(m, s, m.groups[c.group], c.k0, c.k1, v);
  for (int q = c.first_run; q < c.last_run; ++q) {
    const SpringLayout::Run& r = ws.layout.runs[q];
    const int t = r.k - c.k0;
    if (r.j - r.i >= r.n) {
      scatter_run_pair(r.n, a + r.k, v.load + t, v.ux + t, v.uy + t, v.uz + t, fx + r.i, fy + r.i,
                       fz + r.i, fx + r.j, fy + r.j, fz + r.j);
      continue;
    }
    for (const auto& [node, sign] : {std::pair{r.i, -1.0}, std::pair{r.j, 1.0}})
      scatter_run(r.n, sign, a + r.k, v.load + t, v.ux + t, v.uy + t, v.uz + t, fx + node,
                  fy + node, fz + node);
  }
}

// Geometry and loads of every spring, and their forces summed into ws.force (which holds the
// node terms already). Springs in runs go chunk by chunk (geometry, law, scatter), so a chunk's
// per-spring values are reused from L1 rather than streamed through memory three times.
void spring_forces(const Model& m, const State& s, Workspace& ws, bool keep) {
  const int nn = m.num_nodes();
  copy_positions(s.x, ws);
  const double* __restrict a = m.force_scale.data();
  ws.springs.directions_kept = true;
  if (ws.layout.runs.empty()) {
    const int ns = m.num_springs();
    gather_vectors(ns, s.x.front().data(), m.spring_i.data(), m.spring_j.data(),
                   ws.springs.ux.data(), ws.springs.uy.data(), ws.springs.uz.data());
    ws.springs.slack = room_of(normalise_chunk(
        ns, m.rest_length.data(), m.deflection_scale.data(), ws.layout.min_length.data(),
        ws.springs.ux.data(), ws.springs.uy.data(), ws.springs.uz.data(), ws.springs.length.data(),
        ws.springs.deflection.data()));
    for (const SpringGroup& g : m.groups)
      group_loads(m, s, g, g.begin, g.end, values_at(ws, g.begin));
    const double* __restrict load = ws.springs.load.data();
    double* __restrict F = ws.force.front().data();
    for (int k = 0; k < ns; ++k) {
      const double fk = a[k] * load[k];
      const double fx = fk * ws.springs.ux[k], fy = fk * ws.springs.uy[k],
                   fz = fk * ws.springs.uz[k];
      const int i = 3 * m.spring_i[k], j = 3 * m.spring_j[k];
      F[i] -= fx;
      F[i + 1] -= fy;
      F[i + 2] -= fz;
      F[j] += fx;
      F[j + 1] += fy;
      F[j + 2] += fz;
    }
    return;
  }
  // Chunk by chunk; unless kept (the implicit solver needs every spring's values), a chunk's
  // values live in the chunk buffers only, and no per-spring array is streamed through memory.
  keep = keep ||
         ws.springs.hard_stop_near;  // the hard stop will need them: cheaper kept than refreshed
  ws.springs.directions_kept = keep;
  std::fill(ws.springs.fx.begin(), ws.springs.fx.end(), 0.0);
  std::fill(ws.springs.fy.begin(), ws.springs.fy.end(), 0.0);
  std::fill(ws.springs.fz.begin(), ws.springs.fz.end(), 0.0);
  std::int64_t slack = kNoRoom;
  for (const SpringLayout::Chunk& c : ws.layout.chunks) chunk_forces(m, s, ws, c, keep, a, &slack);
  ws.springs.slack = room_of(slack);
  node_forces(nn, m.mass.data(), s.v.front().data(), ws.springs.fx.data(), ws.springs.fy.data(),
              ws.springs.fz.data(), m.options.gravity.data(), m.options.mass_damping,
              ws.force.front().data());
}

}  // namespace detail

}  // namespace conica
