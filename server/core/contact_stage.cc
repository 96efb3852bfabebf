// Contact stage: probes (node law or surface proxy, core/contact.h) and planes against the body
// (step.h), the explicit integrators' semi-implicit contact update, and the between-tick reply.
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

// Marks node i as having a contact term this evaluation.
void list_contact_node(Workspace& ws, int i) {
  if (ws.contact.in_contact[i]) return;
  ws.contact.in_contact[i] = 1;
  ws.contact.nodes[ws.contact.num_nodes++] = i;
}

}  // namespace

// A probe with the node contact law (step.h): every node inside its sphere, or the listed ones
// only (`nodes`).
// The node law of probe k at `center` against positions x, every node or the listed ones
// (`nodes`): fills probe's force, stiffness and contacts; with a workspace also adds the nodes'
// forces to ws->force and, with the Jacobian, their scaled normals to ws->contact.n.
void node_probe_contact(const Model& m, const std::vector<Vec3>& x, int k, const Vec3& center,
                        ProbeState* p, Workspace* ws, bool with_jacobian,
                        const std::vector<int>* nodes, double h_system) {
  const int nn = nodes ? static_cast<int>(nodes->size()) : m.num_nodes();
  const double h = h_system > 0 ? h_system : detail::substep_of(m);
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
      ws->contact.n[i] += std::sqrt(h * h * kc) * dir;
      list_contact_node(*ws, i);
    }
  }
}

// Contact of probes (at their proxies, core/contact.h) and planes with the body: forces into
// ws.force, each probe node's lumped layer stiffness into ws.contact.block and, with the
// Jacobian, each plane node's scaled normal into ws.contact.n. Planes act on every node, or on
// the listed ones only (`nodes`; the multi-rate far field keeps its nodes out of contact, see
// far_step); a probe's candidate triangles are woken with the region (update_region).
void contact_forces(const Model& m, State& s, Workspace& ws, bool with_jacobian,
                    const std::vector<int>* nodes) {
  const int nn = nodes ? static_cast<int>(nodes->size()) : m.num_nodes();
  const double h = detail::implicit_h(m, s);  // the implicit system's step (BDF2: 2h / 3)
  for (int q = 0; q < ws.contact.num_nodes; ++q) {
    const int i = ws.contact.nodes[q];
    ws.contact.n[i].setZero();
    ws.contact.block[i].setZero();
    ws.contact.v_ref[i].setZero();
    ws.contact.in_contact[i] = 0;
  }
  ws.contact.num_nodes = 0;
  ws.contact.num_pairs = 0;
  for (size_t q = 0; q < m.probes.size(); ++q) {
    if (m.probes[q].contact == ContactModel::kNodes) {
      ProbeState& p = s.probes[q];
      if (p.active) {
        node_probe_contact(m, s.x, static_cast<int>(q), p.center, &p, &ws, with_jacobian, nodes, h);
      } else {
        p.force.setZero();
        p.stiffness.setZero();
        p.contacts = 0;
      }
      continue;
    }
    const ProbeState& p = s.probes[q];
    if (!p.active || !p.proxy_placed) continue;
    const std::vector<int>& cand = ws.contact.candidates[q].triangles;
    const double R = probe_radius(m, static_cast<int>(q), p);
    // Bonded nodes: held at proxy + bond[i] by their springs, taken implicitly like the layer.
    const double k_layer = p.bonded.empty() ? 0.0 : contact_layer(m, static_cast<int>(q), R).k;
    for (int i : p.bonded) {
      const double ki = k_layer * p.bond_area[i];
      ws.force[i] += ki * (p.proxy + p.bond[i] - s.x[i]);
      ws.contact.block[i] += ki * Mat3::Identity();
      list_contact_node(ws, i);
      ws.contact.v_ref[i] = p.proxy_velocity;
    }
    ToolContact c;
    const int nc = static_cast<int>(cand.size());
    if (with_jacobian) {  // the implicit system: the layer's pair blocks, face by face
      const int base = ws.contact.num_pairs;
      Mat3* pairs = ws.contact.pair.data() + 6 * base;
      std::fill(pairs, pairs + 6 * nc, Mat3::Zero());
      tool_contact(m, static_cast<int>(q), R, p.proxy, s.x, cand.data(), nc, &c, ws.force.data(),
                   nullptr, kToolForceOnly | kToolPairPressureOnly, nullptr, pairs);
      int kept = 0;  // the touched faces, in place
      for (int t = 0; t < nc; ++t) {
        bool touched = false;
        for (int j = 0; j < 6 && !touched; ++j) touched = pairs[6 * t + j].squaredNorm() > 0;
        if (!touched) continue;
        if (kept != t) std::copy(pairs + 6 * t, pairs + 6 * t + 6, pairs + 6 * kept);
        ws.contact.pair_probe[base + kept] = static_cast<int>(q);
        ws.contact.pair_tris[base + kept++] = cand[t];
      }
      ws.contact.num_pairs = base + kept;
    } else {
      tool_contact(m, static_cast<int>(q), R, p.proxy, s.x, cand.data(), nc, &c, ws.force.data(),
                   ws.contact.block.data(), kToolForceOnly);
    }
    if (c.faces == 0) continue;
    friction_forces(m, static_cast<int>(q), p, s.x, ws.force.data(), ws.contact.block.data());
    // The layer's reference velocity (two probes on one node: the last one's, approximate).
    for (int t : cand)
      for (int i : m.surface[t]) {
        list_contact_node(ws, i);
        ws.contact.v_ref[i] = p.proxy_velocity;
      }
    if (p.stick >= 0)
      for (int i : m.surface[p.stick]) {
        list_contact_node(ws, i);
        ws.contact.v_ref[i] = p.proxy_velocity;
      }
  }
  for (size_t q = 0; q < m.planes.size(); ++q) {
    PlaneState& pl = s.planes[q];
    pl.force.setZero();
    pl.contacts = 0;
    const Vec3& n = m.planes[q].normal;
    const double kp = m.planes[q].stiffness;
    const double mu = pl.stick.empty() ? 0.0 : m.planes[q].friction;
    const Vec3 slide = pl.slide - n.dot(pl.slide) * n;
    const Mat3 tangential = Mat3::Identity() - n * n.transpose();
    for (int t = 0; t < nn; ++t) {
      const int i = nodes ? (*nodes)[t] : t;
      const double depth = pl.offset - n.dot(s.x[i]);
      if (depth <= 0) continue;
      Vec3 f = kp * depth * n;
      if (mu > 0 && m.fixed[i] != 7) {
        // Coulomb by a tangential penalty toward the committed stick point (plate frame), held
        // inside the cone |f_t| <= mu k_p depth (plate_friction_force); the stick point moves
        // only in commit_friction, so every Newton iterate of a step sees the same one. A node
        // that meets the plate during a step sticks where it was at the step's start.
        const Vec3 d = tangential * (s.x[i] - slide - pl.stick[i]);
        Mat3 kt;  // N/m, -d(f_t)/dx: the friction term's stiffness for the implicit system
        f += plate_friction_force(d, kp, mu * kp * depth, tangential, &kt);
        if (with_jacobian) {
          ws.contact.block[i] += kt;
          list_contact_node(ws, i);
        }
      }
      ws.force[i] += f;
      pl.force -= f;
      ++pl.contacts;
      // One normal per node for the Jacobian: a node behind two plates keeps the first's, a rare
      // case that only slows convergence.
      if (with_jacobian && m.fixed[i] != 7 && ws.contact.n[i].squaredNorm() == 0) {
        ws.contact.n[i] = std::sqrt(h * h * kp) * n;
        list_contact_node(ws, i);
      }
    }
  }
}

Vec3 plate_friction_force(const Vec3& d, double kp, double limit, const Mat3& tangential,
                          Mat3* stiffness) {
  const double dn = d.norm();
  if (!(limit > 0)) {
    stiffness->setZero();
    return Vec3::Zero();
  }
  const double z = kp * dn / limit;
  if (!(z > 1e-12)) {
    *stiffness = kp * tangential;
    return -kp * d;
  }
  const Vec3 u = d / dn;
  const Mat3 along = u * u.transpose();
  const double zc = std::min(z, kFrictionSlipStretch), th = std::tanh(zc);
  const double sech = 1 / std::cosh(zc);
  *stiffness = (z < kFrictionSlipStretch ? kp * sech * sech : 0.0) * along +
               (limit * th / dn) * (tangential - along);
  return -limit * th * u;
}

void commit_friction(const Model& m, State& s) {
  for (size_t q = 0; q < m.planes.size(); ++q) {
    PlaneState& pl = s.planes[q];
    if (pl.stick.empty() || !(m.planes[q].friction > 0)) continue;
    const Vec3& n = m.planes[q].normal;
    const double mu = m.planes[q].friction;
    const Vec3 slide = pl.slide - n.dot(pl.slide) * n;
    const Mat3 tangential = Mat3::Identity() - n * n.transpose();
    for (int i = 0; i < m.num_nodes(); ++i) {
      Vec3& a = pl.stick[i];
      const Vec3 p = s.x[i] - slide;  // the node in the plate's frame
      const double depth = pl.offset - n.dot(s.x[i]);
      if (depth <= 0) {  // free: its stick point follows it, for when it meets the plate
        a = p;
        continue;
      }
      // Return mapping (the penalty is common to both sides): |d| <= kFrictionSlipStretch mu
      // depth, past which the node has slid.
      const Vec3 d = tangential * (p - a);
      const double dn = d.norm(), limit = kFrictionSlipStretch * mu * depth;
      if (dn > limit) a += (1 - limit / dn) * d;
    }
  }
}

// The proxy stage: every probe's proxy moves toward its device target with the nodes held
// (core/contact.h), leaving the triangles near it for the contact stage.
void update_proxies(const Model& m, State& s, Workspace& ws) {
  for (size_t q = 0; q < m.probes.size(); ++q)
    if (m.probes[q].contact == ContactModel::kSurface) {
      if (m.probes[q].hold_proxy)
        hold_proxy(m, static_cast<int>(q), s.x, &ws.contact.candidates[q], &s.probes[q]);
      else
        update_proxy(m, static_cast<int>(q), s.x, &ws.contact.candidates[q], &s.probes[q]);
    }
}

// Explicit integrators take the contact layer implicitly (step.h): backward Euler on the layer
// force linearised at x, m (v1 - v) = h (f - B h (v1 - v_p)) with v_p the proxy's velocity over
// its last update, so a node with a layer stiffness B advances with the force
// m (m I + h^2 B)^-1 (f - h B (v - v_p)) instead of f, on its free axes. The h B (v - v_p) term
// is the layer's own backward-Euler damping: without it a node that meets the proxy keeps its
// speed into the layer and gives the energy back on the way out; relative to the proxy it leaves
// a node that moves with the tool (a steady press or drag) undamped.
void semi_implicit_contact(const Model& m, const State& s, Workspace& ws, double h) {
  for (int q = 0; q < ws.contact.num_nodes; ++q) {
    const int i = ws.contact.nodes[q];
    if (m.fixed[i] == 7) continue;
    const Mat3& B = ws.contact.block[i];
    if (B.squaredNorm() == 0) continue;
    const Vec3& free = m.free_axes[i];
    const Mat3 Bf = free.asDiagonal() * B * free.asDiagonal();
    const Mat3 A = m.mass[i] * Mat3::Identity() + h * h * Bf;
    ws.force[i] =
        m.mass[i] * A.ldlt().solve(ws.force[i] - h * (Bf * (s.v[i] - ws.contact.v_ref[i])));
  }
}

}  // namespace detail

using namespace detail;

bool node_contact(const Vec3& x, const Vec3& normal, const Vec3& c, double R, double kc,
                  Vec3* f_node, Mat3* dfdc, Vec3* dir, double* depth_out) {
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
    if (depth_out) *depth_out = depth;
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
    if (depth_out) *depth_out = R - r;
  }
  return true;
}

void probe_contact(const Model& m, const std::vector<Vec3>& x, int k, const Vec3& center,
                   double radius, ProbeState* probe, ContactCandidates* candidates) {
  probe->center = center;
  probe->active = true;
  if (radius > 0) probe->radius = radius;
  if (m.probes[k].contact == ContactModel::kSurface)
    update_proxy(m, k, x, candidates, probe, kReplyMaxEvaluations);
  else
    node_probe_contact(m, x, k, center, probe);
}

}  // namespace conica
