#include "net/server.h"

#include <google/protobuf/arena.h>
#include <poll.h>
#include <pthread.h>
#include <sched.h>
#include <spdlog/spdlog.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <time.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <future>
#include <vector>

#include "core/step.h"
#include "net/curve.h"
#include "net/loop_stats.h"
#include "net/probe_contact.h"

namespace conica::net {
namespace {

using Clock = std::uint64_t;  // CLOCK_MONOTONIC, ns

Clock now_ns() {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<Clock>(ts.tv_sec) * 1000000000ull + static_cast<Clock>(ts.tv_nsec);
}

timespec to_timespec(Clock ns) {
  timespec ts;
  ts.tv_sec = static_cast<time_t>(ns / 1000000000ull);
  ts.tv_nsec = static_cast<long>(ns % 1000000000ull);
  return ts;
}

// Sleeps until the absolute CLOCK_MONOTONIC time `deadline`, retrying on EINTR.
void sleep_until(Clock deadline) {
  const timespec ts = to_timespec(deadline);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

// "tcp://HOST:PORT": is HOST a loopback address? Other transports (inproc, ipc) are local.
bool is_loopback(const std::string& endpoint) {
  const std::string tcp = "tcp://";
  if (endpoint.rfind(tcp, 0) != 0) return true;
  std::string host = endpoint.substr(tcp.size());
  host = host.substr(0, host.rfind(':'));
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']')
    host = host.substr(1, host.size() - 2);
  return host.rfind("127.", 0) == 0 || host == "localhost" || host == "::1";
}

constexpr int kMaxFrames = 4;           // [identity][delimiter][payload] at most, one spare
constexpr Clock kFinalSleepNs = 20000;  // the last stretch before a deadline: clock_nanosleep
constexpr std::uint64_t kStatsEveryTicks = 100;  // percentile refresh period
constexpr Clock kErrorLogPeriodNs = 10ull * 1000000000ull;
// Messages handled per drain call: a client flooding faster than the loop can answer must not
// hold off the tick (the caller checks its deadline between calls).
constexpr int kDrainBudget = 64;

// A spin-wait hint to the CPU (busy polling).
inline void cpu_relax() {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_ia32_pause();
#elif defined(__aarch64__)
  asm volatile("yield");
#endif
}

}  // namespace

struct Server::Loop {
  Server& srv;
  const ServerOptions& opt;
  zmq::socket_t probe, pub, control;
  int probe_fd = -1, control_fd = -1;

  const Model* model = nullptr;
  State state;
  std::unique_ptr<Workspace> ws;
  ProbeLimits limits;
  bool paused = false;

  // Decoding: messages live on an arena that is reset after each one; with a preallocated first
  // block, parsing allocates nothing.
  std::vector<char> arena_block;
  std::unique_ptr<google::protobuf::Arena> arena;
  // Encoding: one reused message per kind, so oneof cases never switch and sub-messages stay.
  v1::ServerMessage force_msg, error_msg, state_msg, control_msg;
  std::vector<std::uint8_t> out;
  std::array<zmq::message_t, kMaxFrames> frames;

  Clock period_ns = 1000000;
  Clock rest_ns = 0;         // busy poll: rest in ppoll this long after a probe (see rest_after)
  Clock rest_until_ns = 0;
  Clock last_probe_ns = 0;
  std::uint64_t positions_every = 0;  // ticks between "S" frames (0: never)
  RollingWindow lateness, input, stepping, publish;
  LoopStatsData stats;
  std::array<Clock, kNumErrorCodes> error_logged_at{};
  std::array<std::uint64_t, kNumErrorCodes> error_suppressed{};
  Clock next_log_ns = 0;

  Loop(Server& s)
      : srv(s),
        opt(s.options_),
        lateness(s.options_.window),
        input(s.options_.window),
        stepping(s.options_.window),
        publish(s.options_.window) {
    arena_block.resize(4 * static_cast<std::size_t>(std::max(opt.max_message_bytes, 4096)));
    google::protobuf::ArenaOptions ao;
    ao.initial_block = arena_block.data();
    ao.initial_block_size = arena_block.size();
    arena = std::make_unique<google::protobuf::Arena>(ao);
    out.resize(64 * 1024);
  }

  // ---- setup ------------------------------------------------------------------------------

  std::string bind_all() {
    auto common = [&](zmq::socket_t& s) {
      s.set(zmq::sockopt::linger, 0);
      if (!opt.curve_secret_key.empty()) set_curve_server(s, opt.curve_secret_key);
    };
    try {
      probe = zmq::socket_t(srv.context_, zmq::socket_type::router);
      pub = zmq::socket_t(srv.context_, zmq::socket_type::pub);
      control = zmq::socket_t(srv.context_, zmq::socket_type::router);
      for (zmq::socket_t* s : {&probe, &pub, &control}) common(*s);
      for (zmq::socket_t* s : {&probe, &control}) {
        s->set(zmq::sockopt::maxmsgsize, static_cast<int64_t>(opt.max_message_bytes));
        s->set(zmq::sockopt::router_mandatory, 0);  // a vanished client: the reply is dropped
      }
      pub.set(zmq::sockopt::sndhwm, opt.pub_sndhwm);
      Endpoints ep;
      const std::pair<zmq::socket_t*, const std::string*> binds[] = {
          {&probe, &opt.probe_endpoint},
          {&pub, &opt.state_endpoint},
          {&control, &opt.control_endpoint}};
      std::string* resolved[] = {&ep.probe, &ep.state, &ep.control};
      for (int k = 0; k < 3; ++k) {
        const std::string& e = *binds[k].second;
        if (!is_loopback(e))
          spdlog::warn("binding {} on a non-loopback address: reachable from other machines{}", e,
                       opt.curve_secret_key.empty()
                           ? ", unauthenticated and unencrypted (see --curve-server-key)"
                           : " (CURVE: listed clients only)");
        try {
          binds[k].first->bind(e);
        } catch (const zmq::error_t& err) {
          return "cannot bind " + e + ": " + err.what();
        }
        *resolved[k] = binds[k].first->get(zmq::sockopt::last_endpoint);
      }
      probe_fd = probe.get(zmq::sockopt::fd);
      control_fd = control.get(zmq::sockopt::fd);
      std::lock_guard lock(srv.mutex_);
      srv.endpoints_ = ep;
    } catch (const zmq::error_t& err) {
      return std::string("zmq: ") + err.what();
    }
    return {};
  }

  // Unbinding first releases an inproc endpoint at once; closing alone leaves it to ZeroMQ's
  // reaper thread, so a restart in the same context could find it still taken.
  void close_all() {
    for (zmq::socket_t* s : {&probe, &pub, &control}) {
      if (s->handle() == nullptr) continue;
      try {
        const std::string e = s->get(zmq::sockopt::last_endpoint);
        if (!e.empty()) s->unbind(e);
      } catch (const zmq::error_t&) {
        // not bound (a failed bind): nothing to release
      }
      s->close();
    }
  }

  void use_model(const Model* m) {
    model = m;
    state = make_state(*m);
    ws = std::make_unique<Workspace>(*m);
    body_box(*m, opt.box_margin, &limits);
  }

  void try_realtime() {
    prctl(PR_SET_TIMERSLACK, 1UL, 0, 0, 0);
    if (opt.busy_poll)
      spdlog::warn("busy poll: the loop thread spins on its sockets (resting {:.0f} % of a period "
                   "after each probe) and uses a whole core", 100 * (1 - opt.busy_poll_fraction));
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

  // ---- messages ---------------------------------------------------------------------------

  // Receives one multipart message without blocking; false when none is waiting. Extra frames
  // beyond kMaxFrames are drained and reported as n = kMaxFrames + 1.
  bool recv_multipart(zmq::socket_t& s, int* n) {
    auto r = s.recv(frames[0], zmq::recv_flags::dontwait);
    if (!r) return false;
    *n = 1;
    while (frames[*n - 1].more()) {
      if (*n < kMaxFrames) {
        (void)s.recv(frames[*n], zmq::recv_flags::none);  // parts arrive atomically
        ++*n;
      } else {
        zmq::message_t extra;
        (void)s.recv(extra, zmq::recv_flags::none);
        if (!extra.more()) {
          *n = kMaxFrames + 1;
          break;
        }
      }
    }
    return true;
  }

  // Reply envelope: [identity] or [identity][empty delimiter] (REQ clients) before the payload.
  // Returns the payload index, or -1 when the envelope is not one of those.
  int payload_index(int n) const {
    if (n == 2) return 1;
    if (n == 3 && frames[1].size() == 0) return 2;
    return -1;
  }

  void send_reply(zmq::socket_t& s, int payload, const v1::ServerMessage& msg) {
    const std::size_t size = msg.ByteSizeLong();
    if (out.size() < size) out.resize(size);
    msg.SerializeWithCachedSizesToArray(out.data());
    try {
      bool ok = s.send(frames[0], zmq::send_flags::sndmore | zmq::send_flags::dontwait).has_value();
      if (ok && payload == 2)
        ok = s.send(zmq::const_buffer(nullptr, 0),
                    zmq::send_flags::sndmore | zmq::send_flags::dontwait)
                 .has_value();
      if (ok)
        ok = s.send(zmq::const_buffer(out.data(), size), zmq::send_flags::dontwait).has_value();
      if (&s == &probe) ok ? ++stats.replies_sent : ++stats.replies_dropped;
    } catch (const zmq::error_t&) {
      ++stats.replies_dropped;  // EHOSTUNREACH and kin: the client is gone
    }
  }

  void count_error(const DecodeError& err, const char* socket) {
    const int code = static_cast<int>(err.kind);
    ++stats.errors;
    ++stats.errors_by_code[code];
    const Clock t = now_ns();
    if (error_logged_at[code] != 0 && t - error_logged_at[code] < kErrorLogPeriodNs) {
      ++error_suppressed[code];
      return;
    }
    spdlog::warn("{} socket: {} message ({}){}", socket, error_kind_name(err.kind), err.message,
                 error_suppressed[code]
                     ? fmt::format("; {} more since the last report", error_suppressed[code])
                     : "");
    error_logged_at[code] = t;
    error_suppressed[code] = 0;
  }

  void reply_error(zmq::socket_t& s, int payload, const DecodeError& err, const char* name) {
    count_error(err, name);
    if (payload < 0) return;  // no usable route
    encode_error(err, &error_msg);
    send_reply(s, payload, error_msg);
  }

  // Receives and answers the waiting probe updates, at most kDrainBudget of them.
  void drain_probes() {
    int n = 0;
    for (int budget = kDrainBudget; budget > 0 && recv_multipart(probe, &n); --budget) {
      const Clock recv = now_ns();
      const int p = payload_index(n);
      DecodeError err;
      ProbeInput in;
      if (p < 0) {
        err = {ErrorKind::kMalformed, "expected [identity][payload] frames", 0};
        reply_error(probe, n >= 2 && n <= kMaxFrames ? 1 : -1, err, "probe");
        continue;
      }
      auto* msg = google::protobuf::Arena::CreateMessage<v1::ClientMessage>(arena.get());
      const bool ok =
          parse_client(frames[p].data(), frames[p].size(), opt.max_message_bytes, msg, &err) &&
          decode_probe(*msg, limits, &in, &err);
      arena->Reset();
      if (!ok) {
        reply_error(probe, p, err, "probe");
        continue;
      }
      ++stats.probes_received;
      ProbeState& ps = state.probes[in.probe_id];
      if (in.radius > 0) ps.radius = in.radius;
      set_probe(state, in.probe_id, in.position, true);
      probe_contact(*model, state, in.probe_id, in.position, ps.radius, &ps);
      encode_force(in, ps, state.tick, recv, now_ns(), &force_msg);
      send_reply(probe, p, force_msg);
    }
  }

  void drain_control() {
    int n = 0;
    for (int budget = kDrainBudget; budget > 0 && recv_multipart(control, &n); --budget) {
      const int p = payload_index(n);
      DecodeError err;
      if (p < 0) {
        err = {ErrorKind::kMalformed, "expected [identity][payload] frames", 0};
        reply_error(control, n >= 2 && n <= kMaxFrames ? 1 : -1, err, "control");
        continue;
      }
      auto* msg = google::protobuf::Arena::CreateMessage<v1::ClientMessage>(arena.get());
      const v1::ControlRequest* req = nullptr;
      if (!parse_client(frames[p].data(), frames[p].size(), opt.max_message_bytes, msg, &err) ||
          !decode_control(*msg, &req, &err)) {
        arena->Reset();
        reply_error(control, p, err, "control");
        continue;
      }
      control_msg.set_protocol_version(kProtocolVersion);
      v1::ControlReply* reply = control_msg.mutable_control_reply();
      reply->Clear();  // the control path may allocate
      reply->set_sequence(req->sequence());
      handle_control(*req, reply);
      arena->Reset();
      refresh_stats();
      encode_stats(stats, state.counters, reply->mutable_stats());
      reply->set_num_nodes(static_cast<std::uint32_t>(model->num_nodes()));
      send_reply(control, p, control_msg);
    }
  }

  void handle_control(const v1::ControlRequest& req, v1::ControlReply* reply) {
    using K = v1::ControlRequest;
    reply->set_ok(true);
    switch (req.kind()) {
      case K::LOAD_SCENE: {
        if (!opt.scene_loader) {
          reply->set_ok(false);
          reply->set_message("this server cannot load scene files");
          return;
        }
        BodySpec spec;
        std::string e = opt.scene_loader(req.text(), &spec);
        std::unique_ptr<Model> m;
        double cost = 0;
        if (e.empty()) e = srv.prepare(spec, &m, &cost);
        if (!e.empty()) {
          spdlog::warn("LOAD_SCENE {} refused: {}", req.text(), e);
          reply->set_ok(false);
          reply->set_message(e);
          return;
        }
        srv.model_ = std::move(m);
        srv.measured_step_us_ = cost;
        use_model(srv.model_.get());
        spdlog::info("loaded scene {}: {} nodes, {} springs, step {:.1f} us", req.text(),
                     model->num_nodes(), model->num_springs(), cost);
        reply->set_message(
            fmt::format("loaded {} nodes, step {:.1f} us", model->num_nodes(), cost));
        return;
      }
      case K::RESET:
        use_model(model);
        reply->set_message("reset to the rest state");
        return;
      case K::PAUSE:
        paused = true;
        reply->set_message("paused");
        return;
      case K::RESUME:
        paused = false;
        reply->set_message("running");
        return;
      case K::SET_PARAMETER: {
        const double v = req.value();
        // The model is immutable during a step; between ticks the server owns it.
        Model& m = *srv.model_;
        bool ok = std::isfinite(v);
        if (ok && req.name() == "damping" && v >= 0)
          m.options.mass_damping = v;
        else if (ok && req.name() == "gravity_x")
          m.options.gravity.x() = v;
        else if (ok && req.name() == "gravity_y")
          m.options.gravity.y() = v;
        else if (ok && req.name() == "gravity_z")
          m.options.gravity.z() = v;
        else if (ok && req.name() == "positions_hz" && v >= 0)
          set_positions_rate(v);
        else
          ok = false;
        reply->set_ok(ok);
        reply->set_message(ok ? req.name() + " set"
                              : "unknown parameter or bad value (damping >= 0 1/s, gravity_x|y|z "
                                "m/s^2, positions_hz >= 0)");
        return;
      }
      case K::GET_STATS:
        return;
      case K::GET_MESH:
        encode_mesh(*model, reply);
        return;
      default:
        reply->set_ok(false);
        reply->set_message("unknown control kind");
    }
  }

  void set_positions_rate(double hz) {
    positions_every = hz > 0 ? std::max<std::uint64_t>(1, std::llround(opt.rate_hz / hz)) : 0;
  }

  // ---- loop -------------------------------------------------------------------------------

  bool readable(zmq::socket_t& s) { return (s.get(zmq::sockopt::events) & ZMQ_POLLIN) != 0; }

  // Busy poll: after a probe is answered (and after a tick when no probe came for a period) the
  // loop rests in ppoll for (1 - busy_poll_fraction) of a period before spinning again. A client
  // at the loop's rate sends its next probe about a period later, so it usually finds the loop
  // spinning, while the thread still sleeps part of every period.
  void rest_after(Clock t) { rest_until_ns = t + rest_ns; }

  // Serves probes and control until the absolute deadline.
  void wait_until(Clock deadline) {
    for (;;) {
      const std::uint64_t seen = stats.probes_received;
      drain_probes();
      drain_control();
      if (srv.stop_.load(std::memory_order_relaxed)) return;
      const Clock t = now_ns();
      if (stats.probes_received != seen) {
        last_probe_ns = t;
        rest_after(t);
      }
      if (t >= deadline) return;
      if (opt.busy_poll && t >= rest_until_ns) {
        // ZMQ_EVENTS processes the I/O thread's commands, so a message that arrived is seen
        // here without any file-descriptor wake-up.
        if (!readable(probe) && !readable(control)) cpu_relax();
        continue;
      }
      if (deadline - t <= kFinalSleepNs) {
        sleep_until(deadline);
        return;
      }
      // ZMQ_FD is edge-triggered: it fires when ZMQ_EVENTS may have changed. After draining to
      // EAGAIN, check the events once more before sleeping on it.
      if (readable(probe) || readable(control)) continue;
      pollfd fds[2] = {{probe_fd, POLLIN, 0}, {control_fd, POLLIN, 0}};
      Clock wake = deadline - kFinalSleepNs;
      if (opt.busy_poll) wake = std::min(wake, rest_until_ns);  // then spin again
      const timespec timeout = to_timespec(wake - t);
      const int r = ppoll(fds, 2, &timeout, nullptr);
      if (r < 0 && errno != EINTR) sleep_until(deadline);  // cannot poll: keep the rate anyway
    }
  }

  void publish_state(bool positions) {
    encode_state(*model, state, positions, stats, &state_msg);
    const std::size_t size = state_msg.ByteSizeLong();
    if (out.size() < size) out.resize(size);
    state_msg.SerializeWithCachedSizesToArray(out.data());
    const char topic = positions ? 'S' : 'F';
    try {
      // PUB never blocks: at the high-water mark a subscriber's frames are dropped.
      if (pub.send(zmq::const_buffer(&topic, 1),
                   zmq::send_flags::sndmore | zmq::send_flags::dontwait))
        (void)pub.send(zmq::const_buffer(out.data(), size), zmq::send_flags::dontwait);
    } catch (const zmq::error_t&) {
    }
  }

  void refresh_stats() {
    const auto l = lateness.summary(), i = input.summary(), s = stepping.summary(),
               p = publish.summary();
    stats.lateness_p50_us = l.p50;
    stats.lateness_p99_us = l.p99;
    stats.lateness_max_us = l.max;
    stats.step_p50_us = s.p50;
    stats.step_p99_us = s.p99;
    stats.step_max_us = s.max;
    stats.input_p50_us = i.p50;
    stats.input_p99_us = i.p99;
    stats.publish_p50_us = p.p50;
    stats.publish_p99_us = p.p99;
    stats.paused = paused;
    stats.window = static_cast<std::uint32_t>(lateness.size());
    std::lock_guard lock(srv.mutex_);
    srv.stats_ = stats;
  }

  void log_stats(Clock t) {
    if (opt.log_period_s <= 0 || t < next_log_ns) return;
    next_log_ns = t + static_cast<Clock>(opt.log_period_s * 1e9);
    const Counters& c = state.counters;
    spdlog::info(
        "loop: {} ticks, {} missed; lateness p50/p99/max {:.0f}/{:.0f}/{:.0f} us; step p50/p99 "
        "{:.0f}/{:.0f} us; input p99 {:.0f} us; publish p99 {:.0f} us; probes {}, errors {}, "
        "rollbacks {}",
        stats.ticks, stats.missed_ticks, stats.lateness_p50_us, stats.lateness_p99_us,
        stats.lateness_max_us, stats.step_p50_us, stats.step_p99_us, stats.input_p99_us,
        stats.publish_p99_us, stats.probes_received, stats.errors, c.rollbacks);
  }

  void run() {
    try_realtime();
    stats.rate_hz = opt.rate_hz;
    period_ns = static_cast<Clock>(std::llround(1e9 / opt.rate_hz));
    rest_ns = static_cast<Clock>((1.0 - opt.busy_poll_fraction) * static_cast<double>(period_ns));
    set_positions_rate(opt.positions_hz);
    Clock next = now_ns() + period_ns;
    next_log_ns = now_ns() + static_cast<Clock>(opt.log_period_s * 1e9);
    while (!srv.stop_.load(std::memory_order_relaxed)) {
      wait_until(next);
      if (srv.stop_.load(std::memory_order_relaxed)) break;
      const Clock wake = now_ns();
      lateness.add(wake > next ? (wake - next) * 1e-3 : 0.0);

      const std::uint64_t seen = stats.probes_received;
      drain_probes();  // input: whatever arrived during the last stretch
      drain_control();
      const Clock t_in = now_ns();
      if (stats.probes_received != seen) last_probe_ns = t_in;
      if (!paused) step(*model, state, *ws);
      const Clock t_step = now_ns();
      ++stats.ticks;
      publish_state(false);
      if (positions_every && stats.ticks % positions_every == 0) publish_state(true);
      const Clock t_pub = now_ns();
      if (opt.busy_poll && (t_pub - last_probe_ns > period_ns || last_probe_ns >= t_in))
        rest_after(t_pub);  // no client at the rate, or one just answered: rest first
      input.add((t_in - wake) * 1e-3);
      stepping.add((t_step - t_in) * 1e-3);
      publish.add((t_pub - t_step) * 1e-3);
      // Percentiles a few times per second (and early on, so the first frames carry some).
      if (stats.ticks % kStatsEveryTicks == 0 ||
          (stats.ticks < kStatsEveryTicks && (stats.ticks & (stats.ticks - 1)) == 0)) {
        refresh_stats();
        log_stats(t_pub);
      }

      // Next absolute deadline. Late by less than a period: run it at once (lateness counts it);
      // later than that: skip the deadlines that are gone, count them, keep dt.
      next += period_ns;
      const Clock t = now_ns();
      if (t > next + period_ns) {
        const std::uint64_t missed = (t - next) / period_ns;
        next += missed * period_ns;
        stats.missed_ticks += missed;
      }
    }
    refresh_stats();
  }
};

Server::Server(zmq::context_t& context, ServerOptions options)
    : context_(context), options_(std::move(options)) {}

Server::~Server() { stop(); }

const Model& Server::model() const { return *model_; }

Endpoints Server::endpoints() const {
  std::lock_guard lock(mutex_);
  return endpoints_;
}

LoopStatsData Server::stats() const {
  std::lock_guard lock(mutex_);
  return stats_;
}

std::string Server::prepare(const BodySpec& spec, std::unique_ptr<Model>* out,
                            double* step_us) const {
  auto m = std::make_unique<Model>();
  if (std::string e = build_model(spec, m.get()); !e.empty()) return e;
  const double period_s = 1.0 / options_.rate_hz;
  if (std::abs(m->options.dt - period_s) > 1e-9 * period_s)
    spdlog::warn("scene dt {} s differs from the loop period {} s: simulated time runs at {:.2f}x",
                 m->options.dt, period_s, m->options.dt / period_s);
  if (m->probes.empty()) spdlog::warn("scene has no probe: every probe update will be refused");
  // Step cost on a copy of the rest state, 50 steps.
  State s = make_state(*m);
  Workspace ws(*m);
  std::vector<double> cost;
  for (int k = 0; k < 50; ++k) {
    const Clock t0 = now_ns();
    step(*m, s, ws);
    cost.push_back((now_ns() - t0) * 1e-3);
  }
  std::nth_element(cost.begin(), cost.begin() + 25, cost.end());
  const double median = cost[25];
  if (m->options.active_region) {
    if (m->options.integrator == Integrator::kImplicitEuler)
      spdlog::warn("active region ignored: the implicit integrator steps every node");
    else if (ws.far_every > 0)
      spdlog::info("active region: tolerance {} m; far field one step every {} ticks (measured "
                   "stability bound {}, far inertia x {:.3f}); the step below is measured at rest",
                   m->options.active_tolerance, ws.far_every, ws.measured_every, ws.far_raise);
    else
      spdlog::info("active region: tolerance {} m; far field frozen", m->options.active_tolerance);
  }
  const double period_us = 1e6 * period_s;
  *step_us = median;
  if (median > period_us && options_.refuse_slow_scene)
    return fmt::format(
        "the step costs {:.0f} us (median of 50), more than the {:.0f} us period "
        "at {} Hz: lower the rate or simplify the scene",
        median, period_us, options_.rate_hz);
  if (median > 0.5 * period_us)
    spdlog::warn("the step costs {:.0f} us of the {:.0f} us period: ticks may be missed", median,
                 period_us);
  *out = std::move(m);
  return {};
}

std::string Server::load(const BodySpec& spec) {
  if (running()) return "load() while running: use LOAD_SCENE";
  std::unique_ptr<Model> m;
  double cost = 0;
  if (std::string e = prepare(spec, &m, &cost); !e.empty()) return e;
  model_ = std::move(m);
  measured_step_us_ = cost;
  spdlog::info("scene: {} nodes, {} springs, {} probes; step {:.1f} us (median of 50)",
               model_->num_nodes(), model_->num_springs(), model_->probes.size(), cost);
  return {};
}

std::string Server::start() {
  if (running()) return "already running";
  if (!model_) return "no scene loaded";
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
    Loop loop(*this);
    loop.use_model(model_.get());
    std::string e = loop.bind_all();
    const bool ok = e.empty();
    if (!ok) loop.close_all();
    bound.set_value(std::move(e));  // `bound` is not touched after this
    if (!ok) return;
    loop.run();
    loop.close_all();  // sockets before the caller's context, linger 0
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
