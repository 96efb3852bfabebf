// Multi-rate serving (solver body_rate_hz, core/multirate.h): the accurate body steps at its own
// rate on a thread of its own, and each 1 kHz tick answers the probes from the local compliance
// its last step left, so a body whose step costs tens of milliseconds is felt at 1 kHz.
//
// Every `every` ticks the tick hands the probes' poses to the body thread (if it is idle), which
// steps the body once by every / rate seconds with the probes there (implicit Euler), builds each
// active probe's local model and hands back the model and the node positions through a second
// buffer. The body's system is factored anew after a step when the served model's
// refactor_every body steps have passed, when CG took more than its refactor_iterations per
// Newton iteration with the factor in hand, or after a rollback, on a thread of its own by
// default (Factoring); until it is handed over the local models come from the factor in hand
// (which also preconditions the steps). The tick swaps in a finished
// step at its start and never waits: a body thread that falls behind leaves the tick on the last
// local model (late_ticks counts the ticks a step was due but the thread was still busy). A probe
// farther from where the body step saw it than the local model's reach, or one with no local model
// yet, is answered by its contact law against the body's last positions with each node behind its
// own share of the tissue (estimate_local_model). Surface probes (contact SURFACE) keep their proxy
// on the tick's side: each tick moves it against the served positions, and the body step holds it
// where the tick left it (body_model, ProbeSpec::hold_proxy).
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <thread>
#include <vector>

#include "core/model.h"
#include "core/multirate.h"
#include "core/step.h"
#include "loop/messages.h"

namespace conica::loop {

// Where the body's numeric factorisations run (LocalModelBuilder::refactor): on the body thread
// after the step that asked for one; on a thread of their own while the body steps on with the
// factor in hand (handed over at the first body step after it finished); or on that thread with
// the next body step waiting for it (the same sequence on any machine, for tests and benchmarks).
enum class Factoring { kInline, kBackground, kWaited };

class BodyWorker {
 public:
  // `served`: the scene's model (dt one tick) at rest in `rest`; the body steps every
  // round(rate / options.body_rate_hz) ticks. Allocates; starts the threads (normal priority).
  BodyWorker(const Model& served, const State& rest, Factoring factoring = Factoring::kBackground);
  ~BodyWorker();
  BodyWorker(const BodyWorker&) = delete;
  BodyWorker& operator=(const BodyWorker&) = delete;

  // In place of step() at each tick (the loop thread): no allocation, never waits.
  void tick(const Model& served, State& s);
  // A probe's force at a pose between ticks (the probe reply), like tick's; a surface probe's is
  // its proxy moved against the served positions with the nodes held (as a single-rate reply).
  void contact(const Model& served, const State& s, int k, const Vec3& center, double radius,
               ProbeState* probe);

  int every() const { return every_; }
  // Tests and benchmarks: a body step is handed over no sooner than `ticks` ticks after its
  // kick-off, as from a body thread that slow (deterministic where the caller waits for each
  // step to finish before the next tick). 0: as soon as it is done.
  void set_latency(int ticks) { latency_ = ticks; }
  bool stepping() const { return state_.load(std::memory_order_acquire) == kRun; }  // any thread
  double reach() const { return reach_; }
  std::uint64_t body_steps() const { return body_steps_; }  // swapped in
  std::uint64_t late_ticks() const { return late_ticks_; }
  std::uint64_t frozen_answers() const { return frozen_; }  // answered by the estimate
  // Joint solves answered by the proxy moved alone (LocalModel::proxy_fallback; 1 kHz thread).
  std::uint64_t proxy_fallbacks() const { return proxy_fallbacks_; }
  // Layer evaluations of the last answer from a local model (ticks; for benchmarks).
  int last_layer_evaluations() const { return evaluations_; }
  // The body thread's factorisations and W solves so far (relaxed reads; for statistics).
  std::uint64_t factorizations() const { return factorizations_.load(std::memory_order_relaxed); }
  std::uint64_t region_solves() const { return region_solves_.load(std::memory_order_relaxed); }
  std::uint64_t rollbacks() const { return rollbacks_.load(std::memory_order_relaxed); }
  // The body's Newton and CG iterations so far (relaxed reads; for benchmarks).
  std::uint64_t newton_iterations() const { return newton_.load(std::memory_order_relaxed); }
  std::uint64_t cg_iterations() const { return cg_.load(std::memory_order_relaxed); }
  // The body thread's last step plus local models, ns (relaxed; for statistics).
  std::int64_t last_body_ns() const { return body_ns_.load(std::memory_order_relaxed); }
  BodyStats stats() const;  // all of the above, for the loop's statistics

 private:
  enum : int { kIdle = 0, kRun = 1, kDone = 2, kStop = 3 };
  struct Snapshot {
    std::vector<LocalModel> local;  // (probes)
    std::vector<Vec3> x;            // (nodes) m
  };
  void run();
  void run_factor();
  void answer(const Model& served, const std::vector<Vec3>& x, int k, const Vec3& center,
              double radius, ProbeState* probe, std::vector<Vec3>* x_out);

  Model body_;  // the served model, dt = every ticks
  State body_state_;
  Workspace ws_;
  LocalModelBuilder builder_;
  int every_ = 1;
  SolverOptions served_options_;  // refactor_every (body steps), refactor_iterations
  int since_factor_ = 0;          // body steps since the last factor
  double reach_ = 0;              // m, the region's margin beyond the probe radius
  Snapshot snap_[2];
  SurfaceScratch surface_;     // the ticks' surface contact (probes with contact SURFACE)
  std::vector<double> share_;  // (probes) N/m, the estimate's stiffness per node
  // (probes) Until a body step's model covers the probe: an estimate around it, kept while the
  // probe stays within reach of where it was made and no body step has been handed over (its
  // region's motion then carries over from tick to tick, as a body step's model's does).
  struct Estimate {
    LocalModel model;
    std::uint64_t body_step = 0;  // body_steps_ when it was made
    double radius = 0;            // m, the tool radius it was made for
  };
  std::vector<Estimate> estimates_;
  std::vector<std::pair<double, int>> near_;  // (nodes) the estimate's scratch
  int front_ = 0, back_ = 1;
  std::vector<ProbeState> input_;  // the poses of the next body step
  std::atomic<int> state_{kIdle};
  std::atomic<std::int64_t> body_ns_{0};
  std::atomic<std::uint64_t> factorizations_{0}, region_solves_{0}, rollbacks_{0};
  std::atomic<std::uint64_t> newton_{0}, cg_{0};
  int since_ = 0;
  std::uint64_t body_steps_ = 0, late_ticks_ = 0, frozen_ = 0, proxy_fallbacks_ = 0;
  int latency_ = 0;
  int evaluations_ = 0;
  Factoring factoring_ = Factoring::kBackground;
  std::atomic<int> factor_job_{0};  // 1: the builder has a factorisation pending; 2: stop
  std::thread factor_thread_;
  std::thread thread_;
};

}  // namespace conica::loop
