// conica-latency: open-loop probe updates at a fixed rate, round trips measured from each
// update's *scheduled* send time (no coordinated omission), replies matched by echoed sequence.
//
// Schedule: request i is due at t0 + i / rate (absolute CLOCK_MONOTONIC deadlines). Between
// sends the socket is polled (ppoll on ZMQ_FD) and replies are timestamped as they are read; the
// last 50 us before a deadline are slept with clock_nanosleep(TIMER_ABSTIME). A late wake-up
// delays the send, never the schedule: the request still counts from its due time.
// Low-latency options: --spin-us N busy-waits (polling the socket) through the last N us before
// each send instead of sleeping; --busy-poll-us N keeps polling the socket without sleeping
// for up to N us after each send or until its reply is in (never past the next send's spin or
// sleep); --io-threads sets the ZeroMQ I/O threads; --realtime runs this thread and the I/O
// threads SCHED_FIFO (when allowed). Timer slack is always 1 ns.
// After the last send, replies are awaited for --drain seconds; the rest are lost.
// The server's loop statistics (tick lateness, missed ticks) come from control GET_STATS.
#include <pthread.h>
#include <sched.h>
#include <sys/prctl.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <string>
#include <thread>

#include "client/connection.h"
#include "common/latency_stats.h"
#include "net/io_threads.h"

using namespace conica::client;

int main(int argc, char** argv) {
  CLI::App app{"conica-latency: open-loop probe round-trip latency against conica-server"};
  std::string endpoint = "tcp://127.0.0.1:5555", control = "tcp://127.0.0.1:5557";
  std::string position = "0.02,0.02,0.042", csv, plot, label;
  std::string plot_script = std::string(CONICA_SOURCE_DIR) + "/scripts/plot_latency.py";
  double rate_hz = 1000, seconds = 10, drain_s = 0.5, radius = 0;
  int probe = 0;
  std::uint32_t client_id = 7;
  std::string curve_server_pub, curve_key;
  double spin_us = 0, busy_poll_us = 0;
  int io_threads = 1;
  bool realtime = false;
  app.add_option("--endpoint", endpoint, "probe ROUTER of the server");
  app.add_option("--control-endpoint", control, "control ROUTER of the server ('' to skip stats)");
  app.add_option("--rate-hz", rate_hz, "updates per second")->check(CLI::Range(1.0, 100000.0));
  app.add_option("--seconds", seconds, "duration of the run, s")->check(CLI::Range(0.01, 3600.0));
  app.add_option("--position", position, "m, probe centre x,y,z for every update");
  app.add_option("--probe", probe, "probe index");
  app.add_option("--radius", radius, "m, probe radius (0: the scene's)");
  app.add_option("--drain", drain_s, "s to wait for replies after the last send");
  app.add_option("--client-id", client_id, "client id sent with every update");
  app.add_option("--csv", csv, "write samples: seq,scheduled_us,latency_us (-1: lost)");
  app.add_option("--label", label, "name of this run in the CSV and plots (e.g. the scene)");
  app.add_option("--plot", plot, "PNG: latency CDF (needs --csv; /usr/bin/python3 + matplotlib)");
  app.add_option("--plot-script", plot_script, "plotting script");
  app.add_option("--spin-us", spin_us,
                 "us before each send spent spinning on the socket instead of sleeping")
      ->check(CLI::Range(0.0, 1e6));
  app.add_option("--busy-poll-us", busy_poll_us,
                 "us after each send spent polling for its reply without sleeping")
      ->check(CLI::Range(0.0, 1e6));
  app.add_option("--io-threads", io_threads, "ZeroMQ I/O threads")->check(CLI::Range(1, 16));
  app.add_flag("--realtime", realtime,
               "SCHED_FIFO (priority 70) for this thread and the ZeroMQ I/O threads");
  app.add_option("--curve-server-pub", curve_server_pub,
                 "CURVE: the server's public certificate (its NAME.key, not NAME.key_secret)");
  app.add_option("--curve-key", curve_key,
                 "CURVE: this client's secret certificate NAME.key_secret (the server lists "
                 "its NAME.key)");
  CLI11_PARSE(app, argc, argv);

  const auto pos = parse_vec3(position);
  if (!pos) {
    std::cerr << "conica-latency: --position must be x,y,z in metres\n";
    return 1;
  }
  if (!plot.empty() && csv.empty()) {
    std::cerr << "conica-latency: --plot needs --csv\n";
    return 1;
  }
  CurveClient curve;
  if (std::string e = load_curve_client(curve_server_pub, curve_key, &curve); !e.empty()) {
    std::cerr << "conica-latency: " << e << "\n";
    return 1;
  }
  prctl(PR_SET_TIMERSLACK, 1UL, 0, 0, 0);  // precise wake-ups (field notes: default slack 50 us)

  zmq::context_t context(io_threads);
  if (realtime) {
    constexpr int kPriority = 70;
    if (conica::net::set_io_threads_fifo(context, kPriority)) {
      sched_param sp{};
      sp.sched_priority = kPriority;
      pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
    } else {
      std::cerr << "conica-latency: SCHED_FIFO refused; running at normal priority\n";
    }
  }
  conica::v1::ControlReply before, after;
  std::string error;
  const bool have_stats =
      !control.empty() && control_request(context, control, conica::v1::ControlRequest::GET_STATS,
                                          1000, &before, &error, curve);
  if (!control.empty() && !have_stats)
    std::cerr << "conica-latency: no server statistics: " << error << "\n";

  ProbeConnection conn(context, endpoint, client_id, curve);
  const auto n = static_cast<std::size_t>(rate_hz * seconds + 0.5);
  const std::int64_t period_ns = static_cast<std::int64_t>(1e9 / rate_hz + 0.5);
  LatencyRecorder rec(n);
  std::size_t errors = 0, send_failures = 0;
  std::int64_t worst_send_delay_ns = 0;
  std::string last_error;

  // Legs of each round trip (same host, same CLOCK_MONOTONIC): scheduled -> server receive,
  // server receive -> server reply, server reply -> client read.
  std::vector<double> to_server, in_server, to_client;
  to_server.reserve(n);
  in_server.reserve(n);
  to_client.reserve(n);
  ForceSample f;
  auto drain = [&](std::int64_t deadline_ns) {
    for (;;) {
      bool got = false;
      const ReplyKind k = conn.receive(deadline_ns, &f, &error, &got);
      if (!got) return;
      const std::int64_t t = now_ns();
      if (k == ReplyKind::kForce && f.client_id == client_id) {
        if (rec.on_reply(f.sequence, t) && f.server_recv_time_ns > 0) {
          const double sched = static_cast<double>(rec.scheduled_ns(f.sequence));
          to_server.push_back((static_cast<double>(f.server_recv_time_ns) - sched) * 1e-3);
          in_server.push_back((static_cast<double>(f.server_reply_time_ns) -
                               static_cast<double>(f.server_recv_time_ns)) *
                              1e-3);
          to_client.push_back(
              (static_cast<double>(t) - static_cast<double>(f.server_reply_time_ns)) * 1e-3);
        }
      } else if (k == ReplyKind::kError || k == ReplyKind::kMalformed) {
        ++errors;
        last_error = error;
      }
      deadline_ns = 0;  // after the first message only take what is already queued
    }
  };

  // Let the connection come up before the clock starts.
  const std::int64_t t0 = now_ns() + 100'000'000;
  // The last stretch before a send: slept (clock_nanosleep) or spun (--spin-us).
  const std::int64_t spin_ns = static_cast<std::int64_t>(spin_us * 1e3);
  const std::int64_t busy_ns = static_cast<std::int64_t>(busy_poll_us * 1e3);
  const std::int64_t guard_ns = std::max<std::int64_t>(50'000, spin_ns);
  for (std::size_t i = 0; i < n; ++i) {
    const std::int64_t due = t0 + static_cast<std::int64_t>(i) * period_ns;
    while (now_ns() < due - guard_ns) drain(due - guard_ns);
    drain(0);
    if (spin_ns > 0) {
      while (now_ns() < due) drain(0);
    } else {
      sleep_until_ns(due);
    }
    const std::int64_t late = now_ns() - due;
    if (late > worst_send_delay_ns) worst_send_delay_ns = late;
    rec.on_sent(i, due);
    if (!conn.send(static_cast<std::uint32_t>(probe), i, static_cast<std::uint64_t>(due), *pos,
                   radius))
      ++send_failures;
    drain(0);
    if (busy_ns > 0) {
      const std::int64_t until = std::min(now_ns() + busy_ns, due + period_ns - guard_ns);
      while (rec.received() < rec.sent() && now_ns() < until) drain(0);
    }
  }
  const std::int64_t end = now_ns() + static_cast<std::int64_t>(drain_s * 1e9);
  while (rec.received() < rec.sent() && now_ns() < end) drain(end);

  const bool have_after =
      have_stats && control_request(context, control, conica::v1::ControlRequest::GET_STATS, 1000,
                                    &after, &error, curve);

  const LatencySummary s = summarize(rec.latencies_us());
  std::printf("conica-latency: %s, %.0f Hz for %.1f s, probe %d at %s\n", endpoint.c_str(), rate_hz,
              seconds, probe, position.c_str());
  std::printf(
      "round trip from scheduled send (us): p50 %.1f  p90 %.1f  p99 %.1f  p99.9 %.1f  "
      "max %.1f  mean %.1f\n",
      s.p50, s.p90, s.p99, s.p999, s.max, s.mean);
  std::printf(
      "sent %zu, received %zu, lost %zu, duplicates %zu, unknown %zu, server errors %zu, "
      "send failures %zu, worst send delay %.1f us\n",
      rec.sent(), rec.received(), rec.lost(), rec.duplicates(), rec.unknown(), errors,
      send_failures, worst_send_delay_ns * 1e-3);
  if (!to_server.empty()) {
    const LatencySummary a = summarize(to_server), b = summarize(in_server),
                         c = summarize(to_client);
    std::printf(
        "legs p50 / p99 (us): scheduled -> server recv %.1f / %.1f, in server %.1f / %.1f, "
        "server reply -> client read %.1f / %.1f\n",
        a.p50, a.p99, b.p50, b.p99, c.p50, c.p99);
  }
  if (!last_error.empty()) std::printf("last server error: %s\n", last_error.c_str());
  std::uint32_t nodes = 0;
  if (have_after) {
    const auto& a = after.stats();
    const auto& b = before.stats();
    nodes = after.num_nodes();
    std::printf("%s\n", describe_stats(a).c_str());
    std::printf("  during this run: %llu ticks, %llu missed; scene nodes %u\n",
                static_cast<unsigned long long>(a.ticks() - b.ticks()),
                static_cast<unsigned long long>(a.missed_ticks() - b.missed_ticks()), nodes);
  }

  if (!csv.empty()) {
    std::ofstream out(csv);
    if (!out) {
      std::cerr << "conica-latency: cannot write " << csv << "\n";
      return 1;
    }
    out << "# conica-latency endpoint=" << endpoint << " rate_hz=" << rate_hz
        << " seconds=" << seconds << " num_nodes=" << nodes
        << " label=" << (label.empty() ? "run" : label) << " lost=" << rec.lost()
        << " sent=" << rec.sent() << "\n";
    out << "seq,scheduled_us,latency_us\n";
    char line[96];
    for (std::size_t i = 0; i < rec.sent(); ++i) {
      std::snprintf(line, sizeof line, "%zu,%.3f,%.3f\n", i, (rec.scheduled_ns(i) - t0) * 1e-3,
                    rec.latency_us(i));
      out << line;
    }
  }
  if (!plot.empty()) {
    const std::string cmd =
        "/usr/bin/python3 '" + plot_script + "' --out '" + plot + "' '" + csv + "'";
    if (std::system(cmd.c_str()) != 0)
      std::cerr << "conica-latency: plotting failed: " << cmd << "\n";
  }
  if (rec.received() == 0)
    std::fprintf(stderr, "conica-latency: no replies from %s; is conica-server running there?\n",
                 endpoint.c_str());
  std::printf("%s\n", summary_line(s, rec.lost(), rec.sent()).c_str());
  return rec.received() > 0 ? 0 : 2;
}
