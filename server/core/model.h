// The immutable model of a mass-spring body and its copyable state, in the spirit of MuJoCo's
// mjModel / mjData: a step is a function of (const Model&, State&), so snapshots, rollback and
// replay are copies. All quantities SI: m, kg, s, N, Pa.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "core/conical.h"
#include "core/mesh.h"

namespace conica {

using Mat3 = Eigen::Matrix3d;

enum class LawKind : std::uint8_t { kHooke = 0, kConical = 1 };

// How a card's spring is mapped onto a mesh spring of rest length l0.
//  kRaw:    every mesh spring IS the card's spring: deflection = l0 - l, force = P(deflection).
//  kStrain: the card describes a column of side L (its free length): stress P/L^2 at strain
//           deflection/L. A mesh spring with rest length l0 and volume share V gets
//           deflection = (L / l0)(l0 - l) and force = P * V / (l0 L^2), so the bulk response of a
//           body depends on strain only and does not change when the mesh is refined.
enum class Mapping : std::uint8_t { kRaw = 0, kStrain = 1 };

// A spring card: the law of one spring group.
struct SpringCard {
  LawKind law = LawKind::kConical;
  ConicalCard conical;         // kConical: G in Pa, lengths in m
  double hooke_k = 0;          // kHooke: stiffness in N/m of the card's spring
  double hooke_length = 0;     // kHooke: its free length L in m (used by kStrain)
  double stiffness_cap = 1e3;  // kConical: tangent stiffness cap as a multiple of K0
  double damping = 0;          // N s/m of the card's spring (dashpot parallel to it)
  double maxwell_k = 0;        // N/m: Maxwell branch spring (0: no branch)
  double maxwell_tau = 0;      // s: Maxwell branch relaxation time

  double free_length() const { return law == LawKind::kConical ? conical.L0 : hooke_length; }
  // Initial (linear-phase) stiffness in N/m of the card's spring.
  double k0() const;
};

// Springs of one group are contiguous: [begin, end).
struct SpringGroup {
  std::string name;
  SpringCard card;
  std::optional<ConicalLaw> law;  // set for kConical, with the card's cap
  int begin = 0, end = 0;
  bool viscous = false;  // damping or Maxwell branch present
};

enum class Integrator : std::uint8_t {
  kSymplecticEuler = 0,  // paper eq. (22)-(23): v += dt F/m; x += dt v
  kExplicitEuler = 1,    // x += dt v; v += dt F/m (from the old state): fails first
  kImplicitEuler = 2,    // backward Euler, Newton + matrix-free PCG, fixed budgets
};
const char* integrator_name(Integrator i);

// How the implicit integrator solves each Newton iteration's system A dx = rhs.
enum class LinearSolver : std::uint8_t {
  kBlockJacobiCG = 0,  // matrix-free CG, 3 x 3 block-Jacobi preconditioner (core/implicit.cc)
  kFactorCG = 1,       // matrix-free CG preconditioned by a sparse Cholesky factor of A, renewed
                       // every refactor_every steps or when CG needs more than
                       // refactor_iterations (core/sparse_system.h)
};

struct SolverOptions {
  Integrator integrator = Integrator::kSymplecticEuler;
  double dt = 1e-3;             // s, one tick
  int substeps = 1;             // steps per tick (dt / substeps each)
  int newton_iterations = 2;    // implicit: budget per step
  double newton_tolerance = 0;  // m, implicit: stop when an update moves no node farther (0: the
                                // whole budget every step)
  int cg_iterations = 40;       // implicit: fixed budget per Newton iteration
  double cg_tolerance = 1e-8;   // implicit: relative residual to stop early
  LinearSolver linear_solver = LinearSolver::kBlockJacobiCG;  // implicit
  int refactor_every = 0;       // kFactorCG: steps between factorisations (0: only on demand)
  int refactor_iterations = 4;  // kFactorCG: a solve that takes more CG iterations asks for a
                                // new factor
  // Multi-rate serving (the server's loop, loop/body_worker.h; core/multirate.h): the body steps
  // at body_rate_hz on a thread of its own and each tick answers the probes from the local
  // compliance of its last step. 0: the body steps every tick. Implicit Euler, node contact.
  double body_rate_hz = 0;  // Hz
  double body_reach = 0;    // m, the local model's region beyond the probe radius (0: half of it)
  bool exact_compliance = true;  // multi-rate: W from the tetrahedra's exact element Hessians
  // Implicit Euler: Newton's matrix takes the tetrahedra's element terms with their exact
  // Hessians (prepare_tet_tangents, projected where indefinite), not the Gauss-Newton blocks
  // (volume g g^T, the shear term's Laplacian); hexahedra keep the Gauss-Newton blocks.
  bool exact_tangent = false;
  // Implicit Euler: the second-order backward differentiation formula (BDF2) from the second step
  // on, backward Euler on the first and after a rollback. BDF2 is backward Euler of step 2h / 3
  // from x^ = (4 x_n - x_n-1) / 3, v^ = (4 v_n - v_n-1) / 3, so each step solves the same system
  // (the stiff terms, a contact layer included, in balance at its end, as backward Euler has
  // them) and damps a resolved oscillation far less: per step at h omega = 1 (undamped) 0.93
  // against backward Euler's 0.71. The state keeps the previous step (State::x_prev, v_prev).
  bool bdf2 = false;
  double mass_damping = 0;  // 1/s: Rayleigh mass-proportional damping on all nodes
  Eigen::Vector3d gravity = Eigen::Vector3d::Zero();  // m/s^2
  double min_length_fraction = 0.05;                  // hard stop: no spring shorter than this x l0
  bool hard_stop = true;                              // off only to show what happens without it
  // Active region (symplectic and explicit Euler): only nodes a probe can move by more than
  // active_tolerance are integrated; the rest sleep at their state (see step.h).
  bool active_region = false;
  double active_tolerance = 1e-5;  // m, displacement tolerance that sizes the region
  // Far field (sleeping nodes): 0 moves it multi-rate, one step of active_far_every ticks at a
  // time, with the interval chosen from its stability bound; n > 0 forces that interval; -1
  // freezes it at its state (see step.h).
  int active_far_every = 0;
  // Multi-rate: when a tick with the region is estimated to cost more than this fraction of a
  // whole step, the whole body steps every tick until the estimate falls below 0.8 of it
  // (infinity: never; see step.h).
  double active_whole_body_cost = 0.85;
  double max_speed = 50;  // m/s: guard: faster nodes mean the step blew up
};

// A rigid tool moved by a client, in contact with the body's deformed surface through a proxy
// (core/contact.h).
enum class ToolShape : std::uint8_t {
  kSphere = 0,  // a ball of `radius` around the pose
  kPunch = 1,  // a flat-ended cylinder of `radius`: its end face centred at the pose, pushing along
               // `axis`
  kPlane = 2,  // an unbounded flat face through the pose pushing along `axis` (the tool fills the
               // half-space behind it); `radius` is its length scale (layer depth, defaults)
};
enum class ContactModel : std::uint8_t {
  kSurface = 0,  // the tool against the deformed surface triangles through a proxy (core/contact.h)
  kNodes = 1,    // a sphere against the nodes, a penalty per node (core/step.h)
};
struct ProbeSpec {
  double radius = 5e-3;  // m
  double stiffness = 0;  // kNodes: N/m per node, 0: from node masses and the step;
                         // kSurface: Pa/m, the contact layer's pressure per metre of
                         // penetration, 0: from the tissue (kContactStiffnessFactor E* / R)
  ContactModel contact = ContactModel::kSurface;
  ToolShape shape = ToolShape::kSphere;
  Eigen::Vector3d axis = -Eigen::Vector3d::UnitZ();  // unit, punch and plane: the direction it
                                                     // pushes along
  double coupling = 0;      // kSurface: N/m, virtual coupling device-proxy; 0: kCouplingFactor
                            // E* R
  double friction = 0;      // kSurface: Coulomb coefficient mu (>= 0), stick and slip
  bool bonded = false;      // kSurface: every surface node the tool reaches is glued to it from
                            // then on (moves with it on all axes, no slip) until it is lifted
                            // off (inactive); not with friction
  bool hold_proxy = false;  // kSurface: the step keeps the proxy where it is (hold_proxy): the
                            // multi-rate body, whose proxy the 1 kHz tick solves (not in scenes)
};

// A rigid half-space {x : n.x >= offset} that nodes cannot enter (compression plates).
struct PlaneSpec {
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  // unit, points into the free side
  double offset = 0;                                  // m
  double stiffness = 0;  // N/m per node penalty; 0: chosen from masses and dt
  // A bonded plate (no slip): the nodes on its face at rest (|n.x - offset| <= bond_tolerance)
  // are glued to it and move with it on all axes, x = rest + (offset_now - offset) n
  // (core/boundary.h); the force on the plate then includes their reactions. Other nodes still
  // meet its penalty.
  bool bonded = false;
  double bond_tolerance = 0;      // m; 0: 1e-6 of the body's size
  std::vector<int> bonded_nodes;  // filled by build_model
  // Coulomb friction coefficient (>= 0, dimensionless; 0: frictionless): a node behind the plate
  // sticks to the point of the plate where it met it, held there by a tangential penalty of the
  // same stiffness, and slides when that force would exceed friction times its normal force
  // (return mapping, core/contact_stage.cc). Stick points are kept in the plate's frame, so they
  // move with the plate (PlaneState::slide). Not on bonded nodes.
  double friction = 0;
};

// A node set moved along a prescribed path (core/boundary.h): on the selected axes its nodes sit
// at rest + displacement(t), the displacement piecewise linear between waypoints (held at the
// first before it and at the last after it).
struct NodeMotion {
  std::vector<int> nodes;
  int axes = 7;                    // bit 0 x, 1 y, 2 z: the prescribed (and fixed) axes
  std::vector<double> time;        // s, ascending
  std::vector<Vec3> displacement;  // m, from rest, one per waypoint
};

struct Model {
  // Nodes (num_nodes).
  std::vector<Vec3> rest;           // m
  std::vector<double> mass;         // kg
  std::vector<double> inv_mass;     // 1/kg, 0 for nodes fixed on all axes
  std::vector<std::uint8_t> fixed;  // axis mask: bit 0 x, 1 y, 2 z; 7: the node never moves
  std::vector<Vec3> free_axes;      // 1 on axes the node may move along, 0 on fixed ones

  // Springs (num_springs), sorted by group.
  std::vector<int> spring_i, spring_j;
  std::vector<double> rest_length;       // l0, m
  std::vector<double> force_scale;       // a: spring force = a P(delta)
  std::vector<double> deflection_scale;  // b: delta = b (l0 - l)
  std::vector<SpringGroup> groups;

  // Geometry kept for contact, viewers and volume.
  std::vector<std::array<int, 4>> tetrahedra;
  std::vector<std::array<int, 8>> hexahedra;
  std::vector<std::array<int, 3>> surface;  // outward triangles
  std::vector<int> surface_nodes;
  std::vector<Vec3> normal;  // (num_nodes) outward unit normal at rest on the
                             // surface, zero inside

  // Volume stiffness (core/volume.h): with bulk_modulus > 0 every tetrahedron and hexahedron
  // stores (kappa / (2 |V0|)) (V - V0)^2.
  double bulk_modulus = 0;              // Pa, kappa; 0: pair springs only
  std::vector<double> tet_rest_volume;  // (tetrahedra) signed V0, m^3, when kappa > 0
  std::vector<double> hex_rest_volume;  // (hexahedra) signed trilinear V0, m^3, when kappa > 0
  // Gauss-point spread: a hexahedron's volume constraint leaves the modes that move volume
  // between its Gauss points free (hourglass modes: layers that alternately bulge and narrow).
  // With spread_modulus > 0 each hexahedron also stores (kappa_s / (2 |V0| / 8)) sum_q d_q^2,
  // d_q = (v_q - v0_q) - (V - V0) / 8, its Gauss-point shares' departure from a uniform change.
  double spread_modulus = 0;           // Pa, kappa_s
  std::vector<double> hex_rest_gauss;  // (8 hexahedra) signed v0_q, m^3, when kappa > 0
  // Shear stiffness (core/volume.h): isochoric neo-Hookean per tetrahedron and per Gauss point
  // of a hexahedron, with shape-function gradients at rest (tetrahedra 4 each, then hexahedra
  // 64 each, point-major) and rest volume shares |v0| (1 per tetrahedron, 8 per hexahedron).
  double shear_modulus = 0;     // Pa, mu; 0: none
  double shear_stiffening = 0;  // beta (dimensionless): Yeoh's (mu / 2) beta (I1b - 3)^2 on top
  std::vector<Vec3> shear_b;    // 1/m
  // The hexahedra's b_qa again, laid out for the one pass over their Gauss points (hex_terms,
  // core/element_terms.cc): 192 per hexahedron, [(3 a + j) 8 + q] (component j of b_qa).
  std::vector<double> hex_b;     // 1/m
  std::vector<double> shear_v0;  // m^3

  std::vector<ProbeSpec> probes;
  std::vector<PlaneSpec> planes;
  std::vector<NodeMotion> motions;  // prescribed paths (core/boundary.h)
  SolverOptions options;
  Mapping mapping = Mapping::kStrain;
  double contact_modulus = 0;  // Pa, E* of the body (core/contact.h), set at build

  int num_nodes() const { return static_cast<int>(rest.size()); }
  int num_springs() const { return static_cast<int>(rest_length.size()); }
  double total_mass() const;
};

// Live pose of a probe and what the body does to it.
struct ProbeState {
  Vec3 center = Vec3::Zero();     // m, the device target the client sets
  double radius = 0;              // m (0: the model's)
  bool active = false;            // a probe far away or never placed does nothing
  Vec3 force = Vec3::Zero();      // N, on the device: the coupling force k_vc (proxy - center)
  Mat3 stiffness = Mat3::Zero();  // N/m, d force / d center with nodes held
  int contacts = 0;               // surface triangles in contact
  // The proxy (core/contact.h): the pose the tool takes in the body's world.
  Vec3 proxy = Vec3::Zero();           // m
  bool proxy_placed = false;           // false until the first update after activation
  Vec3 proxy_velocity = Vec3::Zero();  // m/s, the proxy's move in its last update / dt
  double depth = 0;                 // m, deepest penetration of the tool into the deformed surface
  int evaluations = 0;              // of the contact layer in the last proxy update (its cost)
  int anchor = -1;                  // surface triangle nearest the proxy (-1: none in reach)
  Vec3 anchor_bary = Vec3::Zero();  // barycentric coordinates of the nearest point on it
  Vec3 anchor_offset = Vec3::Zero();  // proxy - that point in the triangle's frame (its two edge
                                      // vectors from node 0 and its unit normal)
  // Friction (probe friction > 0): the stick point, carried like the anchor, and the tangential
  // force the tool exerts on the body there.
  int stick = -1;  // surface triangle of the stick point (-1: none)
  Vec3 stick_bary = Vec3::Zero();
  Vec3 stick_offset = Vec3::Zero();
  Vec3 friction_force = Vec3::Zero();  // N, on the body at the stick point
  Vec3 contact_normal = Vec3::Zero();  // unit, the layer's force on the tool (friction only)
  double friction_limit = 0;           // N, mu times the normal force
  bool sliding = false;                // the last update slipped
  // Bonded tools (ProbeSpec::bonded): the nodes glued to the tool, in the order they were, each
  // one's place relative to the proxy (m; NaN where not bonded) and its bonded area A_i (m^2: the
  // largest share int l_i dA of the surface the tool has covered, l_i its barycentric weight, the
  // share by which the layer spreads a pressure to it). Node i is held at proxy + bond[i] by a
  // spring k_layer A_i, so a bonded tool pulls on the nodes as its layer pushes on them. The
  // arrays have num_nodes entries for a bonded probe and are empty otherwise; `covered` is
  // scratch for the proxy stage (zero between updates).
  std::vector<int> bonded;  // capacity: every surface node (make_state)
  std::vector<Vec3> bond;
  std::vector<double> bond_area;
  std::vector<double> covered;
};

struct PlaneState {
  double offset = 0;          // m, current offset (plates move along their normal)
  Vec3 slide = Vec3::Zero();  // m, the plate's tangential travel from its start (plates move
                              // along their face: carries stick points and bonded nodes; only
                              // its part normal to the plate counts)
  Vec3 force = Vec3::Zero();  // N, on the plate
  int contacts = 0;
  // A frictional plate's stick points (num_nodes; empty when frictionless), m, in the plate's
  // frame (the world point is stick + slide; only the part along the face counts): where each
  // node behind it is held tangentially; a node in front of it keeps its own position there, so
  // a node that meets the plate during a step sticks where it was at the step's start. Updated at
  // the end of each substep (commit_friction), read by the force passes.
  std::vector<Vec3> stick;
};

// The stages of a tick (core/step.h), in the order Counters::stage_ns and the published
// LoopStats.stage_ns list them.
enum class Stage : int {
  kProxies = 0,  // surface-contact proxies toward their targets
  kRegion,       // choosing the active region
  kSprings,      // spring geometry, law, dampers, Maxwell branches
  kElements,     // volume, spread and shear terms
  kContact,      // probes and planes against the body
  kIntegrate,    // the integrator's own work (explicit update, implicit system and solve)
  kHardStop,     // solid-height projection and Maxwell relaxation
  kFarField,     // the multi-rate far field's share and step
  kGuard,        // NaN / speed check and rollback
  kCount
};
inline constexpr int kNumStages = static_cast<int>(Stage::kCount);
const char* stage_name(Stage stage);

// Counters the step reports through instead of logging.
struct Counters {
  std::uint64_t steps = 0;
  std::uint64_t rollbacks = 0;          // guard trips rolled back to the last good state
  std::uint64_t nan_events = 0;         // NaN / Inf found after a step
  std::uint64_t speed_events = 0;       // a node faster than options.max_speed
  std::uint64_t hard_stops = 0;         // springs projected back to their minimum length
  std::uint64_t cg_iterations = 0;      // total, implicit only
  std::uint64_t newton_iterations = 0;  // total, implicit only
  std::uint64_t newton_estimates = 0;   // kFactorCG: steps ended by the factor's estimate
  std::uint64_t factorizations = 0;     // kFactorCG: factors taken into use
  std::uint64_t factor_failures = 0;    // kFactorCG: factorisations refused (not positive definite)
  std::uint64_t indefinite_tangents = 0;  // Newton iterations whose exact tangent CG refused
  std::uint64_t awake_nodes = 0;          // active region: nodes integrated in the last tick
  std::array<std::uint64_t, kNumStages> stage_ns{};  // ns spent in each stage, in all (steady
                                                     // clock; diagnostic, not part of replay)
};

// A vector whose copies keep the capacity of their source, so that a copied State still pushes
// into its reserved lists without allocating.
template <class T>
struct ReservedVector : std::vector<T> {
  ReservedVector() = default;
  ReservedVector(const ReservedVector& o) : std::vector<T>() { copy_from(o); }
  ReservedVector(ReservedVector&&) noexcept = default;
  ReservedVector& operator=(const ReservedVector& o) {
    if (this != &o) copy_from(o);
    return *this;
  }
  ReservedVector& operator=(ReservedVector&&) noexcept = default;

 private:
  void copy_from(const ReservedVector& o) {
    this->clear();
    this->reserve(o.capacity());
    this->insert(this->end(), o.begin(), o.end());
  }
};

// The active region's dynamic part (core/step.h): which nodes are awake, the lists built from
// them (in the order they were built, which the force sums follow) and the multi-rate far field's
// phase and pending sums. Sized by make_state; part of State, so a State copy is an exact
// snapshot with the region on.
struct RegionState {
  std::vector<std::uint8_t> awake;      // (num_nodes) integrated this interval
  std::vector<std::uint8_t> wake;       // (num_nodes) to be woken at the next choice
  std::vector<int> active;              // (num_springs) first num_active: springs with an awake end
  int num_active = -1;                  // -1: not chosen yet
  std::vector<double> active_scale;     // (num_springs) force_scale, 0 if both ends sleep
  std::vector<std::uint8_t> spring_on;  // (num_springs) the spring has an awake end
  std::vector<std::uint8_t> chunk_awake;  // (chunks) a spring of the chunk has an awake end
  std::vector<std::uint8_t> chunk_slow;   // (chunks) a spring of the chunk has both ends asleep
  std::vector<int> chunk_active_count;    // (chunks) springs with an awake end
  ReservedVector<int> awake_list;         // awake nodes
  ReservedVector<int> border;             // sleeping nodes an awake spring touches
  std::vector<std::uint8_t> in_border;    // (num_nodes)
  ReservedVector<int> slow;               // springs with both ends asleep (no runs)
  std::vector<double> slow_scale;         // (num_springs) force_scale if both ends sleep
  ReservedVector<int> flipped;            // nodes that changed side in this update
  // Multi-rate far field.
  int far_phase = 0;                           // ticks into the current interval
  std::vector<Vec3> impulse;                   // (num_nodes) N s from awake springs, this interval
  std::vector<double> far_fx, far_fy, far_fz;  // (num_nodes) N, far springs' forces of this
                                               // interval, summed over its ticks
  int far_springs_evaluated = 0;               // springs the last tick's far share evaluated
  double cost = 0;          // the last estimate of a multi-rate tick's cost (fraction of a step)
  bool whole_body = false;  // the region costs about a whole step: every node steps every tick
};

// Everything that changes as a body steps: a copy is an exact snapshot, and stepping two copies
// with the same inputs gives bit-identical states (the Workspace holds only what is derived from
// the Model and per-stage scratch).
struct State {
  double time = 0;  // s
  std::uint64_t tick = 0;
  std::vector<Vec3> x, v;  // (num_nodes) m, m/s
  // SolverOptions::bdf2: the state before the last step (sized by make_state when the model asks
  // for BDF2, empty otherwise) and whether it is one (not after make_state or a rollback).
  std::vector<Vec3> x_prev, v_prev;  // (num_nodes) m, m/s
  bool has_prev = false;
  std::vector<double> maxwell;     // (num_springs) Maxwell dashpot deflection, card units
  std::vector<ProbeState> probes;  // (model.probes.size())
  std::vector<PlaneState> planes;  // (model.planes.size())
  RegionState region;
  Counters counters;
};

// The state at rest: positions at rest, zero velocity, probes inactive.
State make_state(const Model& model);

}  // namespace conica
