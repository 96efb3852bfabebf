// Advancing a body in time. A tick runs in named stages:
//   probe input (already in State) -> spring forces -> element volume and shear terms (volume.h,
//   when the model has them) -> contact -> integrate -> hard stop -> guard
// What is derived from the model and the stages' scratch live in a Workspace sized once per model;
// everything that changes from tick to tick (the active region and the far field's pending sums
// included) lives in State, so a State copy is an exact snapshot and a Workspace can be rebuilt or
// shared at any tick (tests/core/snapshot_test.cc). A step allocates nothing, does no I/O and never
// throws.
//
// Spring s between nodes i and j, u = x_j - x_i, l = |u|, d = u / l:
//   deflection  delta = b (l0 - l)                (compression positive; b, a from the mapping)
//   card load   P = law(delta) + c delta_dot + k_m (delta - e_m)   (damper, Maxwell branch)
//   forces      f_i = -a P d,  f_j = +a P d
//   stiffness   K_s = k_ax d d^T + max(0, T / l)(I - d d^T),  k_ax = a b k_t,  T = -a P
//               (the geometric term is clamped at 0 in compression: a definiteness fix so that
//                the implicit system stays positive definite)
// Maxwell dashpot: e_m relaxes to delta with time constant tau, updated exactly per step:
//   e_m <- delta + (e_m - delta) exp(-h / tau).
// Contact with probes, by the probe's contact model.
// ContactModel::kNodes: per node inside a sphere of radius R around c (u = x - c, r =
// |u|):
//   surface node with outward normal n: it leaves the sphere inward along -n by
//     e = a + sqrt(a^2 - r^2 + R^2), a = u.n  (so the probe is pushed out of the body even after
//     slipping between surface nodes);  f_node = -k_c s n with the depth
//     s = min(e, kContactDepthCap (R - r)).
//     The cap makes the force continuous: e alone jumps from 0 to 2a when a node enters the sphere
//     on its far side (a > 0), and grows as sqrt(R^2 - r^2) for a node entering at the sphere's
//     equator (a = 0), an unbounded stiffness. With the cap at 2, |ds/du| <= 1 + sqrt(3), so the
//     force is Lipschitz in the probe position with constant (1 + sqrt(3)) k_c per node. The cap
//     leaves a flat press untouched until the contact rim is 60 degrees from the probe's pole (e is
//     the radial depth divided by about cos(theta) there).
//   interior node: f_node = k_c (R - r) u / r (radially out of the sphere)
//   probe force = -sum f_node, and its 3x3 stiffness d(probe force)/dc (nodes held) exactly.
// The surface potential's force is not its gradient (the normal direction is fixed per node): a
// penalty of this form is not conservative in tangential motion, which the energy checks allow.
// ContactModel::kSurface (the default): rigid tools against the deformed surface through a proxy
// (core/contact.h). At the start of a tick each probe's proxy moves toward its device target with
// the nodes held (the proxy stage); the body then steps with the tools held at their proxies, the
// contact layer's forces on the surface triangles' nodes in its forces. Explicit integrators take
// the contact layer by linearised backward Euler: a node in contact advances with the force
// m (m I + h^2 B)^-1 (f - h B (v - v_p)), v_p the proxy's velocity over its last update, B the
// node's lumped layer stiffness, which bounds the layer's stiffness from above, so the stiff layer
// never limits the step (h^2 B / m of a touched node is often past the explicit bound of 4) and a
// node that meets the proxy does not keep its speed into the layer (the equilibrium is the same:
// f = 0, v = v_p = 0 there). Rigid planes {n.x >= offset}: f_node = k_p (offset - n.x) n for nodes
// behind the plane.
//
// Active region (options.active_region, explicit integrators): a probe pressing with force P moves
// the surface of an elastic half-space by about u(r) = P (1 - nu^2) / (pi E r) at distance r
// (Boussinesq), so nodes farther than R = P (1 - nu^2) / (pi E eps) move less than the tolerance
// eps. Nodes within max(R, 2 probe radii) of an active probe are awake; they fall asleep (velocity
// zeroed, position kept) beyond 1.25 R, and a sleeping node wakes when the springs of the awake
// region pull on it with more than k_node eps (k_node: mean axial stiffness per node). Only springs
// with an awake end act (lattices: only chunks holding one are evaluated, whole, with the other
// springs' forces scaled to zero). E is the network's isotropic estimate sum(k l0^2) / (6 V),
// nu = 1/4.
// The far field (sleeping nodes) is either frozen (active_far_every = -1: the body is stiffer than
// it is, since the Boussinesq displacement decays only as 1/r) or multi-rate: it takes one
// symplectic Euler step of H = N dt every N ticks, with the forces of the springs between sleeping
// nodes and the node terms at that time, plus the impulse the awake springs gave it tick by tick
// over the interval (so momentum passes between the two sides exactly). The awake side sees the
// far nodes where their last step left them. N is the interval the far field's linear phase
// allows at a typical node: H omega < 2 with omega^2 bounded per node (Gershgorin) by
// 2 sum(a b K0) / m, times a 0.9 margin, at the median node; lighter far nodes (a lattice's edges
// and corners) take the far step with the larger inertia that keeps their own bound (selective
// mass scaling; gravity and damping keep the true mass). A far spring whose tangent stiffness
// leaves the linear phase (more than 1.5 K0), or a far node behind a plane, wakes its nodes at the
// next interval, when the region is chosen again. Since sleeping nodes move only at the far step,
// the far springs' forces are evaluated in N shares, one per tick of the interval (a chunk range
// or a slice of the far spring list each), and summed; the far step itself is then one pass over
// the nodes. A tick costs the awake side (its springs, its nodes and the sleeping nodes they pull,
// the border) plus about 1/N of the far springs, never a whole far step.
//
// A region that grows until a multi-rate tick costs about a whole step (options.
// active_whole_body_cost of it, 0.85 by default, estimated from the springs the awake side and one
// far share evaluate) is dropped: the whole body steps every tick, as without the active region,
// until the estimate falls below kRegionResumeFraction of that, checked every tick; the switch is
// made at an interval's start, where no far share or impulse is pending, so it is exact.
//
// Solid height: the law's stiffness cap (ConicalLaw) keeps k_t finite, and a hard stop projects
// any spring shorter than max(l0 - S/b, min_length_fraction l0) back to that length, removing
// the approaching relative velocity. The implicit solver's line search never takes a Newton step
// that makes a spring shorter than that length.
#pragma once

#include <memory>
#include <vector>

#include "core/contact.h"
#include "core/model.h"

namespace conica {

struct FactorScratch;  // core/sparse_system.h

// What the compile step derives from the model (layout, bounds) and each stage's scratch, sized
// once per model (compile.cc). Nothing here outlives a tick: a Workspace built afresh at any tick
// continues a State exactly.

// The springs in the order the stages stream them (compile stage).
struct SpringLayout {
  // Springs in runs: [k, k + n) join nodes i + t and j + t (t < n). Set when the model's springs
  // are mostly in runs (lattices, see build_model); the step then reads positions and writes
  // forces as contiguous streams of the structure-of-arrays copies in SpringScratch instead of
  // gathering.
  struct Run {
    int k, n, i, j;
  };
  std::vector<Run> runs;  // cut at groups, at most 256 springs each
  // Consecutive runs of one group, about 256 springs: geometry, law and scatter run chunk by
  // chunk. Runs [first_run, last_run), springs [k0, k1).
  struct Chunk {
    int group, first_run, last_run, k0, k1;
  };
  std::vector<Chunk> chunks;
  static constexpr int kChunkSprings = 256;
  std::vector<double> min_length, min_length2;       // (num_springs) m and m^2, hard stop
  std::vector<int> spring_group;                     // (num_springs) group of each spring
  std::vector<int> node_spring_start, node_springs;  // (num_nodes + 1), (2 num_springs): springs
                                                     // of node i: [start[i], start[i + 1])
  std::vector<int> spring_chunk;                     // (num_springs) its chunk (runs path)
  std::vector<double> tangent_limit;                 // (groups) card units: far springs beyond wake
  bool has_maxwell = false;                          // a group has a Maxwell branch
};

// The active region's constants (compile stage; its dynamic part is State::region).
struct RegionBounds {
  double modulus = 0;                // Pa, network estimate
  double node_stiffness = 0;         // N/m, mean axial stiffness per node
  int far_every = 0;                 // N ticks per far step; 0: frozen far field
  int far_max_every = 1;             // the far field's stability bound on N
                                     // (Gershgorin, lightest node)
  int measured_every = 0;            // the bound from the measured spectrum (0: not
                                     // measured: frozen or no active region)
  double far_lambda = 0;             // 1/s^2, largest eigenvalue of M^-1 K measured
  double far_gamma = 0;              // 1/s, the far step's explicit damping bound
  double far_raise = 1;              // inertia factor of every far node (measured)
  std::vector<double> far_inv_mass;  // (num_nodes) 1/kg, inertia of a far step
};

// The spring stage's scratch (springs.cc), read by the implicit system and the hard stop.
struct SpringScratch {
  Vec3 dir(int k) const { return Vec3(ux[k], uy[k], uz[k]); }
  std::vector<double> deflection, load, tangent;  // (num_springs) card units
  std::vector<double> length;                     // (num_springs) m
  std::vector<double> ux, uy, uz;                 // (num_springs) unit direction i -> j
  // A chunk's direction, length, deflection, load and tangent when they are not kept per spring
  // (explicit integrators; directions_kept false: ux, uy, uz are stale until refreshed).
  std::vector<double> chunk_ux, chunk_uy, chunk_uz, chunk_length, chunk_deflection, chunk_load,
      chunk_tangent;
  bool directions_kept = true;
  bool hard_stop_near = false;     // the last hard-stop test could not rule out a short spring
  std::vector<double> px, py, pz;  // (num_nodes) m, positions at the last geometry
  std::vector<double> fx, fy, fz;  // (num_nodes) N, spring forces being summed
  // Smallest length - min_length over springs at the last geometry (m): while no node has moved
  // by more than half of it, no spring can be short, and the hard-stop pass is skipped.
  double slack = -1;
};

// The element stage's scratch (core/element_terms.h), what the implicit system reads of it.
struct ElementScratch {
  // Volume stiffness (model.bulk_modulus > 0): dV/dx of every element node at the last force
  // evaluation, tetrahedra first (4 each), then hexahedra (8 each), and kappa / |V0| per element
  // in the same order (the implicit system adds h^2 kappa / |V0| g g^T per element).
  std::vector<Vec3> volume_grad;
  std::vector<double> volume_coef;
  // Gauss-point spread (model.spread_modulus > 0): per hexahedron, d(d_q)/dx_a for q, a < 8
  // (64 entries, q-major), and 8 kappa_s / |V0| (the system adds h^2 times that sum_q G_q G_q^T).
  std::vector<Vec3> spread_grad;
  std::vector<double> spread_coef;
  // Shear stiffness (model.shear_modulus > 0): |v0| mu J^(-2/3) per tetrahedron and Gauss point
  // at the last force evaluation (the system adds h^2 times that (b_a . b_b) I).
  std::vector<double> shear_coef;
  // Per element (tetrahedra 16 entries, then hexahedra 64): the implicit system's shear
  // Laplacian h^2 sum_q c_q (b_qa . b_qb), assembled once per Newton iteration.
  std::vector<double> element_lap;
  // Tetrahedra with the exact tangent (prepare_tet_tangents): 45 entries each, and whether the
  // implicit system uses them this Newton iteration instead of the terms' Gauss-Newton blocks.
  std::vector<double> tet_tangent;
  bool tangent = false;
};

// The contact stage's scratch (contact_stage.cc, core/contact.h). Planes: normal * sqrt(h^2 k_p)
// per node behind a plate (implicit only). Probes: each node's lumped layer stiffness (N/m), what
// the implicit system and the explicit integrators' semi-implicit contact update use; frictional
// plates add their tangential stiffness there too (implicit only). The first num_nodes entries of
// nodes list the nodes with either (in_contact flags them). v_ref: the velocity of the proxy a
// probe node's layer holds it against (what the explicit update's layer damping is relative to).
struct ContactScratch {
  std::vector<Vec3> n;                   // (num_nodes)
  std::vector<Mat3> block;               // (num_nodes) N/m
  std::vector<Vec3> v_ref;               // (num_nodes) m/s
  std::vector<int> nodes;                // (num_nodes)
  std::vector<std::uint8_t> in_contact;  // (num_nodes)
  int num_nodes = 0;
  std::vector<ContactCandidates> candidates;  // (probes) surface triangles near each proxy
  // The implicit system's surface-probe layers, triangle by triangle: the touched triangles'
  // pair blocks K_ab = sum w l_a l_b p' u u^T (N/m, the pressure term of tool_contact's node_pair,
  // six per triangle: 00 11 22 01 02 12), instead of their row sums in `block`, so that Newton's
  // matrix couples the nodes of a face the way the layer does. The first num_pairs entries of
  // pair_tris (surface triangle indices) and 6 num_pairs of pair are in use.
  std::vector<int> pair_tris;   // (probes x surface triangles)
  std::vector<int> pair_probe;  // (the same) the probe of each
  std::vector<Mat3> pair;       // (6 x that)
  int num_pairs = 0;
};

// The implicit integrator's system and solver scratch (implicit.cc). Node vectors are
// component-major: entry c n + i is component c of node i; diag and pre hold six such entries
// (00 11 22 01 02 12).
struct SystemScratch {
  std::vector<double> alpha, beta;           // (num_springs) system coefficients
  double h2 = 0;                             // s^2, h^2 of the system being solved
  std::vector<Vec3> x0, v0;                  // (num_nodes) state at the step's start
  std::vector<Vec3> x_base;                  // (num_nodes) a Newton iterate being backtracked
  std::vector<double> mass;                  // (num_nodes) kg, m (1 + h mu)
  std::vector<double> free;                  // (3 num_nodes) 1 on free axes, 0 on fixed
  std::vector<double> diag, pre;             // (6 num_nodes) diagonal blocks, inverses
  std::vector<double> rhs, r, z, p, ap, dx;  // (3 num_nodes) PCG
  std::vector<double> chunk;                 // (6 kChunkSprings) a chunk's products/blocks
  bool indefinite = false;                   // the last CG met p^T A p <= 0
};

// The guard's last good state (step.cc): what a rollback returns to.
struct Rollback {
  std::vector<Vec3> x, v;
  std::vector<double> maxwell;
  std::vector<std::vector<Vec3>> stick;  // (planes) each frictional plate's stick points
};

struct Workspace {
  explicit Workspace(const Model& model);
  ~Workspace();
  Workspace(Workspace&&) noexcept;
  Workspace& operator=(Workspace&&) noexcept;

  SpringLayout layout;
  RegionBounds bounds;
  std::vector<Vec3> force;  // (num_nodes) N, the forces being summed by the stages
  SpringScratch springs;
  ElementScratch elements;
  ContactScratch contact;
  SystemScratch system;
  Rollback good;
  // The implicit system's sparse factor (options.linear_solver kFactorCG), else null. A worker
  // thread that factors its `next` (loop/factor_worker.h) must be stopped before the Workspace is
  // replaced or destroyed.
  std::unique_ptr<FactorScratch> factor;
  std::uint64_t lap_ns = 0;  // steady clock at the last stage lap (step_detail.h)
};

// The largest eigenvalue (1/s^2) of M^-1 K of the body at rest in its springs' linear phase
// (K = sum a b (K0 + k_m) d d^T over free axes), by 40 Lanczos iterations: the largest Ritz value
// plus its residual. The multi-rate far field's automatic interval N is the largest with
// (N dt)^2 lambda / s + 2 N dt gamma(s) <= 1.8^2 for an inertia factor s <= 1.1 on every far node
// (symplectic Euler with explicit damping gamma = mass_damping + max(c / K0) lambda / s is stable
// below 4; 0.9 margin on H omega); up to that N the far nodes take that uniform s (the smallest
// that meets the bound) and no per-node raise; when the typical node's Gershgorin interval is
// longer (a mesh whose few light, stiff nodes set the spectrum) that one is kept, with raised
// inertia. Allocates: for building a Workspace only.
double far_spectral_bound(const Model& model);

// Forces on every node at (state.x, state.v): springs, dampers, Maxwell branches, element
// volumes, gravity, mass damping, contact. Fills ws.force and the probe/plane reactions in state.
// Surface-contact probes run the proxy stage first, so their proxies move toward their targets.
void compute_forces(const Model& model, State& state, Workspace& ws);

// Stored energy (J): springs (law energy scaled by a / b), Maxwell branches, element volumes,
// contact penalties.
double potential_energy(const Model& model, const State& state);
double kinetic_energy(const Model& model, const State& state);

enum class StepStatus { kOk, kRolledBack };

// One tick: options.substeps steps of dt / substeps with the model's integrator, then the guard.
// On NaN / Inf or a node faster than max_speed the state returns to the last good one (velocities
// zeroed), counters record it, and the tick still advances.
StepStatus step(const Model& model, State& state, Workspace& ws);

// The region is used again when its cost estimate falls below this fraction of
// options.active_whole_body_cost; a listed spring (scalar law, gathered) costs about
// kListSpringCost times a spring of the chunked whole step.
inline constexpr double kRegionResumeFraction = 0.8;
inline constexpr double kListSpringCost = 4.0;

// The surface contact depth is capped at this multiple of a node's radial depth in the sphere.
inline constexpr double kContactDepthCap = 2.0;

// Contact of one node at x (outward surface normal `normal`, zero inside the body) with a probe
// sphere of radius R around c and penalty kc, by the law above. Returns false when the node is
// outside the sphere; otherwise the force on the node, the node's share of d(probe force)/dc
// (nodes held), the unit direction along which the node is pushed and, when asked, the depth s
// (m; the penalty's energy is kc s^2 / 2, with the same cap as the force).
bool node_contact(const Vec3& x, const Vec3& normal, const Vec3& c, double R, double kc,
                  Vec3* f_node, Mat3* dfdc, Vec3* dir, double* depth = nullptr);

// The contact stage alone for probe k (kNodes: the node law against x, nodes held; kSurface: the
// proxy stage, moving probe->proxy) at the device target `center` (m) with a sphere or punch
// of radius `radius` (m; <= 0: the probe's): moves probe->proxy and fills probe->force (on the
// device), stiffness and contacts against node positions x, without touching the nodes. What the
// server answers a probe update with between ticks (the proxy moved with at most
// kReplyMaxEvaluations layer evaluations per solve). `candidates` as in update_proxy.
void probe_contact(const Model& model, const std::vector<Vec3>& x, int k, const Vec3& center,
                   double radius, ProbeState* probe, ContactCandidates* candidates = nullptr);

// After model.options changed between ticks (damping over the control socket, say): rebuilds the
// Workspace from the model (what it derived from the options: the far field's interval and
// inertia depend on the damping) and, if the far field's interval changed, restarts its interval
// (pending far shares and impulses are dropped, the region is chosen again at the next tick).
// Allocates: between ticks only.
void options_changed(const Model& model, State& state, Workspace& ws);

// Moves a probe (input stage). Inactive probes exert nothing.
void set_probe(State& state, int probe, const Vec3& center, bool active = true);

}  // namespace conica
