#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>

#include "core/body.h"
#include "core/contact.h"
#include "core/step_detail.h"
#include "core/volume.h"

namespace conica {
namespace {

// The smallest room (length - min_length) of a set of springs is reduced as the int64 bit
// patterns of the doubles: for rooms >= 0 their order is the doubles' order, any negative room
// gives a negative pattern (that is all the hard-stop test needs: "none may be short"), and an
// integer min vectorises where a floating-point one would need -ffinite-math-only. NaN patterns
// are large: ignored here, caught by the guard after the step.
constexpr std::int64_t kNoRoom = std::numeric_limits<std::int64_t>::max();
double room_of(std::int64_t bits) {
  return bits == kNoRoom ? std::numeric_limits<double>::infinity() : std::bit_cast<double>(bits);
}

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

// Keeps a structure-of-arrays copy of x (the positions of this geometry, for the hard-stop test).
void copy_positions(const std::vector<Vec3>& x, Workspace& ws) {
  const int nn = static_cast<int>(x.size());
  for (int i = 0; i < nn; ++i) {
    ws.px[i] = x[i].x();
    ws.py[i] = x[i].y();
    ws.pz[i] = x[i].z();
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
  const double c = g.card.damping, km = g.card.maxwell_k;
  for (int t = 0; t < n; ++t) {
    const int k = k0 + t;
    const Vec3 d(v.ux[t], v.uy[t], v.uz[t]);
    const double ldot = d.dot(s.v[m.spring_j[k]] - s.v[m.spring_i[k]]);
    const double ddot = -m.deflection_scale[k] * ldot;
    v.load[t] += c * ddot + km * (v.deflection[t] - s.maxwell[k]);
    v.tangent[t] += km;
  }
}

SpringValues values_at(Workspace& ws, int k) {
  return {ws.ux.data() + k,         ws.uy.data() + k,   ws.uz.data() + k,     ws.length.data() + k,
          ws.deflection.data() + k, ws.load.data() + k, ws.tangent.data() + k};
}

// Directions of every spring at the positions of the last geometry (px, py, pz), for a hard stop
// after a step that kept them only chunk by chunk.
void refresh_directions(const Model& m, Workspace& ws) {
  const int ns = m.num_springs();
  for (int k = 0; k < ns; ++k) {
    const int i = m.spring_i[k], j = m.spring_j[k];
    const Vec3 u(ws.px[j] - ws.px[i], ws.py[j] - ws.py[i], ws.pz[j] - ws.pz[i]);
    const Vec3 d = u / std::max(u.norm(), 1e-300);
    ws.ux[k] = d.x();
    ws.uy[k] = d.y();
    ws.uz[k] = d.z();
  }
  ws.directions_kept = true;
}

// Geometry, loads and forces (summed into ws.fx, fy, fz, or into out[0..2] when given) of one
// chunk of springs in runs, with force scales a (per spring); values kept per spring or only in
// the chunk buffers.
void chunk_forces(const Model& m, const State& s, Workspace& ws, const Workspace::Chunk& c,
                  bool keep, const double* __restrict a, std::int64_t* slack,
                  double* const* out = nullptr) {
  double* const fx = out ? out[0] : ws.fx.data();
  double* const fy = out ? out[1] : ws.fy.data();
  double* const fz = out ? out[2] : ws.fz.data();
  const SpringValues v =
      keep ? values_at(ws, c.k0)
           : SpringValues{ws.chunk_ux.data(),     ws.chunk_uy.data(),         ws.chunk_uz.data(),
                          ws.chunk_length.data(), ws.chunk_deflection.data(), ws.chunk_load.data(),
                          ws.chunk_tangent.data()};
  for (int q = c.first_run; q < c.last_run; ++q) {
    const Workspace::Run& r = ws.runs[q];
    const int t = r.k - c.k0;
    run_vectors(r.n, ws.px.data() + r.i, ws.py.data() + r.i, ws.pz.data() + r.i, ws.px.data() + r.j,
                ws.py.data() + r.j, ws.pz.data() + r.j, v.ux + t, v.uy + t, v.uz + t);
  }
  *slack = std::min(
      *slack,
      normalise_chunk(c.k1 - c.k0, m.rest_length.data() + c.k0, m.deflection_scale.data() + c.k0,
                      ws.min_length.data() + c.k0, v.ux, v.uy, v.uz, v.length, v.deflection));
  group_loads(m, s, m.groups[c.group], c.k0, c.k1, v);
  for (int q = c.first_run; q < c.last_run; ++q) {
    const Workspace::Run& r = ws.runs[q];
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
  ws.directions_kept = true;
  if (ws.runs.empty()) {
    const int ns = m.num_springs();
    gather_vectors(ns, s.x.front().data(), m.spring_i.data(), m.spring_j.data(), ws.ux.data(),
                   ws.uy.data(), ws.uz.data());
    ws.slack = room_of(normalise_chunk(ns, m.rest_length.data(), m.deflection_scale.data(),
                                       ws.min_length.data(), ws.ux.data(), ws.uy.data(),
                                       ws.uz.data(), ws.length.data(), ws.deflection.data()));
    for (const SpringGroup& g : m.groups)
      group_loads(m, s, g, g.begin, g.end, values_at(ws, g.begin));
    const double* __restrict load = ws.load.data();
    double* __restrict F = ws.force.front().data();
    for (int k = 0; k < ns; ++k) {
      const double fk = a[k] * load[k];
      const double fx = fk * ws.ux[k], fy = fk * ws.uy[k], fz = fk * ws.uz[k];
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
  keep = keep || ws.hard_stop_near;  // the hard stop will need them: cheaper kept than refreshed
  ws.directions_kept = keep;
  std::fill(ws.fx.begin(), ws.fx.end(), 0.0);
  std::fill(ws.fy.begin(), ws.fy.end(), 0.0);
  std::fill(ws.fz.begin(), ws.fz.end(), 0.0);
  std::int64_t slack = kNoRoom;
  for (const Workspace::Chunk& c : ws.chunks) chunk_forces(m, s, ws, c, keep, a, &slack);
  ws.slack = room_of(slack);
  node_forces(nn, m.mass.data(), s.v.front().data(), ws.fx.data(), ws.fy.data(), ws.fz.data(),
              m.options.gravity.data(), m.options.mass_damping, ws.force.front().data());
}

// Pressure forces of the elements' volume stiffness and the hexahedra's Gauss-point spread
// (core/volume.h), added to ws.force; every element's dV/dx (and the spread's gradients) are kept
// for the implicit system.
void volume_forces(const Model& m, const State& s, Workspace& ws) {
  if (!(m.bulk_modulus > 0)) return;
  const bool spread = m.spread_modulus > 0;
  Vec3* g = ws.volume_grad.data();
  double* coef = ws.volume_coef.data();
  double vq[8];
  auto element = [&](const int* nodes, int n, double v0, Vec3* gq) {
    const double v = element_volume(s.x, nodes, n, g, gq ? vq : nullptr, gq);
    *coef = m.bulk_modulus / std::abs(v0);
    const double p = -*coef * (v - v0);
    for (int a = 0; a < n; ++a) ws.force[nodes[a]] += p * g[a];
    g += n;
    ++coef;
    return v;
  };
  const int nt = static_cast<int>(m.tetrahedra.size());
  for (int e = 0; e < nt; ++e) element(m.tetrahedra[e].data(), 4, m.tet_rest_volume[e], nullptr);
  const int nh = static_cast<int>(m.hexahedra.size());
  for (int e = 0; e < nh; ++e) {
    const int* nodes = m.hexahedra[e].data();
    const double v0 = m.hex_rest_volume[e];
    Vec3* gq = spread ? ws.spread_grad.data() + 64 * e : nullptr;
    const Vec3* gh = g;  // this hexahedron's dV/dx
    const double v = element(nodes, 8, v0, gq);
    if (!spread) continue;
    // Spread: force -(8 kappa_s / |V0|) sum_q d_q G_q with G_q = g_q - g / 8.
    const double cs = 8 * m.spread_modulus / std::abs(v0);
    ws.spread_coef[e] = cs;
    const double* v0q = m.hex_rest_gauss.data() + 8 * e;
    const double mean = (v - v0) / 8;
    for (int q = 0; q < 8; ++q) {
      const double dq = -cs * ((vq[q] - v0q[q]) - mean);
      for (int a = 0; a < 8; ++a) {
        gq[8 * q + a] -= gh[a] / 8;
        ws.force[nodes[a]] += dq * gq[8 * q + a];
      }
    }
  }
}

// Shear stiffness forces of one element on N nodes with `points` tetrahedra / Gauss points
// (core/volume.h), added to ws.force; advances b, v0 and coef past the element.
template <int N>
void shear_element(const Model& m, const State& s, const std::array<int, N>& nodes, int points,
                   const Vec3*& b, const double*& v0, double*& coef, Workspace& ws) {
  Vec3 x[N], f[N];
  for (int a = 0; a < N; ++a) {
    x[a] = s.x[nodes[a]];
    f[a].setZero();
  }
  for (int q = 0; q < points; ++q, b += N) {
    Mat3 F = Mat3::Zero();
    for (int a = 0; a < N; ++a) F.noalias() += x[a] * b[a].transpose();
    Mat3 P;
    double jm;
    isochoric_neo_hookean(F.data(), m.shear_modulus, P.data(), &jm);
    P *= *v0;
    for (int a = 0; a < N; ++a) f[a].noalias() -= P * b[a];
    *coef++ = *v0++ * m.shear_modulus * jm;
  }
  for (int a = 0; a < N; ++a) ws.force[nodes[a]] += f[a];
}

// Shear stiffness forces (core/volume.h), added to ws.force.
void shear_forces(const Model& m, const State& s, Workspace& ws) {
  if (!(m.shear_modulus > 0)) return;
  const Vec3* b = m.shear_b.data();
  const double* v0 = m.shear_v0.data();
  double* coef = ws.shear_coef.data();
  for (const auto& t : m.tetrahedra) shear_element<4>(m, s, t, 1, b, v0, coef, ws);
  for (const auto& h : m.hexahedra) shear_element<8>(m, s, h, 8, b, v0, coef, ws);
}

void hard_stop_project(const Model& m, State& s, Workspace& ws);

// Marks node i as having a contact term this evaluation.
void list_contact_node(Workspace& ws, int i) {
  if (ws.in_contact[i]) return;
  ws.in_contact[i] = 1;
  ws.contact_nodes[ws.num_contact_nodes++] = i;
}

// A probe with the node contact law (step.h): every node inside its sphere, or the listed ones
// only (`nodes`).
// The node law of probe k at `center` against positions x, every node or the listed ones
// (`nodes`): fills probe's force, stiffness and contacts; with a workspace also adds the nodes'
// forces to ws->force and, with the Jacobian, their scaled normals to ws->contact_n.
void node_probe_contact(const Model& m, const std::vector<Vec3>& x, int k, const Vec3& center,
                        ProbeState* p, Workspace* ws = nullptr, bool with_jacobian = false,
                        const std::vector<int>* nodes = nullptr) {
  const int nn = nodes ? static_cast<int>(nodes->size()) : m.num_nodes();
  const double h = detail::substep_of(m);
  p->force.setZero();
  p->stiffness.setZero();
  p->contacts = 0;
  const double R = probe_radius(m, k, *p);
  const double kc = m.probes[k].stiffness;
  for (int n = 0; n < nn; ++n) {
    const int i = nodes ? (*nodes)[n] : n;
    Vec3 f, dir;
    Mat3 dfdc;
    if (!node_contact(x[i], m.normal[i], center, R, kc, &f, &dfdc, &dir)) continue;
    p->force -= f;
    p->stiffness += dfdc;
    ++p->contacts;
    if (!ws) continue;
    ws->force[i] += f;
    // Jacobian h^2 k n n^T stored as a scaled direction (two probes on one node: approximate).
    if (with_jacobian && m.fixed[i] != 7) {
      ws->contact_n[i] += std::sqrt(h * h * kc) * dir;
      list_contact_node(*ws, i);
    }
  }
}

// Contact of probes (at their proxies, core/contact.h) and planes with the body: forces into
// ws.force, each probe node's lumped layer stiffness into ws.contact_block and, with the
// Jacobian, each plane node's scaled normal into ws.contact_n. Planes act on every node, or on
// the listed ones only (`nodes`; the multi-rate far field keeps its nodes out of contact, see
// far_step); a probe's candidate triangles are woken with the region (update_region).
void contact_forces(const Model& m, State& s, Workspace& ws, bool with_jacobian,
                    const std::vector<int>* nodes = nullptr) {
  const int nn = nodes ? static_cast<int>(nodes->size()) : m.num_nodes();
  const double h = detail::substep_of(m);
  for (int q = 0; q < ws.num_contact_nodes; ++q) {
    const int i = ws.contact_nodes[q];
    ws.contact_n[i].setZero();
    ws.contact_block[i].setZero();
    ws.in_contact[i] = 0;
  }
  ws.num_contact_nodes = 0;
  for (size_t q = 0; q < m.probes.size(); ++q) {
    if (m.probes[q].contact == ContactModel::kNodes) {
      ProbeState& p = s.probes[q];
      if (p.active) {
        node_probe_contact(m, s.x, static_cast<int>(q), p.center, &p, &ws, with_jacobian, nodes);
      } else {
        p.force.setZero();
        p.stiffness.setZero();
        p.contacts = 0;
      }
      continue;
    }
    const ProbeState& p = s.probes[q];
    if (!p.active || !p.proxy_placed) continue;
    const std::vector<int>& cand = ws.probe_candidates[q];
    ToolContact c;
    tool_contact(m, static_cast<int>(q), probe_radius(m, static_cast<int>(q), p), p.proxy, s.x,
                 cand.data(), static_cast<int>(cand.size()), &c, ws.force.data(),
                 ws.contact_block.data());
    if (c.faces == 0) continue;
    friction_forces(m, static_cast<int>(q), p, s.x, ws.force.data(), ws.contact_block.data());
    for (int t : cand)
      for (int i : m.surface[t]) list_contact_node(ws, i);
    if (p.stick >= 0)
      for (int i : m.surface[p.stick]) list_contact_node(ws, i);
  }
  for (size_t q = 0; q < m.planes.size(); ++q) {
    PlaneState& pl = s.planes[q];
    pl.force.setZero();
    pl.contacts = 0;
    const Vec3& n = m.planes[q].normal;
    const double kp = m.planes[q].stiffness;
    for (int t = 0; t < nn; ++t) {
      const int i = nodes ? (*nodes)[t] : t;
      const double depth = pl.offset - n.dot(s.x[i]);
      if (depth <= 0) continue;
      const Vec3 f = kp * depth * n;
      ws.force[i] += f;
      pl.force -= f;
      ++pl.contacts;
      // One normal per node for the Jacobian: a node behind two plates keeps the first's, a rare
      // case that only slows convergence.
      if (with_jacobian && m.fixed[i] != 7 && ws.contact_n[i].squaredNorm() == 0) {
        ws.contact_n[i] = std::sqrt(h * h * kp) * n;
        list_contact_node(ws, i);
      }
    }
  }
}

// The proxy stage: every probe's proxy moves toward its device target with the nodes held
// (core/contact.h), leaving the triangles near it for the contact stage.
void update_proxies(const Model& m, State& s, Workspace& ws) {
  for (size_t q = 0; q < m.probes.size(); ++q)
    if (m.probes[q].contact == ContactModel::kSurface)
      update_proxy(m, static_cast<int>(q), s.x, &ws.probe_candidates[q], &s.probes[q]);
}

// Explicit integrators take the contact layer semi-implicitly (step.h): a node with a layer
// stiffness B advances with m (m I + h^2 B)^-1 f instead of f, on its free axes.
void semi_implicit_contact(const Model& m, Workspace& ws, double h) {
  for (int q = 0; q < ws.num_contact_nodes; ++q) {
    const int i = ws.contact_nodes[q];
    if (m.fixed[i] == 7) continue;
    const Mat3& B = ws.contact_block[i];
    if (B.squaredNorm() == 0) continue;
    const Vec3& free = m.free_axes[i];
    const Mat3 A =
        m.mass[i] * Mat3::Identity() + h * h * (free.asDiagonal() * B * free.asDiagonal());
    ws.force[i] = m.mass[i] * A.ldlt().solve(ws.force[i]);
  }
}

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
  const bool chunked = !ws.runs.empty() && 8 * s.region.num_active > m.num_springs();
  if (chunked) {
    copy_positions(s.x, ws);
    std::fill(ws.fx.begin(), ws.fx.end(), 0.0);
    std::fill(ws.fy.begin(), ws.fy.end(), 0.0);
    std::fill(ws.fz.begin(), ws.fz.end(), 0.0);
    std::int64_t slack = kNoRoom;
    for (size_t c = 0; c < ws.chunks.size(); ++c)
      if (s.region.chunk_awake[c])
        chunk_forces(m, s, ws, ws.chunks[c], true, s.region.active_scale.data(), &slack);
    for (int i = 0; i < nn; ++i) {
      const Vec3 f(ws.fx[i], ws.fy[i], ws.fz[i]);
      ws.force[i] = s.region.awake[i] ? Vec3(m.mass[i] * (m.options.gravity - mu * s.v[i]) + f) : f;
    }
  } else if (ws.far_every > 0) {
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
    ws.ux[k] = d.x();
    ws.uy[k] = d.y();
    ws.uz[k] = d.z();
    ws.length[k] = l;
    const double delta = m.deflection_scale[k] * (m.rest_length[k] - l);
    ws.deflection[k] = delta;
    const SpringGroup& g = m.groups[ws.spring_group[k]];
    double load = g.law ? g.law->evaluate(delta).force : g.card.hooke_k * delta;
    if (g.viscous) {
      const double ddot = -m.deflection_scale[k] * d.dot(s.v[j] - s.v[i]);
      load += g.card.damping * ddot + g.card.maxwell_k * (delta - s.maxwell[k]);
    }
    ws.load[k] = load;
    const Vec3 f = m.force_scale[k] * load * d;
    ws.force[i] -= f;
    ws.force[j] += f;
  }
  if (ws.far_every > 0) return;  // the far field moves: its pull is no reason to wake
  const double f_tol = ws.node_stiffness * m.options.active_tolerance;
  for (int i = 0; i < nn; ++i)
    if (!s.region.awake[i] && m.fixed[i] != 7 && ws.force[i].squaredNorm() > f_tol * f_tol)
      s.region.wake[i] = 1;
}

void forces_impl(const Model& m, State& s, Workspace& ws, bool with_jacobian) {
  const int nn = m.num_nodes();
  if (region_in_use(m, s) && !with_jacobian) {
    forces_active(m, s, ws);
    contact_forces(m, s, ws, false, ws.far_every > 0 ? &s.region.awake_list : nullptr);
    return;
  }
  const double mu = m.options.mass_damping;
  if (ws.runs.empty())  // the runs path writes the node terms with the spring forces
    for (int i = 0; i < nn; ++i) ws.force[i] = m.mass[i] * (m.options.gravity - mu * s.v[i]);
  spring_forces(m, s, ws, with_jacobian);
  volume_forces(m, s, ws);
  shear_forces(m, s, ws);
  contact_forces(m, s, ws, with_jacobian);
}

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

// Projects springs shorter than their minimum length back to it (mass-weighted) and removes the
// approaching part of their relative velocity.
void hard_stop(const Model& m, State& s, Workspace& ws) {
  if (region_in_use(m, s) && m.options.integrator != Integrator::kImplicitEuler) {
    // Only springs with an awake end can have moved.
    int n = 0;
    for (int q = 0; q < s.region.num_active; ++q) {
      const int k = s.region.active[q];
      n += (s.x[m.spring_j[k]] - s.x[m.spring_i[k]]).dot(ws.dir(k)) < ws.min_length[k];
    }
    if (n > 0) hard_stop_project(m, s, ws);
    return;
  }
  // Measured along its direction at the last geometry, a spring is no shorter than its length
  // then minus the motion of its two ends since: with no node moved by half the smallest room,
  // none can be short.
  ws.hard_stop_near =
      !(ws.slack > 0) || count_moved(m.num_nodes(), s.x.front().data(), ws.px.data(), ws.py.data(),
                                     ws.pz.data(), 0.5 * ws.slack) > 0;
  if (!ws.hard_stop_near) return;
  if (!ws.directions_kept) refresh_directions(m, ws);
  if (count_short(m.num_springs(), s.x.front().data(), m.spring_i.data(), m.spring_j.data(),
                  ws.ux.data(), ws.uy.data(), ws.uz.data(), ws.min_length.data()) > 0)
    hard_stop_project(m, s, ws);
}

void hard_stop_project(const Model& m, State& s, Workspace& ws) {
  const int ns = m.num_springs();
  for (int k = 0; k < ns; ++k) {
    const int i = m.spring_i[k], j = m.spring_j[k];
    const Vec3 d = ws.dir(k);  // direction before the step: robust to inversion
    const Vec3 u = s.x[j] - s.x[i];
    const double l = u.dot(d);
    const double lmin = ws.min_length[k];
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

void integrate_explicit(const Model& m, State& s, Workspace& ws, bool symplectic) {
  const double h = detail::substep_of(m);
  forces_impl(m, s, ws, false);
  semi_implicit_contact(m, ws, h);
  const int nn = m.num_nodes();
  if (!region_in_use(m, s)) {
    advance_nodes(nn, h, symplectic, ws.force.front().data(), m.inv_mass.data(),
                  m.free_axes.front().data(), s.x.front().data(), s.v.front().data());
    return;
  }
  if (ws.far_every > 0) {
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

}  // namespace

Workspace::Workspace(const Model& m) {
  const size_t ns = m.num_springs(), nn = m.num_nodes();
  deflection.assign(ns, 0);
  load.assign(ns, 0);
  tangent.assign(ns, 0);
  length.assign(ns, 0);
  ux.assign(ns, 1.0);
  uy.assign(ns, 0);
  uz.assign(ns, 0);
  for (size_t k = 0; k < ns; ++k) {  // directions at rest until the first force evaluation
    const Vec3 u = m.rest[m.spring_j[k]] - m.rest[m.spring_i[k]];
    if (u.norm() > 0) {
      ux[k] = u.x() / u.norm();
      uy[k] = u.y() / u.norm();
      uz[k] = u.z() / u.norm();
    }
  }
  min_length.assign(ns, 0);
  min_length2.assign(ns, 0);
  alpha.assign(ns, 0);
  beta.assign(ns, 0);
  force.assign(nn, Vec3::Zero());
  for (auto* v : {&px, &py, &pz, &fx, &fy, &fz}) v->assign(nn, 0.0);
  for (auto* v : {&chunk_ux, &chunk_uy, &chunk_uz, &chunk_length, &chunk_deflection, &chunk_load,
                  &chunk_tangent})
    v->assign(kChunkSprings, 0.0);
  // Runs, cut at group boundaries and into pieces of at most kChunk springs; chunks of whole
  // pieces of one group, about kChunk springs each.
  constexpr int kChunk = kChunkSprings;
  for (int g = 0; g < static_cast<int>(m.groups.size()); ++g) {
    const int end = m.groups[g].end;
    Chunk chunk{g, static_cast<int>(runs.size()), 0, m.groups[g].begin, 0};
    for (int k = m.groups[g].begin; k < end;) {
      int n = 1;
      while (k + n < end && n < kChunk && m.spring_i[k + n] == m.spring_i[k] + n &&
             m.spring_j[k + n] == m.spring_j[k] + n)
        ++n;
      if (k + n - chunk.k0 > kChunk) {
        chunk.last_run = static_cast<int>(runs.size());
        chunk.k1 = k;
        chunks.push_back(chunk);
        chunk = Chunk{g, chunk.last_run, 0, k, 0};
      }
      runs.push_back({k, n, m.spring_i[k], m.spring_j[k]});
      k += n;
    }
    chunk.last_run = static_cast<int>(runs.size());
    chunk.k1 = end;
    if (chunk.k1 > chunk.k0) chunks.push_back(chunk);
  }
  constexpr size_t kMinMeanRun = 4;  // shorter runs: the gather kernels are faster
  if (ns < kMinMeanRun * runs.size()) {
    runs.clear();
    chunks.clear();
  }
  contact_n.assign(nn, Vec3::Zero());
  contact_block.assign(nn, Mat3::Zero());
  contact_nodes.assign(nn, 0);
  in_contact.assign(nn, 0);
  probe_candidates.resize(m.probes.size());
  for (auto& c : probe_candidates) c.reserve(m.surface.size());
  for (auto* v : {&x0, &v0, &good_x, &good_v}) v->assign(nn, Vec3::Zero());
  sys_mass.assign(nn, 0.0);
  sys_free.assign(3 * nn, 0.0);
  for (size_t i = 0; i < nn; ++i)
    for (int c = 0; c < 3; ++c) sys_free[c * nn + i] = m.free_axes[i][c];
  for (auto* v : {&sys_diag, &sys_pre}) v->assign(6 * nn, 0.0);
  for (auto* v : {&sys_rhs, &sys_r, &sys_z, &sys_p, &sys_ap, &sys_dx}) v->assign(3 * nn, 0.0);
  sys_chunk.assign(6 * kChunkSprings, 0.0);
  good_maxwell.assign(ns, 0);
  if (m.shear_modulus > 0) {
    shear_coef.assign(m.shear_v0.size(), 0.0);
    element_lap.assign(16 * m.tetrahedra.size() + 64 * m.hexahedra.size(), 0.0);
  }
  if (m.bulk_modulus > 0) {
    volume_grad.assign(4 * m.tetrahedra.size() + 8 * m.hexahedra.size(), Vec3::Zero());
    volume_coef.assign(m.tetrahedra.size() + m.hexahedra.size(), 0.0);
    if (m.spread_modulus > 0) {
      spread_grad.assign(64 * m.hexahedra.size(), Vec3::Zero());
      spread_coef.assign(m.hexahedra.size(), 0.0);
    }
  }
  spring_group.assign(ns, 0);
  for (size_t g = 0; g < m.groups.size(); ++g)
    for (int k = m.groups[g].begin; k < m.groups[g].end; ++k) spring_group[k] = static_cast<int>(g);
  // Network modulus E = sum(k_ax l0^2) / (6 V) (isotropic central-force network, nu = 1/4) and the
  // mean axial stiffness per node, from the stiffness of every spring at rest (K0; k_t(delta0)
  // for a pre-compressed conical card).
  const double volume = body_volume(m);
  double kl2 = 0, ksum = 0;
  for (const SpringGroup& g : m.groups) {
    const double k0 = g.law ? g.law->rest_stiffness() : g.card.hooke_k;
    for (int k = g.begin; k < g.end; ++k) {
      const double kax = m.force_scale[k] * m.deflection_scale[k] * k0;
      kl2 += kax * m.rest_length[k] * m.rest_length[k];
      ksum += kax;
    }
  }
  modulus = volume > 0 ? kl2 / (6 * volume) : 1.0;
  node_stiffness = nn > 0 ? 2 * ksum / nn : 1.0;
  // Multi-rate far field: omega^2 <= max_i 2 sum(a b K0) / m_i over free nodes (Gershgorin on
  // M^-1 K in the linear phase), and symplectic Euler needs H omega < 2.
  {
    std::vector<double> node_k(nn, 0.0);
    for (const SpringGroup& g : m.groups) {
      const double k0 = (g.law ? g.law->rest_stiffness() : g.card.hooke_k) + g.card.maxwell_k;
      for (int k = g.begin; k < g.end; ++k) {
        const double kax = m.force_scale[k] * m.deflection_scale[k] * k0;
        node_k[m.spring_i[k]] += kax;
        node_k[m.spring_j[k]] += kax;
      }
      tangent_limit.push_back(1.5 * (g.law ? g.law->rest_stiffness() : g.card.hooke_k) +
                              g.card.maxwell_k);
      has_maxwell |= g.card.maxwell_k > 0;
    }
    double omega2 = 0;
    for (size_t i = 0; i < nn; ++i)
      if (m.fixed[i] != 7) omega2 = std::max(omega2, 2 * node_k[i] * m.inv_mass[i]);
    const double dt = m.options.dt;
    far_max_every = omega2 > 0 ? std::max(1, int(0.9 * 2 / (dt * std::sqrt(omega2)))) : 1;
    // The light nodes (edges and corners of a lattice, small cells of a mesh) set that bound; the
    // automatic interval is the typical node's (median of 2 sum(a b K0) / m), and far nodes
    // lighter than their springs allow at that interval step with a larger inertia
    // m' = H^2 2 sum(a b K0) / (2 * 0.9)^2 (their weight and damping keep the true mass), so that
    // every row of M'^-1 K meets H omega < 2 with the 0.9 margin.
    std::vector<double> rate;
    for (size_t i = 0; i < nn; ++i)
      if (m.fixed[i] != 7) rate.push_back(2 * node_k[i] * m.inv_mass[i]);
    int typical = far_max_every;
    if (!rate.empty()) {
      std::nth_element(rate.begin(), rate.begin() + rate.size() / 2, rate.end());
      const double w2 = rate[rate.size() / 2];
      if (w2 > 0) typical = std::max(far_max_every, int(0.9 * 2 / (dt * std::sqrt(w2))));
    }
    // Measured instead: the largest eigenvalue of M^-1 K (linear phase, at rest) by Lanczos, and
    // the dampers' explicit damping, which lowers the bound (see far_spectral_bound).
    measured_every = 0;
    double ratio = 0;  // largest dashpot / stiffness ratio of a group, s
    for (const SpringGroup& g : m.groups) {
      const double k = (g.law ? g.law->k0() : g.card.hooke_k) + g.card.maxwell_k;
      if (k > 0) ratio = std::max(ratio, g.card.damping / k);
    }
    // Symplectic Euler with explicit damping g on a mode omega^2 = lambda is stable while
    // H^2 lambda + 2 H g < 4; with the 0.9 margin on H omega: <= 1.8^2. An inertia raised by a
    // factor s on every far node divides lambda and the dashpots' part of g by s: the smallest s
    // that keeps an interval of n ticks stable.
    auto raise_for = [&](int n) {
      const double H = n * dt, room = 1.8 * 1.8 - 2 * H * m.options.mass_damping;
      if (!(room > 0)) return std::numeric_limits<double>::infinity();
      return std::max(1.0, (H * H * far_lambda + 2 * H * ratio * far_lambda) / room);
    };
    if (m.options.active_region && m.options.active_far_every >= 0) {
      far_lambda = far_spectral_bound(m);
      far_gamma = m.options.mass_damping + ratio * far_lambda;
      // The interval is the longest that needs s <= 1.1 (far frequencies within 5 %).
      for (int n = 1; n < 64 && raise_for(n) <= 1.1; ++n) measured_every = n;
      // A mesh whose few lightest, stiffest nodes set the spectrum keeps the typical node's
      // interval with their inertia raised (below) when that is longer.
      typical = std::max(typical, measured_every);
    }
    far_every = m.options.active_far_every < 0    ? 0
                : m.options.active_far_every == 0 ? typical
                                                  : m.options.active_far_every;
    far_inv_mass = m.inv_mass;
    const double H = std::max(far_every, 1) * dt;
    const bool raise = measured_every == 0 || far_every > measured_every;
    far_raise = 1;
    if (!raise && far_every > 0) {
      far_raise = raise_for(far_every);
      for (size_t i = 0; i < nn; ++i) far_inv_mass[i] = m.inv_mass[i] / far_raise;
    }
    for (size_t i = 0; i < nn && raise; ++i)
      if (node_k[i] > 0)
        far_inv_mass[i] = std::min(m.inv_mass[i], (2 * 0.9) * (2 * 0.9) / (H * H * 2 * node_k[i]));
  }
  node_spring_start.assign(nn + 1, 0);
  for (size_t k = 0; k < ns; ++k) {
    ++node_spring_start[m.spring_i[k] + 1];
    ++node_spring_start[m.spring_j[k] + 1];
  }
  for (size_t i = 0; i < nn; ++i) node_spring_start[i + 1] += node_spring_start[i];
  node_springs.assign(2 * ns, 0);
  {
    std::vector<int> fill(node_spring_start.begin(), node_spring_start.end() - 1);
    for (size_t k = 0; k < ns; ++k) {
      node_springs[fill[m.spring_i[k]]++] = static_cast<int>(k);
      node_springs[fill[m.spring_j[k]]++] = static_cast<int>(k);
    }
  }
  spring_chunk.assign(ns, 0);
  for (size_t c = 0; c < chunks.size(); ++c)
    for (int k = chunks[c].k0; k < chunks[c].k1; ++k) spring_chunk[k] = static_cast<int>(c);
  for (const SpringGroup& g : m.groups) {
    for (int k = g.begin; k < g.end; ++k) {
      const double l0 = m.rest_length[k];
      double lmin = m.options.min_length_fraction * l0;
      if (g.law) lmin = std::max(lmin, l0 - g.law->remaining_stroke() / m.deflection_scale[k]);
      if (!m.options.hard_stop) lmin = -std::numeric_limits<double>::infinity();
      min_length[k] = lmin;
      min_length2[k] = lmin * lmin;
    }
  }
}

void options_changed(const Model& m, State& s, Workspace& ws) {
  const int old_every = ws.far_every;
  ws = Workspace(m);
  if (ws.far_every == old_every) return;
  RegionState& r = s.region;
  r.far_phase = 0;
  r.num_active = -1;
  std::fill(r.impulse.begin(), r.impulse.end(), Vec3::Zero());
  for (auto* f : {&r.far_fx, &r.far_fy, &r.far_fz}) std::fill(f->begin(), f->end(), 0.0);
}

double far_spectral_bound(const Model& m) {
  // Lanczos on A = M^-1/2 K M^-1/2 over the free axes, K = sum a b (K0 + k_m) d d^T at rest.
  // The largest Ritz value plus its residual |beta_j s_j| bounds the eigenvalue it converges to
  // from above; 40 iterations resolve the top of a lattice's spectrum to about 1 %.
  const int nn = m.num_nodes(), ns = m.num_springs();
  std::vector<double> w(3 * nn), q(3 * nn, 0.0), qprev(3 * nn, 0.0), y(3 * nn), kax(ns);
  std::vector<Vec3> dir(ns);
  for (const SpringGroup& g : m.groups) {
    const double k0 = (g.law ? g.law->k0() : g.card.hooke_k) + g.card.maxwell_k;
    for (int k = g.begin; k < g.end; ++k) {
      kax[k] = m.force_scale[k] * m.deflection_scale[k] * k0;
      const Vec3 u = m.rest[m.spring_j[k]] - m.rest[m.spring_i[k]];
      dir[k] = u / std::max(u.norm(), 1e-300);
    }
  }
  for (int i = 0; i < nn; ++i)
    for (int c = 0; c < 3; ++c) w[3 * i + c] = std::sqrt(m.inv_mass[i]) * m.free_axes[i][c];
  auto apply = [&](const std::vector<double>& x, std::vector<double>& out) {
    std::fill(out.begin(), out.end(), 0.0);
    for (int k = 0; k < ns; ++k) {
      const int i = 3 * m.spring_i[k], j = 3 * m.spring_j[k];
      const Vec3 xi(w[i] * x[i], w[i + 1] * x[i + 1], w[i + 2] * x[i + 2]);
      const Vec3 xj(w[j] * x[j], w[j + 1] * x[j + 1], w[j + 2] * x[j + 2]);
      const Vec3 f = kax[k] * dir[k].dot(xj - xi) * dir[k];
      for (int c = 0; c < 3; ++c) {
        out[i + c] -= f[c];
        out[j + c] += f[c];
      }
    }
    for (int t = 0; t < 3 * nn; ++t) out[t] *= w[t];
  };
  // Deterministic start with every mode present: a fixed pseudo-random vector.
  std::uint64_t seed = 0x9e3779b97f4a7c15ULL;
  double norm = 0;
  for (int t = 0; t < 3 * nn; ++t) {
    seed = seed * 6364136223846793005ULL + 1442695040888963407ULL;
    q[t] = (double(seed >> 11) / double(1ULL << 53) - 0.5) * (w[t] > 0);
    norm += q[t] * q[t];
  }
  if (!(norm > 0)) return 0;
  for (double& v : q) v /= std::sqrt(norm);
  constexpr int kIter = 40;
  std::vector<double> alpha, beta;
  double b = 0;
  for (int it = 0; it < kIter; ++it) {
    apply(q, y);
    double a = 0;
    for (int t = 0; t < 3 * nn; ++t) a += q[t] * y[t];
    for (int t = 0; t < 3 * nn; ++t) y[t] -= a * q[t] + b * qprev[t];
    alpha.push_back(a);
    double nb = 0;
    for (double v : y) nb += v * v;
    nb = std::sqrt(nb);
    beta.push_back(nb);
    if (!(nb > 1e-12 * std::abs(a))) break;
    qprev.swap(q);
    for (int t = 0; t < 3 * nn; ++t) q[t] = y[t] / nb;
    b = nb;
  }
  const int k = static_cast<int>(alpha.size());
  Eigen::MatrixXd T = Eigen::MatrixXd::Zero(k, k);
  for (int i = 0; i < k; ++i) {
    T(i, i) = alpha[i];
    if (i + 1 < k) T(i, i + 1) = T(i + 1, i) = beta[i];
  }
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(T);
  const double theta = eig.eigenvalues()(k - 1);
  const double residual = std::abs(beta[k - 1] * eig.eigenvectors()(k - 1, k - 1));
  return theta + residual;
}

void compute_forces(const Model& model, State& state, Workspace& ws) {
  update_proxies(model, state, ws);
  forces_impl(model, state, ws, false);
}

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
  if (m.bulk_modulus > 0) {
    Vec3 g[8];
    double vq[8];
    const bool spread = m.spread_modulus > 0;
    for (size_t t = 0; t < m.tetrahedra.size(); ++t) {
      const double d = element_volume(s.x, m.tetrahedra[t].data(), 4, g) - m.tet_rest_volume[t];
      e += 0.5 * m.bulk_modulus / std::abs(m.tet_rest_volume[t]) * d * d;
    }
    for (size_t h = 0; h < m.hexahedra.size(); ++h) {
      const double v0 = m.hex_rest_volume[h];
      const double d = element_volume(s.x, m.hexahedra[h].data(), 8, g, vq) - v0;
      e += 0.5 * m.bulk_modulus / std::abs(v0) * d * d;
      for (int q = 0; q < 8 && spread; ++q) {
        const double dq = vq[q] - m.hex_rest_gauss[8 * h + q] - d / 8;
        e += 0.5 * 8 * m.spread_modulus / std::abs(v0) * dq * dq;
      }
    }
  }
  if (m.shear_modulus > 0) {
    const Vec3* b = m.shear_b.data();
    const double* v0 = m.shear_v0.data();
    auto point = [&](const int* nodes, int n) {
      const Mat3 F = deformation_gradient(s.x, nodes, n, b);
      Mat3 P;
      double jm;
      e += *v0++ * isochoric_neo_hookean(F.data(), m.shear_modulus, P.data(), &jm);
      b += n;
    };
    for (const auto& t : m.tetrahedra) point(t.data(), 4);
    for (const auto& h : m.hexahedra)
      for (int q = 0; q < 8; ++q) point(h.data(), 8);
  }
  for (size_t q = 0; q < m.probes.size(); ++q) {
    const ProbeState& p = s.probes[q];
    if (!p.active || m.probes[q].contact != ContactModel::kNodes) continue;
    const double R = p.radius > 0 ? p.radius : m.probes[q].radius;
    for (int i = 0; i < m.num_nodes(); ++i) {
      const Vec3 u = s.x[i] - p.center;
      const double r2 = u.squaredNorm();
      if (r2 >= R * R) continue;
      double depth;
      if (m.normal[i].squaredNorm() > 0) {
        const double a = u.dot(m.normal[i]);
        depth = a + std::sqrt(std::max(a * a - r2 + R * R, 0.0));
      } else {
        depth = R - std::sqrt(r2);
      }
      e += 0.5 * m.probes[q].stiffness * depth * depth;
    }
  }
  for (size_t q = 0; q < m.probes.size(); ++q) {
    const ProbeState& p = s.probes[q];
    if (!p.active || !p.proxy_placed || m.probes[q].contact != ContactModel::kSurface) continue;
    ToolContact c;
    const double R = probe_radius(m, static_cast<int>(q), p);
    tool_contact(m, static_cast<int>(q), R, p.proxy, s.x, nullptr, 0, &c);
    // The layer and the virtual coupling between the device and the proxy.
    e += c.energy +
         0.5 * coupling_stiffness(m, static_cast<int>(q), R) * (p.proxy - p.center).squaredNorm();
  }
  for (size_t q = 0; q < m.planes.size(); ++q)
    for (const Vec3& x : s.x) {
      const double depth = s.planes[q].offset - m.planes[q].normal.dot(x);
      if (depth > 0) e += 0.5 * m.planes[q].stiffness * depth * depth;
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

bool node_contact(const Vec3& x, const Vec3& normal, const Vec3& c, double R, double kc,
                  Vec3* f_node, Mat3* dfdc, Vec3* dir) {
  const Vec3 u = x - c;
  const double r2 = u.squaredNorm(), R2 = R * R;
  if (r2 >= R2) return false;
  if (normal.squaredNorm() > 0) {
    // Surface node: pushed inward along -n by the depth s = min(a + sqrt(a^2 - r^2 + R^2),
    // kContactDepthCap (R - r)), a = u.n: the distance it needs to leave the sphere along -n
    // (so the probe is pushed out of the body even when it has slipped between surface nodes),
    // capped by a multiple of its radial depth, which makes the force vanish on the sphere
    // (continuous) with a bounded slope (see step.h).
    const double a = u.dot(normal);
    const double sq = std::sqrt(std::max(a * a - r2 + R2, 1e-12 * R2));
    const double r = std::sqrt(r2);
    const double cap = kContactDepthCap * (R - r);
    Vec3 dsdu;
    double depth;
    if (a + sq <= cap || !(r > 1e-12 * R)) {
      depth = a + sq;
      dsdu = normal + (a * normal - u) / sq;
    } else {
      depth = cap;
      dsdu = -kContactDepthCap / r * u;
    }
    *f_node = -kc * depth * normal;
    *dfdc = -kc * normal * dsdu.transpose();
    *dir = normal;
  } else {
    // Interior node (a probe that went deep): pushed radially out of the sphere. A node at the
    // exact centre is pushed along +z: bounded, never NaN.
    const double r = std::sqrt(r2);
    const bool centred = !(r > 1e-12 * R);
    const Vec3 n = centred ? Vec3::UnitZ() : Vec3(u / r);
    *f_node = kc * (R - r) * n;
    const Mat3 nnT = n * n.transpose();
    *dfdc = kc * (-nnT + (centred ? 0.0 : (R - r) / r) * (Mat3::Identity() - nnT));
    *dir = n;
  }
  return true;
}

void probe_contact(const Model& m, const std::vector<Vec3>& x, int k, const Vec3& center,
                   double radius, ProbeState* probe, std::vector<int>* candidates) {
  probe->center = center;
  probe->active = true;
  if (radius > 0) probe->radius = radius;
  if (m.probes[k].contact == ContactModel::kSurface)
    update_proxy(m, k, x, candidates, probe);
  else
    node_probe_contact(m, x, k, center, probe);
}

void set_probe(State& state, int probe, const Vec3& center, bool active) {
  state.probes[probe].center = center;
  state.probes[probe].active = active;
}

// The cost of a multi-rate tick with the current region, as a fraction of a whole step: the
// springs the awake side evaluates (lattices: whole chunks holding an awake spring when the region
// is large, else its list at the scalar law's higher price per spring) plus one share of the far
// springs. Checked against measured step times on the 21,952-node block and the liver
// (docs/performance.md, "Active region").
double region_cost(const Model& m, const State& s, const Workspace& ws) {
  const double ns = std::max(1, m.num_springs());
  const double N = std::max(1, ws.far_every);
  if (ws.runs.empty()) return (s.region.num_active + s.region.slow.size() / N) / ns;
  int awake = 0, slow = 0;
  for (size_t c = 0; c < ws.chunks.size(); ++c) {
    awake += s.region.chunk_awake[c];
    slow += s.region.chunk_slow[c];
  }
  const double C = std::max<size_t>(1, ws.chunks.size());
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
    const double rp = p.radius > 0 ? p.radius : m.probes[q].radius;
    double boussinesq =
        p.force.norm() * (1 - kNu * kNu) / (M_PI * ws.modulus * m.options.active_tolerance);
    // Multi-rate: the radius grows in steps of 10 % of itself, so that a growing press rebuilds
    // the region's lists (O(springs)) every few intervals rather than at every one.
    if (ws.far_every > 0 && boussinesq > rp)
      boussinesq = rp * std::pow(1.1, std::ceil(std::log(boussinesq / rp) / std::log(1.1)));
    R[np] = std::max(2 * rp, rp + boussinesq);
    Rsleep[np] = 1.25 * R[np];
    c[np++] = p.proxy_placed && m.probes[q].contact == ContactModel::kSurface ? p.proxy : p.center;
    // The nodes of the triangles the tool touches are awake, however large the triangles are.
    if (p.proxy_placed)
      for (int t : ws.probe_candidates[q])
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
      s.region.flipped.push_back(i);                    // capacity reserved for every node
      if (!now && ws.far_every <= 0) s.v[i].setZero();  // frozen: falls asleep at its state
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
  const bool multirate = ws.far_every > 0;
  if (multirate && !ws.runs.empty() && !first) {
    // Lattices, multi-rate: only the springs of nodes that changed side change theirs, so the
    // per-spring scales and the per-chunk counts are updated from the node-spring adjacency, and
    // the active list and the border are rebuilt from the awake nodes' springs: O(awake springs)
    // instead of O(springs), so a tick that changes the region stays cheap.
    for (int i : s.region.flipped) {
      for (int e = ws.node_spring_start[i]; e < ws.node_spring_start[i + 1]; ++e) {
        const int k = ws.node_springs[e];
        const std::uint8_t on = s.region.awake[m.spring_i[k]] || s.region.awake[m.spring_j[k]];
        if (on == s.region.spring_on[k]) continue;
        s.region.spring_on[k] = on;
        const int c = ws.spring_chunk[k];
        s.region.chunk_active_count[c] += on ? 1 : -1;
        s.region.active_scale[k] = on ? m.force_scale[k] : 0.0;
        s.region.slow_scale[k] = on ? 0.0 : m.force_scale[k];
      }
    }
    s.region.flipped.clear();
    int n = 0;
    for (int i : s.region.awake_list) {
      for (int e = ws.node_spring_start[i]; e < ws.node_spring_start[i + 1]; ++e) {
        const int k = ws.node_springs[e];
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
    for (size_t c = 0; c < ws.chunks.size(); ++c) {
      const int size = ws.chunks[c].k1 - ws.chunks[c].k0;
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
    if (!on && ws.runs.empty()) s.region.slow.push_back(k);
    if (on && !(s.region.awake[i] && s.region.awake[j])) {
      const int b = s.region.awake[i] ? j : i;
      if (!s.region.in_border[b]) s.region.border.push_back(b);
      s.region.in_border[b] = 1;
    }
  }
  s.region.num_active = n;
  for (size_t c = 0; c < ws.chunks.size(); ++c) {
    bool any = false, any_slow = false;
    int count = 0;
    for (int k = ws.chunks[c].k0; k < ws.chunks[c].k1; ++k) {
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
  const int N = ws.far_every;
  s.region.far_springs_evaluated = 0;
  if (!ws.runs.empty()) {
    if (phase == 0) copy_positions(s.x, ws);  // the far state of this interval
    const int nc = static_cast<int>(ws.chunks.size());
    const int c0 = static_cast<int>(std::int64_t(nc) * phase / N);
    const int c1 = static_cast<int>(std::int64_t(nc) * (phase + 1) / N);
    double* const out[3] = {s.region.far_fx.data(), s.region.far_fy.data(), s.region.far_fz.data()};
    std::int64_t slack = kNoRoom;
    for (int c = c0; c < c1; ++c) {
      if (!s.region.chunk_slow[c]) continue;
      const Workspace::Chunk& ch = ws.chunks[c];
      chunk_forces(m, s, ws, ch, false, s.region.slow_scale.data(), &slack, out);
      s.region.far_springs_evaluated += ch.k1 - ch.k0;
      const double limit = ws.tangent_limit[ch.group];
      int stiff = 0;  // counted branch-free: the common case (none) costs a vectorised pass
      const double* __restrict tangent = ws.chunk_tangent.data();
      for (int t = 0; t < ch.k1 - ch.k0; ++t) stiff += tangent[t] > limit;
      if (stiff == 0) continue;
      for (int k = ch.k0; k < ch.k1; ++k)
        if (s.region.slow_scale[k] != 0 && ws.chunk_tangent[k - ch.k0] > limit)
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
    const SpringGroup& g = m.groups[ws.spring_group[k]];
    double load = g.card.hooke_k * delta, tangent = g.card.hooke_k;
    if (g.law) {
      const LawSample e = g.law->evaluate(delta);
      load = e.force;
      tangent = e.stiffness;
    }
    if (g.viscous) {
      const double ddot = -m.deflection_scale[k] * d.dot(s.v[j] - s.v[i]);
      load += g.card.damping * ddot + g.card.maxwell_k * (delta - s.maxwell[k]);
      tangent += g.card.maxwell_k;
    }
    if (tangent > ws.tangent_limit[ws.spring_group[k]]) s.region.wake[i] = s.region.wake[j] = 1;
    const Vec3 f = m.force_scale[k] * load * d;
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
  const double H = ws.far_every * m.options.dt, mu = m.options.mass_damping;
  for (int i = 0; i < nn; ++i) {
    const Vec3 spring(s.region.far_fx[i], s.region.far_fy[i], s.region.far_fz[i]);
    s.region.far_fx[i] = s.region.far_fy[i] = s.region.far_fz[i] = 0;
    if (s.region.awake[i] || m.fixed[i] == 7) continue;
    const Vec3 f = m.mass[i] * (m.options.gravity - mu * s.v[i]) + spring;
    s.v[i] += ((H * f + s.region.impulse[i]) * ws.far_inv_mass[i]).cwiseProduct(m.free_axes[i]);
    s.x[i] += (H * s.v[i]).cwiseProduct(m.free_axes[i]);
    s.region.impulse[i].setZero();
    for (size_t q = 0; q < m.planes.size(); ++q)
      if (s.planes[q].offset - m.planes[q].normal.dot(s.x[i]) > 0) s.region.wake[i] = 1;
  }
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

StepStatus step(const Model& m, State& s, Workspace& ws) {
  update_proxies(m, s, ws);
  const bool region = m.options.active_region && m.options.integrator != Integrator::kImplicitEuler;
  // Multi-rate far field: the region is chosen at the start of an interval, the far field steps at
  // its end; in between only the awake nodes change, and only they are saved and checked.
  bool multirate = region && ws.far_every > 0;
  if (region && (!multirate || s.region.far_phase == 0 || s.region.num_active < 0)) {
    update_region(m, s, ws);
    // A region that costs about a whole step is not worth its bookkeeping: the whole body steps
    // every tick until the region's cost falls well below it (hysteresis). The switch happens at
    // an interval's start, when no far share or impulse is pending.
    if (multirate) {
      s.region.cost = region_cost(m, s, ws);
      const double enter = m.options.active_whole_body_cost;
      s.region.whole_body =
          s.region.cost > (s.region.whole_body ? kRegionResumeFraction * enter : enter);
    }
  }
  if (multirate && s.region.whole_body) {
    multirate = false;
    s.counters.awake_nodes = static_cast<std::uint64_t>(m.num_nodes());
  }
  const bool far_tick = multirate && s.region.far_phase == ws.far_every - 1;
  const bool partial = multirate && !far_tick;
  if (partial) {
    for (int i : s.region.awake_list) {
      ws.good_x[i] = s.x[i];
      ws.good_v[i] = s.v[i];
    }
  } else {
    std::copy(s.x.begin(), s.x.end(), ws.good_x.begin());
    std::copy(s.v.begin(), s.v.end(), ws.good_v.begin());
  }
  if (ws.has_maxwell) std::copy(s.maxwell.begin(), s.maxwell.end(), ws.good_maxwell.begin());
  const double h = detail::substep_of(m);
  for (int sub = 0; sub < m.options.substeps; ++sub) {
    switch (m.options.integrator) {
      case Integrator::kSymplecticEuler:
        integrate_explicit(m, s, ws, true);
        break;
      case Integrator::kExplicitEuler:
        integrate_explicit(m, s, ws, false);
        break;
      case Integrator::kImplicitEuler:
        detail::integrate_implicit(m, s, ws);
        break;
    }
    hard_stop(m, s, ws);
    relax_maxwell(m, s, h);
  }
  if (multirate) far_forces_part(m, s, ws, s.region.far_phase);
  if (far_tick) far_step(m, s, ws);
  if (multirate) s.region.far_phase = (s.region.far_phase + 1) % ws.far_every;
  ++s.counters.steps;
  ++s.tick;
  s.time += m.options.dt;
  if (partial ? nodes_ok(m, s, s.region.awake_list) : state_ok(m, s)) return StepStatus::kOk;
  if (partial) {
    for (int i : s.region.awake_list) s.x[i] = ws.good_x[i];
    for (int i : s.region.border) s.region.impulse[i].setZero();
  } else {
    std::copy(ws.good_x.begin(), ws.good_x.end(), s.x.begin());
  }
  std::fill(s.v.begin(), s.v.end(), Vec3::Zero());
  if (ws.has_maxwell) std::copy(ws.good_maxwell.begin(), ws.good_maxwell.end(), s.maxwell.begin());
  ++s.counters.rollbacks;
  return StepStatus::kRolledBack;
}

namespace detail {

void evaluate_forces(const Model& m, State& s, Workspace& ws, bool with_jacobian) {
  forces_impl(m, s, ws, with_jacobian);
}

void apply_hard_stop(const Model& m, State& s, Workspace& ws) { hard_stop(m, s, ws); }

}  // namespace detail

}  // namespace conica
