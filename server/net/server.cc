#include "net/server.h"

#include <pthread.h>
#include <sched.h>
#include <spdlog/spdlog.h>
#include <sys/mman.h>
#include <sys/prctl.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <future>

#include "loop/clock.h"
#include "loop/fixed_rate_loop.h"
#include "net/curve.h"
#include "net/probe_contact.h"
#include "net/zmq_transport.h"

namespace conica::net {
namespace {

constexpr loop::TimeNs kFinalSleepNs =
    20000;  // the last stretch before a deadline: clock_nanosleep
constexpr loop::TimeNs kErrorLogPeriodNs = 10ull * 1000000000ull;

loop::LoopOptions loop_options(const ServerOptions& o) {
  loop::LoopOptions l;
  l.rate_hz = o.rate_hz;
  l.positions_hz = o.positions_hz;
  l.window = o.window;
  l.final_sleep_ns = o.busy_poll ? 0 : kFinalSleepNs;  // busy poll spins up to the deadline
  l.prepare.refuse_slow_scene = o.refuse_slow_scene;
  l.prepare.box_margin = o.box_margin;
  l.scene_loader = o.scene_loader;
  l.contact = &probe_contact;
  return l;
}

void log_notes(const std::vector<loop::Note>& notes) {
  for (const loop::Note& n : notes) {
    if (n.warning)
      spdlog::warn("{}", n.text);
    else
      spdlog::info("{}", n.text);
  }
}

void try_realtime(const ServerOptions& opt) {
  prctl(PR_SET_TIMERSLACK, 1UL, 0, 0, 0);
  if (opt.busy_poll)
    spdlog::warn(
        "busy poll: the loop thread spins on its sockets (resting {:.0f} % of a period "
        "after each probe) and uses a whole core",
        100 * (1 - opt.busy_poll_fraction));
  if (!opt.realtime) return;
  sched_param sp{};
  sp.sched_priority = std::min(80, sched_get_priority_max(SCHED_FIFO));
  if (const int e = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp); e != 0)
    spdlog::info("SCHED_FIFO refused ({}); running at normal priority", std::strerror(e));
  else
    spdlog::info("loop thread runs SCHED_FIFO priority {}", sp.sched_priority);
  if (mlockall(MCL_CURRENT | MCL_FUTURE) != 0)
    spdlog::info("mlockall refused ({}); memory may page", std::strerror(errno));
}

}  // namespace

// What the loop reports, on the loop thread: the statistics snapshot for stats(), and logs.
class Server::Events final : public loop::Observer {
 public:
  Events(Server& server, loop::Clock& clock) : srv_(server), clock_(clock) {}

  void begin() {
    next_log_ns_ = clock_.now_ns() + static_cast<loop::TimeNs>(srv_.options_.log_period_s * 1e9);
    error_logged_at_.fill(0);
    error_suppressed_.fill(0);
  }

  void on_stats(const LoopStatsData& s, const Counters& c) override {
    {
      std::lock_guard lock(srv_.mutex_);
      srv_.stats_ = s;
    }
    const double period_s = srv_.options_.log_period_s;
    const loop::TimeNs t = clock_.now_ns();
    if (period_s <= 0 || t < next_log_ns_) return;
    next_log_ns_ = t + static_cast<loop::TimeNs>(period_s * 1e9);
    spdlog::info(
        "loop: {} ticks, {} missed; lateness p50/p99/max {:.0f}/{:.0f}/{:.0f} us; step p50/p99 "
        "{:.0f}/{:.0f} us; input p99 {:.0f} us; publish p99 {:.0f} us; probes {}, errors {}, "
        "rollbacks {}",
        s.ticks, s.missed_ticks, s.lateness_p50_us, s.lateness_p99_us, s.lateness_max_us,
        s.step_p50_us, s.step_p99_us, s.input_p99_us, s.publish_p99_us, s.probes_received, s.errors,
        c.rollbacks);
    if (s.body.steps > 0)
      spdlog::info(
          "body: {} steps, {} late ticks, {} estimated answers, {} proxy fallbacks, {} "
          "factorisations, {} rollbacks; last step {:.0f} us",
          s.body.steps, s.body.late_ticks, s.body.estimates, s.body.proxy_fallbacks,
          s.body.factorizations, s.body.rollbacks, s.body.step_us);
  }

  // Once per kind per 10 s, with the number suppressed since.
  void on_rejected(loop::Channel channel, const DecodeError& err) override {
    const int code = static_cast<int>(err.kind);
    if (code < 0 || code >= kNumErrorCodes) return;
    const loop::TimeNs t = clock_.now_ns();
    if (error_logged_at_[code] != 0 && t - error_logged_at_[code] < kErrorLogPeriodNs) {
      ++error_suppressed_[code];
      return;
    }
    spdlog::warn("{} socket: {} message ({}){}",
                 channel == loop::Channel::kProbe ? "probe" : "control", error_kind_name(err.kind),
                 err.message,
                 error_suppressed_[code]
                     ? fmt::format("; {} more since the last report", error_suppressed_[code])
                     : "");
    error_logged_at_[code] = t;
    error_suppressed_[code] = 0;
  }

  void on_scene(const loop::SceneReport& r) override {
    if (r.notes) log_notes(*r.notes);
    if (!r.ok) {
      spdlog::warn("LOAD_SCENE {} refused: {}", r.source, r.error);
      return;
    }
    const Model& m = *r.scene->model;
    spdlog::info("loaded scene {}: {} nodes, {} springs, step {:.1f} us", r.source, m.num_nodes(),
                 m.num_springs(), r.scene->step_us);
  }

 private:
  Server& srv_;
  loop::Clock& clock_;
  loop::TimeNs next_log_ns_ = 0;
  std::array<loop::TimeNs, kNumErrorCodes> error_logged_at_{};
  std::array<std::uint64_t, kNumErrorCodes> error_suppressed_{};
};

Server::Server(zmq::context_t& context, ServerOptions options)
    : context_(context),
      options_(std::move(options)),
      clock_(std::make_unique<loop::SteadyClock>()),
      events_(std::make_unique<Events>(*this, *clock_)),
      loop_(std::make_unique<loop::FixedRateLoop>(loop_options(options_), events_.get())) {}

Server::~Server() { stop(); }

const Model& Server::model() const { return *loop_->scene()->model; }

double Server::measured_step_us() const { return loop_->scene() ? loop_->scene()->step_us : 0.0; }

Endpoints Server::endpoints() const {
  std::lock_guard lock(mutex_);
  return endpoints_;
}

LoopStatsData Server::stats() const {
  std::lock_guard lock(mutex_);
  return stats_;
}

std::string Server::load(const BodySpec& spec) {
  if (running()) return "load() while running: use LOAD_SCENE";
  auto scene = std::make_unique<loop::Scene>();
  const std::string e = loop::prepare_scene(spec, loop_->prepare_options(), scene.get());
  log_notes(scene->notes);
  if (!e.empty()) return e;
  const Model& m = *scene->model;
  spdlog::info("scene: {} nodes, {} springs, {} probes; step {:.1f} us (median of {})",
               m.num_nodes(), m.num_springs(), m.probes.size(), scene->step_us,
               loop_->prepare_options().benchmark_steps);
  loop_->install(std::move(scene));
  return {};
}

std::string Server::start() {
  if (running()) return "already running";
  if (!loop_->scene()) return "no scene loaded";
  if (!(options_.rate_hz > 0) || !std::isfinite(options_.rate_hz)) return "rate_hz must be > 0";
  if (!options_.curve_secret_key.empty()) {
    if (!curve_available()) return "CURVE requested but this libzmq has no CURVE support";
    if (!valid_z85_key(options_.curve_secret_key)) return "CURVE secret key is not a z85 key";
    if (options_.curve_client_keys.empty()) return "CURVE needs at least one client public key";
    for (const std::string& k : options_.curve_client_keys)
      if (!valid_z85_key(k)) return "CURVE client key is not a z85 key: " + k;
    // The handler must be bound before the sockets: without one libzmq accepts every client.
    zap_ = std::make_unique<ZapHandler>(context_, options_.curve_client_keys);
    if (std::string e = zap_->start(); !e.empty()) {
      zap_.reset();
      return e;
    }
  }
  stop_.store(false);
  std::promise<std::string> bound;
  std::future<std::string> result = bound.get_future();
  thread_ = std::thread([this, &bound] {
    ZmqTransport transport(context_, options_, *clock_);
    Endpoints ep;
    std::string e = transport.bind(&ep);
    if (e.empty()) {
      std::lock_guard lock(mutex_);
      endpoints_ = ep;
    }
    const bool ok = e.empty();
    if (!ok) transport.close();
    bound.set_value(std::move(e));  // `bound` is not touched after this
    if (!ok) return;
    try_realtime(options_);
    events_->begin();
    loop_->run(*clock_, transport, stop_);
    transport.close();  // sockets before the caller's context, linger 0
  });
  std::string e = result.get();
  if (!e.empty()) {
    thread_.join();
    if (zap_) zap_->stop();
    return e;
  }
  const Endpoints ep = endpoints();
  spdlog::info("serving: probes {}, state {}, control {} at {} Hz{}", ep.probe, ep.state,
               ep.control, options_.rate_hz,
               zap_ ? fmt::format(", CURVE with {} client keys", options_.curve_client_keys.size())
                    : std::string());
  return {};
}

void Server::stop() {
  if (!thread_.joinable()) return;
  stop_.store(true);
  thread_.join();
  if (zap_) zap_->stop();  // after the sockets are closed
}

std::uint64_t Server::curve_refused() const { return zap_ ? zap_->refused() : 0; }
std::uint64_t Server::curve_accepted() const { return zap_ ? zap_->accepted() : 0; }

}  // namespace conica::net
