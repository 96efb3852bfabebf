// Multi-rate haptics: an accurate body steps at its own rate, a 1 kHz tick answers the probe in
// between with the local compliance of the contact region (the split SOFA's haptics uses).
//
// The body (implicit Euler, step h_b, e.g. 20 ms) ends a step at x0 with the probe at c0, in
// equilibrium with the probe's node forces f0 = f(x0, c0). Linearised about that state, an extra
// force df on the nodes moves them at the end of the next step by
//   dx = W df,   W = h_b^2 A^-1,   A = M (1 + h_b mu) + h_b^2 (K + B0)
// (the implicit system, core/sparse_system.h; B0 the probe's contact Jacobian it holds). Between
// body steps the probe moves to c, and the haptic tick solves the contact region R (the nodes the
// probe can reach) for the node displacements dx with
//   dx = W_RR [ f(x0 + dx, c) - f0 + B0 dx ]                                          (1)
// by Newton's method (J = I - W (B0 - df/dc), a dense solve of 3 |R| unknowns); the force on the
// device is -sum f(x0 + dx, c) and its stiffness -dF/dc = sum_i dfdc_i (I - G_i), G = J^-1 W S,
// S the stacked dfdc_i: the body's compliance softens the device's stiffness (FD-tested).
// With c = c0, dx = 0 solves (1) exactly: between body steps the force is continuous with the
// body's own, and moves with the probe as the body would, to first order in the body's response.
//
// Built on the body's thread after a body step (LocalModelBuilder: one force evaluation and an
// assembly; the numeric factorisation, which allocates inside CHOLMOD, there or on a thread of
// its own (loop/body_worker.h); W from the factor in hand with the contact Jacobian it held, by
// one pruned forward solve, SystemFactor::inverse_block); solved on the 1 kHz thread
// (haptic_contact: no allocation, the region's capacity fixed at load).
//
// Surface contact (ContactModel::kSurface, core/contact.h). f is the contact layer's force on the
// nodes with the tool at its proxy, and the region is the nodes of the surface triangles within
// the probe radius plus the margin of the proxy (only surface nodes carry the layer's force). A
// tick first moves the proxy toward the device target with the nodes held where the last answer
// left them (update_proxy, as the single-rate proxy stage does: placement, swept crossings, jumps
// and its depth rate). A frictionless, unbonded tool then solves (1) and the proxy's equilibrium
// (coupling force = the layer's push) together, by Newton on the Schur complement in the proxy
// (haptic_contact says how); the device gets the coupling force at that joint answer and its
// stiffness with the region giving way. Solving the two one after the other once a tick lets
// them chase each other over tens of ticks (a lift read 14 % soft, docs/contact.md). A tool with
// friction or bonded solves (1) with the proxy held (its stick and slip live in update_proxy), the
// device gets the update's force and stiffness with the nodes held, and the next update sees the
// nodes this tick moved (a one-tick stagger, as in the single-rate step). df/dx in J is the
// layer's lumped node blocks (-B, the positive semi-definite bound the implicit system takes), so
// Newton converges to the exact (1) at a linear rate where the blocks leave out the layer's
// curvature. A fresh model (a body step just handed over, in equilibrium with the proxy its step
// held) is first solved against the last tick's proxy, then the proxy moves. Each solve stops at
// LocalModel::layer_tolerance of node motion or after layer_budget layer evaluations, so the tick
// stays bounded. The body step holds the proxy where the ticks left it (body_model).
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include "core/contact.h"
#include "core/model.h"

namespace conica {

struct Workspace;
class SystemFactor;

struct LocalModel {
  explicit LocalModel(int capacity = 48);
  int capacity = 0;
  int num = 0;                  // region nodes in use
  bool valid = false;           // built from a factored system
  double h = 0;                 // s, the body step the compliance is for
  Vec3 center0 = Vec3::Zero();  // m, the probe where the body step ended
  std::vector<int> nodes;       // (capacity) the region
  std::vector<Vec3> x0, f0;     // (capacity) m, N: positions and probe forces at the body state
  std::vector<Mat3> b0;         // (capacity) N/m: the contact Jacobian the system held (node
                                // blocks; a surface layer's face couplings in held_*)
  std::vector<double> w;        // (9 capacity^2) m/N: W_RR, row-major 3 capacity x 3 capacity
  std::vector<double> winv;     // (9 capacity^2) N/m: W_RR^-1 on the free axes (0 on fixed ones)
  // Haptic state and scratch (1 kHz thread). dx: the region's displacements of the last answer,
  // where the next one starts (zero in a fresh model).
  std::vector<Vec3> f, dx, dx_last, step;
  std::vector<Mat3> dfdc;
  std::vector<double> jac, rhs, g;
  std::vector<double> wdx;  // (3 capacity) N: W^-1 dx at the joint solve's current iterate
  std::vector<int> pivot;   // (4 capacity) LU pivots, then the active nodes
  // Surface contact: the layer's coupling of the region's nodes, column by column: node a's
  // entries (kMaxCoupled at most) are the nodes b with K_ba != 0 and K_ba (N/m, minus the
  // derivative of the layer's force on b with respect to a's position).
  static constexpr int kMaxCoupled = 24;
  std::vector<int> coupled_count, coupled_node;  // (capacity), (kMaxCoupled capacity)
  std::vector<Mat3> coupled;                     // (kMaxCoupled capacity)
  // Surface contact: B0's couplings between the region's nodes (the layer's pair blocks the
  // system held, off the diagonal), node a's entries (kMaxCoupled at most) the nodes b with
  // B0_ab != 0 and B0_ab; and hb = B0 dx at the last residual (scratch).
  std::vector<int> held_count, held_node;  // (capacity), (kMaxCoupled capacity)
  std::vector<Mat3> held;                  // (kMaxCoupled capacity)
  std::vector<Vec3> hb;                    // (capacity) N
  bool fresh = false;                      // dx was reset (a new region or body state)
  // The base state's free motion: the region's displacement over one body step from the
  // momentum the body carries with no force changed, A^-1 h M v (build()); the answers move the
  // base along it in proportion to the time since the hand-over (haptic_contact).
  std::vector<Vec3> u_free;  // (capacity) m
  int ticks = 0;             // answers since the model was handed over (< 0: handed over late)
  std::vector<double> wu;    // (3 capacity) N: W^-1 times the free motion so far (scratch)
  // Surface contact: each solve stops at this much node motion (fraction of the tool radius) or
  // after this many layer evaluations (haptic_contact says why these; tests ask for more).
  double layer_tolerance = 1e-4;
  int layer_budget = 8;
  int newton_iterations = 0;  // of the last haptic_contact
  int layer_evaluations = 0;  // of the last haptic_contact (surface contact)
  double residual = 0;        // m, its final |R(dx)|
  // Surface contact: the last joint solve ended out of its evaluations far from the proxy's
  // equilibrium and was answered by moving the proxy alone against the region (haptic_contact):
  // its residual |R_p| above joint_fallback times the larger of the coupling's force and the
  // layer's push, and above joint_fallback times 1 % of k_c R.
  bool proxy_fallback = false;
  double joint_fallback = 0.1;  // ... when |R_p| is above this fraction (haptic_contact)
};

// The 1 kHz side's scratch for probes with surface contact, sized for the model at load: each
// probe's candidate triangles (kept between ticks) and the layer's node forces and blocks.
struct SurfaceScratch {
  explicit SurfaceScratch(const Model& m);
  std::vector<ContactCandidates> candidates;  // (probes)
  std::vector<Vec3> force;                    // (nodes) N
  std::vector<Mat3> block;                    // (nodes) N/m
  std::vector<Mat3> pair;                     // (6 surface triangles) N/m: tool_contact's pairs
  std::vector<int> region;                    // (nodes) index in the region, or -1
};

// The body's side: owns the factor W comes from (allocates: at load).
class LocalModelBuilder {
 public:
  explicit LocalModelBuilder(const Model& m);
  ~LocalModelBuilder();
  // After a body step at h = m's substep: the implicit system at state s (forces with the
  // Jacobian, coefficients, element terms), factored; the probes' contact Jacobians it holds are
  // kept for build(). False when the system is not positive definite (the factor in hand, if
  // any, stays). With kFactorCG the fresh factor becomes ws's current one (the next step's
  // preconditioner). begin_refactor, factor_pending and finish_refactor one after the other.
  bool refactor(const Model& m, State& s, Workspace& ws);
  // The same in three parts, so that the numeric factorisations (tens of milliseconds on the
  // larger bodies, allocating inside CHOLMOD) can run on another thread while the body steps on
  // with the factor in hand (loop/body_worker.h):
  //   begin_refactor (the body's thread): the system at s assembled into the spare factors and
  //     the contact Jacobians it holds recorded; false while a factorisation is pending.
  //   factor_pending (any one thread): the numeric factorisations of what begin_refactor left.
  //   finish_refactor (the body's thread): a finished factorisation handed over (1: the next
  //     build()s use it, and the next step preconditions with it), a failed one counted (-1),
  //     or none finished (0).
  bool begin_refactor(const Model& m, State& s, Workspace& ws);
  void factor_pending();
  int finish_refactor(const Model& m, Workspace& ws);
  bool pending() const { return pending_.load(std::memory_order_acquire) != kNone; }
  // Probe k's local model at state s from the last factor: the region (the nodes within the
  // probe radius plus `margin`, the closest if more than the capacity; surface contact: the nodes
  // of the surface triangles that near the proxy), their positions and probe forces at s, and W =
  // h^2 A^-1 over them with the contact Jacobian A held (B0), so that (1) stays consistent when the
  // factor is some body steps older than s. W is solved anew only when the factor or the region
  // changed since probe k's last model. False without a factor.
  bool build(const Model& m, const State& s, Workspace& ws, int k, double margin, LocalModel* out);
  bool factored() const { return generation_ > 0; }
  std::uint64_t factorizations() const { return factorizations_; }  // successful ones
  std::uint64_t factor_failures() const { return failures_; }
  std::uint64_t region_solves() const { return solves_; }  // W solved (not reused)

 private:
  struct Region {  // probe k's last W (the factor generation it came from)
    std::uint64_t generation = 0;
    int num = 0;
    std::vector<int> nodes;
    std::vector<double> w;     // (3 num)^2, leading dimension 3 num
    std::vector<double> winv;  // its inverse on the free axes (zero on fixed ones), the same
  };
  SystemFactor* last(Workspace& ws);
  enum : int { kNone, kAssembled, kFactored, kFailed };
  std::atomic<int> pending_{kNone};
  std::unique_ptr<SystemFactor> factor_;   // the spare (begin_refactor assembles into it)
  std::unique_ptr<SystemFactor> current_;  // the last factor, when ws has no kFactorCG scratch
  std::unique_ptr<SystemFactor> exact_;    // W's factor (tetrahedra's terms: exact Hessians)
  std::unique_ptr<SystemFactor> exact_next_;
  bool exact_ok_ = false;       // exact_ holds the last refactor's system
  bool exact_next_ok_ = false;  // exact_next_ holds the pending one's
  std::vector<double> r_, z_;
  std::vector<std::pair<double, int>> near_;
  std::vector<std::vector<Mat3>> held_;       // (probes x nodes) N/m: B0 of the factored system
  std::vector<std::vector<Mat3>> held_next_;  // the pending factorisation's
  // A surface probe's B0 beyond its node blocks (held_ holds their diagonal K_aa): the touched
  // faces' pair blocks as the system held them (ContactScratch::pair), num of them in use.
  struct HeldPairs {
    std::vector<int> tris;   // (surface triangles)
    std::vector<Mat3> pair;  // (6 surface triangles) N/m
    int num = 0;
  };
  std::vector<HeldPairs> held_pairs_, held_pairs_next_;  // (probes)
  std::vector<int> region_of_;                           // (nodes) index in build()'s region, -1
  std::vector<Vec3> layer_force_;                        // (nodes) N, surface contact's f0
  std::vector<Region> regions_;                          // (probes)
  std::uint64_t generation_ = 0;                         // W's key: 0 without a usable factor
  std::uint64_t factorizations_ = 0, failures_ = 0, solves_ = 0;
};

// Whether the body's system is factored anew after a body step (loop/body_worker.h): when no
// factor is in hand, every refactor_every body steps (> 0), when CG took more than
// refactor_iterations per Newton iteration with the factor in hand as its preconditioner
// (cg_per_newton < 0: CG is not preconditioned by it, and refactor_every 0 then means every
// step), or after a rollback (`served`:
// the served model's options; body_model's own turn its factorisations off).
bool refactor_due(const SolverOptions& served, bool factored, int steps_since, double cg_per_newton,
                  bool rolled_back);

// One step of the multi-rate body as its thread takes it: step() on `body` (body_model of the
// served model), then a new factor when refactor_due says so (`served`: the served options;
// *since_factor counts the body steps since the last). True when it factored successfully.
// defer: the factorisation is begun (LocalModelBuilder::begin_refactor) for another thread to
// run (factor_pending), and the next step_body hands it over first if it has finished, so that
// the body steps on with the factor in hand meanwhile; the first factor is made inline. True
// then when a factorisation was begun.
bool step_body(const Model& body, const SolverOptions& served, State& s, Workspace& ws,
               LocalModelBuilder& builder, int* since_factor, bool defer = false);

// A node's own share of the tissue, k_t = E* times the median spring length (N/m; a tenth of the
// multi-rate node penalty): what an estimate puts behind each node. Allocates (at load).
double tissue_share_stiffness(const Model& m);

// Until a body step has built a local model around the probe (the probe just arrived, or moved
// beyond the last model's reach), an estimate: the region around `center` (surface contact:
// around the probe's proxy once placed) at positions x, each node behind its own share of the
// tissue (W = I / k_t per node, k_t from tissue_share_stiffness) and no force at the base state.
// `near` is scratch of at least the model's node count and three times its surface triangles
// (reserved). Allocates nothing.
void estimate_local_model(const Model& m, const std::vector<Vec3>& x, int k, const Vec3& center,
                          double radius, double margin, double k_t,
                          std::vector<std::pair<double, int>>* near, LocalModel* lm);

// A model just handed over (fresh) starts its region where `last` (the model it replaces) left
// the nodes the two share: dx = served - x0 for them (served: the positions the last tick
// served), zero for the others. Only the start of the first solve changes, not its answer.
void warm_start(const LocalModel& last, const std::vector<Vec3>& served, LocalModel* fresh);

// Ticks per body step of a served model (options.body_rate_hz > 0): round(rate / body rate).
int ticks_per_body_step(const Model& served);
// The body a served model steps on its own thread: its step ticks_per_body_step ticks long (the
// probes' node stiffness stays the served one) and, with kFactorCG, no factorisation of its own
// (the builder hands it a fresh supernodal factor after every step; until the first,
// prime_workspace leaves CG block-Jacobi preconditioned); surface probes hold their proxy
// where the tick solved it (ProbeSpec::hold_proxy).
Model body_model(const Model& served);
void prime_workspace(Workspace& ws);

// The 1 kHz side: probe k of radius R at `center` against the local model; fills probe's force,
// stiffness, contacts and the region's displaced positions x0 + dx into x (the other nodes keep
// theirs). Newton's method from the last answer's displacements, each step backtracked until the
// residual falls (the node law switches as nodes enter and leave contact, where plain Newton can
// cycle between the two sides). Surface contact needs x (the body's positions with the region
// where the last answer left it: the proxy is moved against them) and `surface`; it also moves
// the probe's proxy. Allocates nothing.
void haptic_contact(const Model& m, LocalModel& lm, int k, const Vec3& center, double radius,
                    ProbeState* probe, std::vector<Vec3>* x, SurfaceScratch* surface = nullptr);

// The converged reference of the joint solve (offline: it copies states and allocates). One step
// of `held` (a body whose surface tool k holds its proxy, ProbeSpec::hold_proxy) from *s, with
// the tool's target t where *s has it and its proxy p in joint equilibrium with the nodes x(p)
// that step leaves: R_p(p) = F_c(p - t) - F_l(p, x(p)) = 0 (the coupling's force and the layer's
// push on the tool; `free` is the same body with the proxy free). Newton on R_p from the proxy
// the plain step and update_proxy leave, its Jacobian by central differences of whole steps,
// backtracked; stops at |R_p| <= tol k_c (k_c the coupling's stiffness) or after `iterations`.
// *s ends at that step, the probe with the coupling's force at p (as the served tick gives it),
// depth and faces. ws: a workspace of `held` to step in (nullptr: one of its own). Returns
// |R_p| / k_c (m).
double joint_proxy_step(const Model& held, const Model& free, int k, State* s,
                        Workspace* ws = nullptr, int iterations = 8, double tol = 1e-10);

}  // namespace conica
