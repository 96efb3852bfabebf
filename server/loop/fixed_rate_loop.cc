#include "loop/fixed_rate_loop.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <utility>

#include "core/step.h"

namespace conica::loop {
namespace {

constexpr std::uint64_t kStatsEveryTicks = 100;  // percentile refresh period

double us(TimeNs from, TimeNs to) { return to > from ? static_cast<double>(to - from) * 1e-3 : 0; }

}  // namespace

void core_probe_contact(const Model& model, const State& state, int k, const Vec3& center,
                        double radius, ProbeState* probe) {
  conica::probe_contact(model, state.x, k, center, radius, probe);
}

FixedRateLoop::FixedRateLoop(LoopOptions options, Observer* observer)
    : opt_(std::move(options)),
      observer_(observer ? observer : &no_observer_),
      lateness_(opt_.window),
      input_(opt_.window),
      stepping_(opt_.window),
      publish_(opt_.window) {}

FixedRateLoop::~FixedRateLoop() = default;

PrepareOptions FixedRateLoop::prepare_options() const {
  PrepareOptions p = opt_.prepare;
  p.rate_hz = opt_.rate_hz;
  return p;
}

void FixedRateLoop::install(std::unique_ptr<Scene> scene) {
  retired_.reset();
  scene_ = std::move(scene);
  scene_installed();
}

void FixedRateLoop::scene_installed() {
  solved_at_.assign(scene_ ? scene_->state.probes.size() : 0, Vec3::Zero());
  if (scene_)
    for (std::size_t k = 0; k < solved_at_.size(); ++k)
      solved_at_[k] = scene_->state.probes[k].center;
}

void FixedRateLoop::run(Clock& clock, Transport& transport, const std::atomic<bool>& stop) {
  begin(clock, transport, &stop);
  while (tick()) {
  }
  end();
}

void FixedRateLoop::begin(Clock& clock, Transport& transport, const std::atomic<bool>* stop) {
  clock_ = &clock;
  transport_ = &transport;
  stop_ = stop;
  if (scene_) reset_scene(scene_.get());
  paused_ = false;
  stats_ = LoopStats{};
  stats_.rate_hz = opt_.rate_hz;
  for (RollingWindow* w : {&lateness_, &input_, &stepping_, &publish_}) w->clear();
  period_ns_ = static_cast<TimeNs>(std::llround(1e9 / opt_.rate_hz));
  reply_budget_ns_ = static_cast<TimeNs>(std::llround(opt_.reply_budget * period_ns_));
  reply_spent_ns_ = 0;
  scene_installed();
  set_positions_rate(opt_.positions_hz);
  next_ = clock.now_ns() + period_ns_;
}

bool FixedRateLoop::tick() {
  if (!scene_ || !transport_) return false;
  serve_until(next_);
  if (stopped()) return false;
  const TimeNs wake = clock_->now_ns();
  lateness_.add(us(next_, wake));

  swap_prepared_scene();  // the tick boundary: a prepared scene takes over here
  for (int k = 0; k < opt_.input_budget && !stopped() && transport_->poll(0, &in_); ++k)
    handle(in_);  // input: whatever arrived during the last stretch
  const TimeNs t_in = clock_->now_ns();
  Scene& s = *scene_;
  if (!paused_) {
    if (s.body_worker)
      s.body_worker->tick(*s.model, s.state);  // multi-rate: the body steps on its own thread
    else
      step(*s.model, s.state, *s.workspace);
  }
  const TimeNs t_step = clock_->now_ns();
  // The step solved every probe's contact at its target: what a held reply answers with.
  if (!paused_)
    for (std::size_t k = 0; k < solved_at_.size(); ++k) solved_at_[k] = s.state.probes[k].center;
  reply_spent_ns_ = 0;
  ++stats_.ticks;
  StateFrame frame{s.model.get(), &s.state, &stats_, false};
  transport_->publish(frame);
  if (positions_every_ && stats_.ticks % positions_every_ == 0) {
    frame.with_positions = true;
    transport_->publish(frame);
  }
  const TimeNs t_pub = clock_->now_ns();
  input_.add(us(wake, t_in));
  stepping_.add(us(t_in, t_step));
  publish_.add(us(t_step, t_pub));
  // Percentiles a few times per second (and early on, so the first frames carry some).
  if (stats_.ticks % kStatsEveryTicks == 0 ||
      (stats_.ticks < kStatsEveryTicks && (stats_.ticks & (stats_.ticks - 1)) == 0))
    refresh_stats();

  // Next absolute deadline. Late by less than a period: run it at once (lateness counts it);
  // later than that: skip the deadlines that are gone, count them, keep dt.
  next_ += period_ns_;
  const TimeNs t = clock_->now_ns();
  if (t > next_ + period_ns_) {
    const std::uint64_t missed = (t - next_) / period_ns_;
    next_ += missed * period_ns_;
    stats_.missed_ticks += missed;
  }
  return true;
}

void FixedRateLoop::end() {
  preparer_.wait();  // a LoadScene still preparing is dropped, unanswered
  if (scene_) refresh_stats();
  clock_ = nullptr;
  transport_ = nullptr;
  stop_ = nullptr;
}

void FixedRateLoop::serve_until(TimeNs deadline) {
  for (;;) {
    if (stopped()) return;
    const TimeNs t = clock_->now_ns();
    if (t >= deadline) return;
    if (deadline - t <= opt_.final_sleep_ns) {
      clock_->sleep_until(deadline);
      return;
    }
    if (transport_->poll(deadline - opt_.final_sleep_ns, &in_)) handle(in_);
  }
}

void FixedRateLoop::handle(const Incoming& in) {
  if (const auto* p = std::get_if<ProbeUpdate>(&in.message))
    answer_probe(in.route, *p);
  else if (const auto* c = std::get_if<ControlRequest>(&in.message))
    apply(in.route, *c);
  else
    reject(in.route, std::get<Rejection>(in.message));
}

void FixedRateLoop::answer_probe(const Route& route, const ProbeUpdate& u) {
  const TimeNs recv = clock_->now_ns();
  Scene& s = *scene_;
  Rejection why;
  if (!check_probe(u, s.limits, &why)) {
    reject(route, why);
    return;
  }
  ++stats_.probes_received;
  ProbeState& ps = s.state.probes[u.probe_id];
  if (u.radius > 0) ps.radius = u.radius;
  set_probe(s.state, u.probe_id, u.position, true);
  // Paused, no step follows that the budget would keep on time.
  const bool held = !paused_ && reply_spent_ns_ >= reply_budget_ns_;
  if (held) {
    ++stats_.replies_held;  // the last solved contact; the step takes the pose as its target
  } else {
    if (s.body_worker)
      s.body_worker->contact(*s.model, s.state, u.probe_id, u.position, ps.radius, &ps);
    else
      opt_.contact(*s.model, s.state, u.probe_id, u.position, ps.radius, &ps);
    solved_at_[u.probe_id] = u.position;
  }
  ForceReply reply;
  reply.update = u;
  reply.probe = ps;
  reply.probe.center = solved_at_[u.probe_id];
  reply.tick = s.state.tick;
  reply.recv_ns = recv;
  reply.reply_ns = clock_->now_ns();
  if (!held) reply_spent_ns_ += reply.reply_ns - recv;
  const bool sent = transport_->reply(route, reply);
  sent ? ++stats_.replies_sent : ++stats_.replies_dropped;
}

void FixedRateLoop::reject(const Route& route, const Rejection& why) {
  const int code = static_cast<int>(why.kind);
  ++stats_.errors;
  if (code >= 0 && code < kNumErrorCodes) ++stats_.errors_by_code[code];
  if (route.routable) {
    const bool sent = transport_->reply(route, why);
    if (route.channel == Channel::kProbe) sent ? ++stats_.replies_sent : ++stats_.replies_dropped;
  }
  observer_->on_rejected(route.channel, why);
}

void FixedRateLoop::apply(const Route& route, const ControlRequest& request) {
  control_.sequence = request.sequence;
  control_.ok = true;
  control_.message.clear();
  control_.mesh = nullptr;
  Scene& s = *scene_;
  const Command& c = request.command;
  if (const auto* load = std::get_if<LoadScene>(&c)) {
    if (!opt_.scene_loader) {
      control_.ok = false;
      control_.message = "this server cannot load scene files";
    } else if (preparer_.busy()) {
      control_.ok = false;
      control_.message = "another scene is still loading";
    } else {
      // Answered when the scene is swapped in or refused (swap_prepared_scene).
      load_route_ = route;
      load_sequence_ = request.sequence;
      preparer_.start(load->source, opt_.scene_loader, prepare_options(), std::move(retired_));
      return;
    }
  } else if (std::holds_alternative<Reset>(c)) {
    reset_scene(&s);
    scene_installed();
    control_.message = "reset to the rest state";
  } else if (std::holds_alternative<Pause>(c)) {
    paused_ = true;
    control_.message = "paused";
  } else if (std::holds_alternative<Resume>(c)) {
    paused_ = false;
    control_.message = "running";
  } else if (const auto* set = std::get_if<SetParameter>(&c)) {
    // The model is immutable during a step; between ticks the loop owns it.
    Model& m = *s.model;
    const double v = set->value;
    bool ok = std::isfinite(v);
    switch (ok ? set->parameter : Parameter::kUnknown) {
      case Parameter::kDamping:
        if ((ok = v >= 0)) {
          m.options.mass_damping = v;
          scene_options_changed(&s);  // the far field's bounds depend on it
        }
        break;
      case Parameter::kGravityX:
      case Parameter::kGravityY:
      case Parameter::kGravityZ:
        m.options
            .gravity[static_cast<int>(set->parameter) - static_cast<int>(Parameter::kGravityX)] = v;
        break;
      case Parameter::kPositionsHz:
        if ((ok = v >= 0)) set_positions_rate(v);
        break;
      case Parameter::kUnknown:
        ok = false;
    }
    control_.ok = ok;
    control_.message = ok ? std::string(parameter_name(set->parameter)) + " set"
                          : "unknown parameter or bad value (damping >= 0 1/s, gravity_x|y|z "
                            "m/s^2, positions_hz >= 0)";
  } else if (std::holds_alternative<GetMesh>(c)) {
    control_.mesh = s.model.get();
  }  // GetStats: the statistics only
  finish_control(route, &control_);
}

void FixedRateLoop::finish_control(const Route& route, ControlResult* result) {
  refresh_stats();
  result->stats = stats_;
  result->counters = scene_->state.counters;
  result->num_nodes = static_cast<std::uint32_t>(scene_->model->num_nodes());
  if (route.routable) (void)transport_->reply(route, *result);
}

void FixedRateLoop::swap_prepared_scene() {
  if (!preparer_.ready()) return;  // one atomic load per tick
  ScenePreparer::Result r = preparer_.take();
  control_.sequence = load_sequence_;
  control_.mesh = nullptr;
  control_.ok = r.scene != nullptr;
  if (control_.ok) {
    retired_ = std::move(scene_);  // destroyed on the next preparation's worker
    scene_ = std::move(r.scene);
    scene_installed();  // allocates: the control path
    char text[96];
    std::snprintf(text, sizeof(text), "loaded %d nodes, step %.1f us", scene_->model->num_nodes(),
                  scene_->step_us);
    control_.message = text;
  } else {
    control_.message = r.error;
  }
  SceneReport report;
  report.source = r.source;
  report.ok = control_.ok;
  report.error = r.error;
  report.scene = scene_.get();
  report.notes = &r.notes;
  observer_->on_scene(report);
  finish_control(load_route_, &control_);
}

void FixedRateLoop::set_positions_rate(double hz) {
  positions_every_ = hz > 0 ? std::max<std::uint64_t>(1, std::llround(opt_.rate_hz / hz)) : 0;
}

void FixedRateLoop::refresh_stats() {
  const auto l = lateness_.summary(), i = input_.summary(), s = stepping_.summary(),
             p = publish_.summary();
  stats_.lateness_p50_us = l.p50;
  stats_.lateness_p99_us = l.p99;
  stats_.lateness_max_us = l.max;
  stats_.step_p50_us = s.p50;
  stats_.step_p99_us = s.p99;
  stats_.step_max_us = s.max;
  stats_.input_p50_us = i.p50;
  stats_.input_p99_us = i.p99;
  stats_.publish_p50_us = p.p50;
  stats_.publish_p99_us = p.p99;
  stats_.paused = paused_;
  stats_.window = static_cast<std::uint32_t>(lateness_.size());
  const BodyWorker* body = scene_ ? scene_->body_worker.get() : nullptr;
  stats_.body = body ? body->stats() : BodyStats{};
  observer_->on_stats(stats_, scene_->state.counters);
}

}  // namespace conica::loop
