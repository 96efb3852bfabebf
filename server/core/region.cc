// Active region (step.h): choosing the awake nodes, the forces of the awake side, and the
// multi-rate far field's shares and steps. Its dynamic part lives in State::region.
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
// The active region decides what a tick touches: it is built and not handed over to whole-body
// steps.
bool region_in_use(const Model& m, const State& s) {
  return m.options.active_region && s.region.num_active >= 0 && !s.region.whole_body;
}

// Forces of the active region only: springs with an awake end, one at a time (scalar law). Sleeping
// nodes on the region's boundary collect the pull of the awake springs; one pulled harder than the
// tolerance is marked to wake.
void forces_active(const Model& m, State& s, Workspace& ws) {
  const int nn = m.num_nodes();
  const double mu = m.options.mass_damping;
  // A large region goes chunk by chunk (chunks with an awake spring, whole; springs with both ends
  // asleep scaled to zero); a small one spring by spring from its list, since its springs are
  // spread over many chunks and the per-node passes of the chunk path cost more than they save.
  const bool chunked = !ws.layout.runs.empty() && 8 * s.region.num_active > m.num_springs();
  if (chunked) {
    copy_positions(s.x, ws);
    std::fill(ws.springs.fx.begin(), ws.springs.fx.end(), 0.0);
    std::fill(ws.springs.fy.begin(), ws.springs.fy.end(), 0.0);
    std::fill(ws.springs.fz.begin(), ws.springs.fz.end(), 0.0);
    std::int64_t slack = kNoRoom;
    for (size_t c = 0; c < ws.layout.chunks.size(); ++c)
      if (s.region.chunk_awake[c])
        chunk_forces(m, s, ws, ws.layout.chunks[c], true, s.region.active_scale.data(), &slack);
    for (int i = 0; i < nn; ++i) {
      const Vec3 f(ws.springs.fx[i], ws.springs.fy[i], ws.springs.fz[i]);
      ws.force[i] = s.region.awake[i] ? Vec3(m.mass[i] * (m.options.gravity - mu * s.v[i]) + f) : f;
    }
  } else if (ws.bounds.far_every > 0) {
    // Multi-rate: only the awake nodes and the border can receive a force.
    for (int i : s.region.awake_list) ws.force[i] = m.mass[i] * (m.options.gravity - mu * s.v[i]);
    for (int i : s.region.border) ws.force[i].setZero();
  } else {
    for (int i = 0; i < nn; ++i)
      ws.force[i] =
          s.region.awake[i] ? Vec3(m.mass[i] * (m.options.gravity - mu * s.v[i])) : Vec3::Zero();
  }
  for (int q = 0; q < s.region.num_active && !chunked; ++q) {
    const int k = s.region.active[q];
    const int i = m.spring_i[k], j = m.spring_j[k];
    const Vec3 u = s.x[j] - s.x[i];
    const double l = u.norm();
    const Vec3 d = u / std::max(l, 1e-300);
    ws.springs.ux[k] = d.x();
    ws.springs.uy[k] = d.y();
    ws.springs.uz[k] = d.z();
    ws.springs.length[k] = l;
    const double delta = m.deflection_scale[k] * (m.rest_length[k] - l);
    ws.springs.deflection[k] = delta;
    const SpringGroup& g = m.groups[ws.layout.spring_group[k]];
    const double ddot = g.viscous ? -m.deflection_scale[k] * d.dot(s.v[j] - s.v[i]) : 0.0;
    const double load = spring_load(g, delta, ddot, s.maxwell[k]).load;
    ws.springs.load[k] = load;
    const Vec3 f = m.force_scale[k] * load * d;
    ws.force[i] -= f;
    ws.force[j] += f;
  }
  if (ws.bounds.far_every > 0) return;  // the far field moves: its pull is no reason to wake
  const double f_tol = ws.bounds.node_stiffness * m.options.active_tolerance;
  for (int i = 0; i < nn; ++i)
    if (!s.region.awake[i] && m.fixed[i] != 7 && ws.force[i].squaredNorm() > f_tol * f_tol)
      s.region.wake[i] = 1;
}

// The cost of a multi-rate tick with the current region, as a fraction of a whole step: the
// springs the awake side evaluates (lattices: whole chunks holding an awake spring when the region
// is large, else its list at the scalar law's higher price per spring) plus one share of the far
// springs. Checked against measured step times on the 21,952-node block and the liver
// (docs/performance.md, "Active region").
double region_cost(const Model& m, const State& s, const Workspace& ws) {
  const double ns = std::max(1, m.num_springs());
  const double N = std::max(1, ws.bounds.far_every);
  if (ws.layout.runs.empty()) return (s.region.num_active + s.region.slow.size() / N) / ns;
  int awake = 0, slow = 0;
  for (size_t c = 0; c < ws.layout.chunks.size(); ++c) {
    awake += s.region.chunk_awake[c];
    slow += s.region.chunk_slow[c];
  }
  const double C = std::max<size_t>(1, ws.layout.chunks.size());
  const bool chunked = 8 * s.region.num_active > m.num_springs();
  // The chunked path also passes over every node and checks the hard stop spring by spring along
  // the active list: about one listed spring's price per active spring.
  return (chunked ? awake / C + s.region.num_active / ns
                  : kListSpringCost * s.region.num_active / ns) +
         slow / C / N;
}

// Chooses the awake nodes for this tick (see step.h) and rebuilds the active spring list when the
// set changed.
void update_region(const Model& m, State& s, Workspace& ws) {
  const int nn = m.num_nodes();
  constexpr double kNu = 0.25;
  bool changed = s.region.num_active < 0;
  double R[8], Rsleep[8];
  Vec3 c[8];
  int np = 0;
  for (size_t q = 0; q < m.probes.size() && np < 8; ++q) {
    const ProbeState& p = s.probes[q];
    if (!p.active) continue;
    const double rp = probe_radius(m, static_cast<int>(q), p);
    double boussinesq =
        p.force.norm() * (1 - kNu * kNu) / (M_PI * ws.bounds.modulus * m.options.active_tolerance);
    // Multi-rate: the radius grows in steps of 10 % of itself, so that a growing press rebuilds
    // the region's lists (O(springs)) every few intervals rather than at every one.
    if (ws.bounds.far_every > 0 && boussinesq > rp)
      boussinesq = rp * std::pow(1.1, std::ceil(std::log(boussinesq / rp) / std::log(1.1)));
    R[np] = std::max(2 * rp, rp + boussinesq);
    Rsleep[np] = 1.25 * R[np];
    c[np++] = p.proxy_placed && m.probes[q].contact == ContactModel::kSurface ? p.proxy : p.center;
    // The nodes of the triangles the tool touches are awake, however large the triangles are.
    if (p.proxy_placed)
      for (int t : ws.contact.candidates[q].triangles)
        if (tool_touches(m, static_cast<int>(q), rp, p.proxy, s.x, t))
          for (int i : m.surface[t]) s.region.wake[i] = 1;
  }
  int awake_count = 0;
  for (int i = 0; i < nn; ++i) {
    bool near = false, keep = false;
    for (int q = 0; q < np; ++q) {
      const double d2 = (s.x[i] - c[q]).squaredNorm();
      near |= d2 < R[q] * R[q];
      keep |= d2 < Rsleep[q] * Rsleep[q];
    }
    const std::uint8_t now = near || s.region.wake[i] || (s.region.awake[i] && keep);
    if (now != s.region.awake[i]) {
      changed = true;
      s.region.flipped.push_back(i);                           // capacity reserved for every node
      if (!now && ws.bounds.far_every <= 0) s.v[i].setZero();  // frozen: falls asleep at its state
      s.region.awake[i] = now;
    }
    s.region.wake[i] = 0;
    awake_count += now;
  }
  s.counters.awake_nodes = awake_count;
  const bool first = s.region.num_active < 0;
  if (!changed) return;
  s.region.awake_list.clear();  // capacities reserved for every node and spring: no allocation
  for (int i = 0; i < nn; ++i)
    if (s.region.awake[i]) s.region.awake_list.push_back(i);
  for (int i : s.region.border) s.region.in_border[i] = 0;
  s.region.border.clear();
  s.region.slow.clear();
  const bool multirate = ws.bounds.far_every > 0;
  if (multirate && !ws.layout.runs.empty() && !first) {
    // Lattices, multi-rate: only the springs of nodes that changed side change theirs, so the
    // per-spring scales and the per-chunk counts are updated from the node-spring adjacency, and
    // the active list and the border are rebuilt from the awake nodes' springs: O(awake springs)
    // instead of O(springs), so a tick that changes the region stays cheap.
    for (int i : s.region.flipped) {
      for (int e = ws.layout.node_spring_start[i]; e < ws.layout.node_spring_start[i + 1]; ++e) {
        const int k = ws.layout.node_springs[e];
        const std::uint8_t on = s.region.awake[m.spring_i[k]] || s.region.awake[m.spring_j[k]];
        if (on == s.region.spring_on[k]) continue;
        s.region.spring_on[k] = on;
        const int c = ws.layout.spring_chunk[k];
        s.region.chunk_active_count[c] += on ? 1 : -1;
        s.region.active_scale[k] = on ? m.force_scale[k] : 0.0;
        s.region.slow_scale[k] = on ? 0.0 : m.force_scale[k];
      }
    }
    s.region.flipped.clear();
    int n = 0;
    for (int i : s.region.awake_list) {
      for (int e = ws.layout.node_spring_start[i]; e < ws.layout.node_spring_start[i + 1]; ++e) {
        const int k = ws.layout.node_springs[e];
        const int o = m.spring_i[k] == i ? m.spring_j[k] : m.spring_i[k];
        if (!s.region.awake[o]) {
          if (!s.region.in_border[o]) s.region.border.push_back(o);
          s.region.in_border[o] = 1;
        } else if (o < i) {
          continue;  // both awake: listed once, from the end with the smaller index
        }
        s.region.active[n++] = k;
      }
    }
    s.region.num_active = n;
    for (size_t c = 0; c < ws.layout.chunks.size(); ++c) {
      const int size = ws.layout.chunks[c].k1 - ws.layout.chunks[c].k0;
      s.region.chunk_awake[c] = s.region.chunk_active_count[c] > 0;
      s.region.chunk_slow[c] = s.region.chunk_active_count[c] < size;
    }
    return;
  }
  s.region.flipped.clear();
  int n = 0;
  for (int k = 0; k < m.num_springs(); ++k) {
    const int i = m.spring_i[k], j = m.spring_j[k];
    const bool on = s.region.awake[i] || s.region.awake[j];
    if (on) s.region.active[n++] = k;
    s.region.active_scale[k] = on ? m.force_scale[k] : 0.0;
    if (!multirate) continue;
    s.region.slow_scale[k] = on ? 0.0 : m.force_scale[k];
    if (!on && ws.layout.runs.empty()) s.region.slow.push_back(k);
    if (on && !(s.region.awake[i] && s.region.awake[j])) {
      const int b = s.region.awake[i] ? j : i;
      if (!s.region.in_border[b]) s.region.border.push_back(b);
      s.region.in_border[b] = 1;
    }
  }
  s.region.num_active = n;
  for (size_t c = 0; c < ws.layout.chunks.size(); ++c) {
    bool any = false, any_slow = false;
    int count = 0;
    for (int k = ws.layout.chunks[c].k0; k < ws.layout.chunks[c].k1; ++k) {
      s.region.spring_on[k] = s.region.active_scale[k] != 0;
      count += s.region.spring_on[k];
      any |= s.region.active_scale[k] != 0;
      any_slow |= multirate && s.region.slow_scale[k] != 0;
    }
    s.region.chunk_active_count[c] = count;
    s.region.chunk_awake[c] = any;
    s.region.chunk_slow[c] = any_slow;
  }
}

// The far field's forces over one interval, spread over its N ticks: tick `phase` evaluates the
// springs between sleeping nodes of chunks (or list entries) [phase C / N, (phase + 1) C / N) and
// sums their forces into s.region.far_fx, far_fy, far_fz. Sleeping nodes do not move within an
// interval (only the far step moves them), so every share sees the same far state, and the sum
// equals one evaluation at the interval's end: no tick pays the whole far field. Far springs out of
// their linear phase are marked to wake at the next interval.
void far_forces_part(const Model& m, State& s, Workspace& ws, int phase) {
  const int N = ws.bounds.far_every;
  s.region.far_springs_evaluated = 0;
  if (!ws.layout.runs.empty()) {
    if (phase == 0) copy_positions(s.x, ws);  // the far state of this interval
    const int nc = static_cast<int>(ws.layout.chunks.size());
    const int c0 = static_cast<int>(std::int64_t(nc) * phase / N);
    const int c1 = static_cast<int>(std::int64_t(nc) * (phase + 1) / N);
    double* const out[3] = {s.region.far_fx.data(), s.region.far_fy.data(), s.region.far_fz.data()};
    std::int64_t slack = kNoRoom;
    for (int c = c0; c < c1; ++c) {
      if (!s.region.chunk_slow[c]) continue;
      const SpringLayout::Chunk& ch = ws.layout.chunks[c];
      chunk_forces(m, s, ws, ch, false, s.region.slow_scale.data(), &slack, out);
      s.region.far_springs_evaluated += ch.k1 - ch.k0;
      const double limit = ws.layout.tangent_limit[ch.group];
      int stiff = 0;  // counted branch-free: the common case (none) costs a vectorised pass
      const double* __restrict tangent = ws.springs.chunk_tangent.data();
      for (int t = 0; t < ch.k1 - ch.k0; ++t) stiff += tangent[t] > limit;
      if (stiff == 0) continue;
      for (int k = ch.k0; k < ch.k1; ++k)
        if (s.region.slow_scale[k] != 0 && ws.springs.chunk_tangent[k - ch.k0] > limit)
          s.region.wake[m.spring_i[k]] = s.region.wake[m.spring_j[k]] = 1;
    }
    return;
  }
  const int ns = static_cast<int>(s.region.slow.size());
  const int q0 = static_cast<int>(std::int64_t(ns) * phase / N);
  const int q1 = static_cast<int>(std::int64_t(ns) * (phase + 1) / N);
  s.region.far_springs_evaluated = q1 - q0;
  for (int q = q0; q < q1; ++q) {
    const int k = s.region.slow[q];
    const int i = m.spring_i[k], j = m.spring_j[k];
    const Vec3 u = s.x[j] - s.x[i];
    const double l = u.norm();
    const Vec3 d = u / std::max(l, 1e-300);
    const double delta = m.deflection_scale[k] * (m.rest_length[k] - l);
    const SpringGroup& g = m.groups[ws.layout.spring_group[k]];
    const double ddot = g.viscous ? -m.deflection_scale[k] * d.dot(s.v[j] - s.v[i]) : 0.0;
    const SpringLoad p = spring_load(g, delta, ddot, s.maxwell[k]);
    if (p.tangent > ws.layout.tangent_limit[ws.layout.spring_group[k]])
      s.region.wake[i] = s.region.wake[j] = 1;
    const Vec3 f = m.force_scale[k] * p.load * d;
    s.region.far_fx[i] -= f.x();
    s.region.far_fy[i] -= f.y();
    s.region.far_fz[i] -= f.z();
    s.region.far_fx[j] += f.x();
    s.region.far_fy[j] += f.y();
    s.region.far_fz[j] += f.z();
  }
}

// One symplectic Euler step of H = far_every ticks for the sleeping nodes, at the interval's last
// tick: the far springs' forces summed over the interval (far_forces_part) and the node terms
// now, plus the impulse the awake springs gave over the interval. The sums are cleared for the
// next interval. Far nodes behind a plane are marked to wake at the next interval.
void far_step(const Model& m, State& s, Workspace& ws) {
  const int nn = m.num_nodes();
  const double H = ws.bounds.far_every * m.options.dt, mu = m.options.mass_damping;
  for (int i = 0; i < nn; ++i) {
    const Vec3 spring(s.region.far_fx[i], s.region.far_fy[i], s.region.far_fz[i]);
    s.region.far_fx[i] = s.region.far_fy[i] = s.region.far_fz[i] = 0;
    if (s.region.awake[i] || m.fixed[i] == 7) continue;
    const Vec3 f = m.mass[i] * (m.options.gravity - mu * s.v[i]) + spring;
    s.v[i] +=
        ((H * f + s.region.impulse[i]) * ws.bounds.far_inv_mass[i]).cwiseProduct(m.free_axes[i]);
    s.x[i] += (H * s.v[i]).cwiseProduct(m.free_axes[i]);
    s.region.impulse[i].setZero();
    for (size_t q = 0; q < m.planes.size(); ++q)
      if (s.planes[q].offset - m.planes[q].normal.dot(s.x[i]) > 0) s.region.wake[i] = 1;
  }
}

}  // namespace detail

}  // namespace conica
