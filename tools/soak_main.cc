// conica-soak: the server under churn for a long time. An in-process server at --rate-hz on
// loopback ports picked by the OS; --clients threads each loop: connect, a seeded random number
// of probe round trips along a moving path, now and then a malformed message (garbage, wrong
// version, NaN, unknown probe, wrong type) that must be answered with an error, now and then a
// control GET_STATS, disconnect. A subscriber reads state frames. Prints missed ticks, errors by
// kind and resident memory (VmRSS), and ends with
//   missed_ticks=A ticks=B errors=C rss_start_kib=D rss_end_kib=E
// errors counts what should not happen: unanswered requests, wrong replies, server-side errors
// beyond the malformed messages sent on purpose. rss_start is taken after a warm-up (the first
// 10 % of the run, at most 30 s) so that allocator and socket buffers have reached their size.
// Exit status 1 when errors > 0, missed ticks exceed --max-missed-fraction of the ticks, or
// memory grew by more than --max-rss-growth-kib.
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <optional>
#include <random>
#include <string>
#include <thread>
#include <vector>
#include <zmq.hpp>

#include "net/builtin_scenes.h"
#include "net/server.h"

namespace {

using Clock = std::chrono::steady_clock;
using conica::Vec3;
namespace v1 = conica::v1;

long rss_kib() {
  std::ifstream f("/proc/self/status");
  std::string key;
  long value = -1;
  while (f >> key) {
    if (key == "VmRSS:") {
      f >> value;
      return value;
    }
    f.ignore(std::numeric_limits<std::streamsize>::max(), '\n');
  }
  return value;
}

struct Tally {
  std::atomic<std::uint64_t> sessions{0}, probes{0}, replies{0}, malformed_sent{0},
      malformed_answered{0}, controls{0}, timeouts{0}, wrong_replies{0};
};

std::string probe_bytes(std::uint64_t seq, const Vec3& c, std::uint32_t probe_id = 0) {
  v1::ClientMessage m;
  m.set_protocol_version(1);
  auto* p = m.mutable_probe();
  p->set_client_id(7);
  p->set_probe_id(probe_id);
  p->set_sequence(seq);
  p->mutable_position()->set_x(c.x());
  p->mutable_position()->set_y(c.y());
  p->mutable_position()->set_z(c.z());
  return m.SerializeAsString();
}

std::optional<v1::ServerMessage> recv_one(zmq::socket_t& s, int timeout_ms) {
  zmq::pollitem_t item{s.handle(), 0, ZMQ_POLLIN, 0};
  if (zmq::poll(&item, 1, std::chrono::milliseconds(timeout_ms)) == 0) return std::nullopt;
  zmq::message_t msg;
  if (!s.recv(msg, zmq::recv_flags::dontwait)) return std::nullopt;
  v1::ServerMessage out;
  if (!out.ParseFromArray(msg.data(), static_cast<int>(msg.size()))) return v1::ServerMessage{};
  return out;
}

// One client thread: sessions until `end`.
void churn(zmq::context_t& ctx, const conica::net::Endpoints& ep, Vec3 lo, Vec3 hi, int id,
           Clock::time_point end, Tally& t) {
  std::mt19937_64 rng(1234 + id);
  std::uniform_real_distribution<double> u(0, 1);
  std::uint64_t seq = 0;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  while (Clock::now() < end) {
    ++t.sessions;
    zmq::socket_t s(ctx, zmq::socket_type::dealer);
    s.set(zmq::sockopt::linger, 0);
    s.connect(ep.probe);
    const int n = 1 + static_cast<int>(u(rng) * 50);
    const Vec3 c0 = lo + (hi - lo).cwiseProduct(Vec3(u(rng), u(rng), 1.0));
    for (int k = 0; k < n && Clock::now() < end; ++k) {
      ++seq;
      const int kind = static_cast<int>(u(rng) * 20);  // 1 in 20: malformed
      std::string bytes;
      bool bad = true;
      switch (kind) {
        case 0: {
          const int r = static_cast<int>(u(rng) * 5);
          if (r == 0) bytes = std::string("\xff\x01garbage", 9);
          if (r == 1) {
            v1::ClientMessage m;
            m.ParseFromString(probe_bytes(seq, c0));
            m.set_protocol_version(99);
            bytes = m.SerializeAsString();
          }
          if (r == 2) bytes = probe_bytes(seq, Vec3(nan, 0, 0));
          if (r == 3) bytes = probe_bytes(seq, c0, 5);
          if (r == 4) {
            v1::ClientMessage m;
            m.set_protocol_version(1);
            m.mutable_control()->set_kind(v1::ControlRequest::GET_STATS);
            bytes = m.SerializeAsString();
          }
          break;
        }
        default: {
          // Down into the body and back along a slow sine, 2 mm deep at most.
          const double depth = 2e-3 * std::sin(0.3 * static_cast<double>(k));
          bytes = probe_bytes(seq, c0 + Vec3(0, 0, 5e-3 - depth));
          bad = false;
        }
      }
      if (!s.send(zmq::buffer(bytes), zmq::send_flags::dontwait)) {
        ++t.timeouts;
        continue;
      }
      bad ? ++t.malformed_sent : ++t.probes;
      auto r = recv_one(s, 1000);
      if (!r) {
        ++t.timeouts;
        break;  // this connection is suspect: start a new session
      }
      if (bad && r->body_case() == v1::ServerMessage::kError)
        ++t.malformed_answered;
      else if (!bad && r->body_case() == v1::ServerMessage::kForce && r->force().sequence() == seq)
        ++t.replies;
      else
        ++t.wrong_replies;
    }
    if (u(rng) < 0.1) {  // now and then the control socket
      zmq::socket_t c(ctx, zmq::socket_type::dealer);
      c.set(zmq::sockopt::linger, 0);
      c.connect(ep.control);
      v1::ClientMessage m;
      m.set_protocol_version(1);
      m.mutable_control()->set_kind(v1::ControlRequest::GET_STATS);
      m.mutable_control()->set_sequence(++seq);
      c.send(zmq::buffer(m.SerializeAsString()), zmq::send_flags::none);
      auto r = recv_one(c, 1000);
      if (!r) ++t.timeouts;
      else if (r->body_case() != v1::ServerMessage::kControlReply) ++t.wrong_replies;
      else ++t.controls;
    }
    std::this_thread::sleep_for(std::chrono::microseconds(static_cast<int>(u(rng) * 2000)));
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"conica-soak: the server under client churn; no crash, few missed ticks, flat memory"};
  double seconds = 60, rate_hz = 1000, max_missed = 0.001;
  int clients = 4;
  long max_growth_kib = 1024;
  std::string builtin = "cube";
  bool realtime = false;
  app.add_option("--seconds", seconds, "run time, s")->check(CLI::Range(1.0, 1e6));
  app.add_option("--clients", clients, "churning client threads")->check(CLI::Range(1, 256));
  app.add_option("--rate-hz", rate_hz, "server loop rate, Hz")->check(CLI::Range(1.0, 20000.0));
  app.add_option("--builtin", builtin, "built-in scene")
      ->check(CLI::IsMember(conica::net::builtin_scene_names()));
  app.add_option("--max-missed-fraction", max_missed, "goal: missed ticks / ticks (default 0.001)");
  app.add_option("--max-rss-growth-kib", max_growth_kib, "goal: VmRSS growth, KiB (default 1024)");
  app.add_flag("--realtime", realtime, "let the loop try SCHED_FIFO and mlockall");
  CLI11_PARSE(app, argc, argv);
  spdlog::set_level(spdlog::level::warn);

  const long rss_launch = rss_kib();
  zmq::context_t ctx(2);
  conica::net::ServerOptions opt;
  opt.probe_endpoint = opt.state_endpoint = opt.control_endpoint = "tcp://127.0.0.1:*";
  opt.rate_hz = rate_hz;
  opt.log_period_s = 0;
  opt.realtime = realtime;
  opt.refuse_slow_scene = false;
  conica::net::Server server(ctx, opt);
  conica::BodySpec spec;
  std::string err = conica::net::builtin_scene(builtin, 1.0 / rate_hz, &spec);
  if (err.empty()) err = server.load(spec);
  if (err.empty()) err = server.start();
  if (!err.empty()) {
    std::fprintf(stderr, "conica-soak: %s\n", err.c_str());
    return 2;
  }
  const conica::net::Endpoints ep = server.endpoints();
  conica::net::ProbeLimits lim;
  conica::net::body_box(server.model(), 0, &lim);
  const Vec3 lo = lim.box_min, hi = lim.box_max;

  const auto t0 = Clock::now();
  const auto end = t0 + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
  const auto warm = t0 + std::chrono::duration_cast<Clock::duration>(
                             std::chrono::duration<double>(std::min(30.0, 0.1 * seconds)));
  Tally tally;
  std::vector<std::thread> threads;
  for (int k = 0; k < clients; ++k)
    threads.emplace_back([&, k] { churn(ctx, ep, lo, hi, k, end, tally); });
  std::atomic<std::uint64_t> frames{0};
  threads.emplace_back([&] {
    zmq::socket_t sub(ctx, zmq::socket_type::sub);
    sub.set(zmq::sockopt::linger, 0);
    sub.set(zmq::sockopt::subscribe, "");
    sub.connect(ep.state);
    zmq::message_t m;
    while (Clock::now() < end) {
      zmq::pollitem_t item{sub.handle(), 0, ZMQ_POLLIN, 0};
      if (zmq::poll(&item, 1, std::chrono::milliseconds(100)) > 0)
        while (sub.recv(m, zmq::recv_flags::dontwait))
          if (!m.more()) ++frames;
    }
  });

  std::this_thread::sleep_until(warm);
  const long rss_start = rss_kib();
  const conica::net::LoopStatsData s_start = server.stats();
  // Progress every 60 s.
  for (auto next = t0 + std::chrono::seconds(60); next < end; next += std::chrono::seconds(60)) {
    std::this_thread::sleep_until(next);
    const auto s = server.stats();
    std::printf("t=%.0f s ticks=%" PRIu64 " missed=%" PRIu64 " sessions=%" PRIu64 " rss_kib=%ld\n",
                std::chrono::duration<double>(Clock::now() - t0).count(), s.ticks, s.missed_ticks,
                tally.sessions.load(), rss_kib());
    std::fflush(stdout);
  }
  for (auto& th : threads) th.join();
  const long rss_end = rss_kib();
  server.stop();
  const conica::net::LoopStatsData s = server.stats();

  std::printf("clients %d, %.0f s at %.0f Hz (%s): %" PRIu64 " sessions, %" PRIu64
              " probes, %" PRIu64 " replies, %" PRIu64 " control requests, %" PRIu64
              " state frames\n",
              clients, seconds, rate_hz, builtin.c_str(), tally.sessions.load(),
              tally.probes.load(), tally.replies.load(), tally.controls.load(), frames.load());
  std::printf("malformed sent %" PRIu64 ", answered with an error %" PRIu64 "\n",
              tally.malformed_sent.load(), tally.malformed_answered.load());
  std::printf("server errors by kind:");
  for (int c = 1; c < conica::net::kNumErrorCodes; ++c)
    std::printf(" %s=%" PRIu64, conica::net::error_kind_name(static_cast<conica::net::ErrorKind>(c)),
                s.errors_by_code[c]);
  std::printf("\nserver: probes %" PRIu64 ", replies sent %" PRIu64 ", dropped %" PRIu64
              "; lateness p50/p99/max %.0f/%.0f/%.0f us; step p99 %.0f us\n",
              s.probes_received, s.replies_sent, s.replies_dropped, s.lateness_p50_us,
              s.lateness_p99_us, s.lateness_max_us, s.step_p99_us);
  const std::uint64_t server_unexpected =
      s.errors > tally.malformed_sent.load() ? s.errors - tally.malformed_sent.load() : 0;
  const std::uint64_t errors = tally.timeouts + tally.wrong_replies +
                               (tally.malformed_sent - tally.malformed_answered) + server_unexpected;
  std::printf("errors: timeouts=%" PRIu64 " wrong_replies=%" PRIu64 " unanswered_malformed=%" PRIu64
              " server_unexpected=%" PRIu64 "\n",
              tally.timeouts.load(), tally.wrong_replies.load(),
              tally.malformed_sent.load() - tally.malformed_answered.load(), server_unexpected);
  std::printf("rss: launch %ld KiB, after warm-up %ld KiB (tick %" PRIu64 "), end %ld KiB\n",
              rss_launch, rss_start, s_start.ticks, rss_end);
  std::printf("missed_ticks=%" PRIu64 " ticks=%" PRIu64 " errors=%" PRIu64
              " rss_start_kib=%ld rss_end_kib=%ld\n",
              s.missed_ticks, s.ticks, errors, rss_start, rss_end);
  const bool ok = errors == 0 &&
                  static_cast<double>(s.missed_ticks) <= max_missed * static_cast<double>(s.ticks) &&
                  rss_end - rss_start <= max_growth_kib;
  return ok ? 0 : 1;
}
