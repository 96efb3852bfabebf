// The fixed-rate loop, apart from any wire: it serves a Transport's typed messages between ticks
// and steps the scene at absolute deadlines on an injectable Clock.
//
// One tick: serve (answer probe updates and apply commands as they arrive, until the deadline;
// the last final_sleep_ns in Clock::sleep_until for precision) -> swap in a prepared scene, if
// one is ready -> input (what arrived meanwhile, at most input_budget messages) -> step (unless
// paused) -> publish a force frame, and a positions frame at positions_hz. Deadlines are
// absolute: late by less than a period, the tick runs at once (lateness counts it); later than
// that, the deadlines that are gone are skipped and counted as missed, dt stays fixed.
//
// A probe update is answered at once with the contact force at its pose against the current node
// positions (options.contact); the next tick integrates with it. Those solves are bounded between
// two ticks (options.reply_budget): past the budget an update is answered with its probe's last
// solved contact and the position it belongs to, and its pose is the next tick's target. Every
// control request is answered with the statistics, LoadScene when its scene is swapped in or
// refused: it is loaded and prepared on a worker thread (ScenePreparer) while the loop keeps
// ticking. Bad messages are answered with a Rejection, counted by kind, and change neither the rate
// nor the state.
//
// In the tick path nothing allocates, logs or does I/O except through the Transport and the
// Observer; the control path (commands other than probe updates) may allocate.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include "loop/clock.h"
#include "loop/messages.h"
#include "loop/scene.h"
#include "loop/stats.h"
#include "loop/transport.h"

namespace conica::loop {

// The contact stage for one probe against the current node positions (fills force, stiffness,
// contacts). The default is the core's (conica::probe_contact in core/step.h).
using ContactFn = void (*)(const Model& model, const State& state, int k, const Vec3& center,
                           double radius, ProbeState* probe);
void core_probe_contact(const Model& model, const State& state, int k, const Vec3& center,
                        double radius, ProbeState* probe);

struct LoopOptions {
  double rate_hz = 1000;     // the model's dt should be 1 / rate_hz
  double positions_hz = 60;  // state frames with node positions (0: never)
  int window = 2048;         // ticks in the rolling statistics window
  // The last stretch before a deadline is slept in Clock::sleep_until instead of polling the
  // transport (0: poll up to the deadline, e.g. for a transport that spins).
  TimeNs final_sleep_ns = 20'000;
  int input_budget = 128;  // messages taken in a tick's input stage
  // The time replies may spend solving contact between two ticks (the serve stretch and the input
  // stage together), as a fraction of the period. Past it, a probe update is answered with its
  // probe's last solved force and stiffness and the position they belong to (ForceReply's
  // position, which a client's local model extrapolates from; counted as replies_held), and its
  // pose becomes the target of the next tick's step. A flood of far-jumping surface-probe updates
  // then costs a tick at most this, plus the one reply that crossed it. A client updating once per
  // tick is never held, nor is any update while the loop is paused (no step to keep on time).
  double reply_budget = 0.25;
  PrepareOptions prepare;    // for LoadScene (its rate_hz is this rate_hz)
  SceneLoader scene_loader;  // LoadScene: unset, refused
  ContactFn contact = &core_probe_contact;
};

class FixedRateLoop {
 public:
  explicit FixedRateLoop(LoopOptions options, Observer* observer = nullptr);
  ~FixedRateLoop();
  FixedRateLoop(const FixedRateLoop&) = delete;
  FixedRateLoop& operator=(const FixedRateLoop&) = delete;

  const LoopOptions& options() const { return opt_; }
  PrepareOptions prepare_options() const;

  // The scene to run (prepared by prepare_scene). Not while running.
  void install(std::unique_ptr<Scene> scene);
  // The scene in use (null before install); valid until the next swap.
  const Scene* scene() const { return scene_.get(); }

  // Runs until `stop` is set (checked between messages and ticks): begin(), tick() until it
  // returns false, end().
  void run(Clock& clock, Transport& transport, const std::atomic<bool>& stop);

  // The same in pieces, for tests that drive the loop tick by tick. begin() resets the scene to
  // rest and the statistics to zero and sets the first deadline a period from now; tick() serves
  // until the next deadline and runs that tick (false, without ticking, once `stop` is set);
  // end() waits for a scene preparation still running, drops it and reports final statistics.
  void begin(Clock& clock, Transport& transport, const std::atomic<bool>* stop = nullptr);
  bool tick();
  void end();

  // While running (loop thread) or between runs.
  const LoopStats& stats() const { return stats_; }
  TimeNs period_ns() const { return period_ns_; }
  TimeNs next_deadline_ns() const { return next_; }
  bool scene_pending() const { return preparer_.busy(); }
  bool scene_ready() const { return preparer_.ready(); }  // any thread

 private:
  void serve_until(TimeNs deadline);
  void handle(const Incoming& in);
  void answer_probe(const Route& route, const ProbeUpdate& update);
  void scene_installed();
  void reject(const Route& route, const Rejection& why);
  void apply(const Route& route, const ControlRequest& request);
  void finish_control(const Route& route, ControlResult* result);
  void swap_prepared_scene();
  void set_positions_rate(double hz);
  void refresh_stats();
  bool stopped() const { return stop_ != nullptr && stop_->load(std::memory_order_relaxed); }

  LoopOptions opt_;
  Observer* observer_;
  Observer no_observer_;
  std::unique_ptr<Scene> scene_, retired_;
  ScenePreparer preparer_;
  Route load_route_;  // who asked for the scene being prepared
  std::uint64_t load_sequence_ = 0;

  Clock* clock_ = nullptr;
  Transport* transport_ = nullptr;
  const std::atomic<bool>* stop_ = nullptr;
  Incoming in_;            // reused: no allocation per message
  ControlResult control_;  // reused
  TimeNs period_ns_ = 1'000'000, next_ = 0;
  std::uint64_t positions_every_ = 0;  // ticks between positions frames (0: never)
  bool paused_ = false;
  TimeNs reply_budget_ns_ = 0, reply_spent_ns_ = 0;  // solving replies since the last tick
  std::vector<Vec3> solved_at_;  // per probe: the position its force and stiffness belong to
  RollingWindow lateness_, input_, stepping_, publish_;
  LoopStats stats_;
};

}  // namespace conica::loop
