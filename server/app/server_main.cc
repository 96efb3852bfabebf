// conica-server: the 1 kHz haptic simulation server (see server/net/server.h for the sockets).
//   conica-server                       built-in cube on the default loopback endpoints
//   conica-server --scene FILE          a scene file
//   conica-server --builtin liver --probe-endpoint tcp://127.0.0.1:6000 --seconds 10
//   conica-server --generate-keys keys --key-name server      keys/server.key (public
//                                       certificate), keys/server.key_secret (secret)
//   conica-server --curve-server-key keys/server.key_secret --curve-clients keys/clients
//                                       CURVE: encrypted, only clients with a NAME.key there
#include <pthread.h>
#include <sched.h>
#include <signal.h>
#include <spdlog/spdlog.h>
#include <time.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <string>
#include <thread>
#include <zmq.hpp>

#include "net/builtin_scenes.h"
#include "net/curve.h"
#include "net/io_threads.h"
#include "net/server.h"

#if defined(CONICA_HAVE_SCENE)
#include "io/scene.h"
#endif

namespace {

std::string load_scene_file(const std::string& path, conica::BodySpec* spec) {
#if defined(CONICA_HAVE_SCENE)
  return conica::io::load_scene(path, spec);
#else
  (void)spec;
  return "scene files are not supported by this build (" + path + ")";
#endif
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"conica-server: real-time haptic soft-tissue simulation over ZeroMQ and protobuf"};
  std::string scene, builtin, log_level = "info";
  conica::net::ServerOptions opt;
  double seconds = 0;
  bool no_realtime = false;
  app.add_option("--scene", scene, "scene file")->check(CLI::ExistingFile);
  app.add_option("--builtin", builtin, "built-in scene: cube, block, liver (default: cube)")
      ->check(CLI::IsMember(conica::net::builtin_scene_names()));
  app.add_option("--rate-hz", opt.rate_hz, "loop rate, Hz")->check(CLI::Range(1.0, 20000.0));
  app.add_option("--probe-endpoint", opt.probe_endpoint, "ROUTER for probe updates");
  app.add_option("--state-endpoint", opt.state_endpoint, "PUB for state frames");
  app.add_option("--control-endpoint", opt.control_endpoint, "ROUTER for control requests");
  app.add_option("--positions-hz", opt.positions_hz,
                 "rate of frames with node positions, Hz (0: never)")
      ->check(CLI::Range(0.0, 20000.0));
  app.add_option("--seconds", seconds, "run for this long, then exit (0: until SIGINT/SIGTERM)")
      ->check(CLI::Range(0.0, 1e9));
  app.add_option("--stats-seconds", opt.log_period_s, "log loop statistics this often (0: never)")
      ->check(CLI::Range(0.0, 1e6));
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error, off")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error", "critical", "off"}));
  app.add_flag("--no-realtime", no_realtime, "do not try SCHED_FIFO and mlockall");
  app.add_flag(
      "--busy-poll", opt.busy_poll,
      "spin on the sockets between ticks instead of sleeping (lower latency, a whole core)");
  app.add_option(
         "--busy-poll-fraction", opt.busy_poll_fraction,
         "with --busy-poll: after each answered probe rest in ppoll for (1 - F) of a period, "
         "then spin (F <= 0.9 keeps a SCHED_FIFO loop under real-time throttling)")
      ->check(CLI::Range(0.0, 1.0));
  int io_threads = 1;
  app.add_option("--io-threads", io_threads, "ZeroMQ I/O threads")->check(CLI::Range(1, 16));
  bool realtime_io = false;
  app.add_flag("--realtime-io", realtime_io,
               "run the ZeroMQ I/O threads SCHED_FIFO (priority 80), also with --no-realtime");
  std::string curve_key, curve_clients, generate_dir, key_name = "server";
  app.add_option("--curve-server-key", curve_key,
                 "CURVE: the server's secret certificate NAME.key_secret (from "
                 "--generate-keys, conica-keygen or pyzmq's zmq.auth.create_certificates)")
      ->check(CLI::ExistingFile);
  app.add_option("--curve-clients", curve_clients,
                 "CURVE: folder of authorised clients' public certificates, one NAME.key each")
      ->check(CLI::ExistingDirectory);
  app.add_option("--generate-keys", generate_dir,
                 "write new CURVE certificates DIR/NAME.key (public) and DIR/NAME.key_secret "
                 "(secret), then exit");
  app.add_option("--key-name", key_name, "file name of --generate-keys (default: server)");
  app.get_option("--curve-server-key")->needs("--curve-clients");
  app.get_option("--curve-clients")->needs("--curve-server-key");
  app.get_option("--scene")->excludes("--builtin");
  CLI11_PARSE(app, argc, argv);

  spdlog::set_level(spdlog::level::from_str(log_level));
  opt.realtime = !no_realtime;

  if (!generate_dir.empty()) {
    conica::net::CurveKeyPair kp;
    std::string e = conica::net::generate_keypair(&kp);
    if (e.empty()) e = conica::net::write_keypair(generate_dir, key_name, kp);
    if (!e.empty()) {
      spdlog::error("{}", e);
      return 1;
    }
    std::printf(
        "%s/%s.key_secret (secret certificate: keep private)\n%s/%s.key (public "
        "certificate: hand out) public-key %s\n",
        generate_dir.c_str(), key_name.c_str(), generate_dir.c_str(), key_name.c_str(),
        kp.public_key.c_str());
    return 0;
  }
  if (!curve_key.empty()) {
    conica::net::CurveKeyPair kp;
    std::string e = conica::net::read_key_file(curve_key, &kp);
    if (e.empty() && kp.secret_key.empty())
      e = curve_key +
          ": a public certificate (no secret key); give the server its secret "
          "certificate (NAME.key_secret)";
    if (e.empty()) e = conica::net::read_client_keys(curve_clients, &opt.curve_client_keys);
    if (!e.empty()) {
      spdlog::error("{}", e);
      return 1;
    }
    opt.curve_secret_key = kp.secret_key;
    spdlog::info("CURVE: server key {}, {} authorised client keys", kp.public_key,
                 opt.curve_client_keys.size());
  }
  opt.scene_loader = load_scene_file;

  // Signals are handled by this thread alone (sigtimedwait below): block them before any other
  // thread starts so the loop thread inherits the mask.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  conica::BodySpec spec;
  std::string err;
  if (!scene.empty()) {
    err = load_scene_file(scene, &spec);
  } else {
    if (builtin.empty()) builtin = "cube";
    err = conica::net::builtin_scene(builtin, 1.0 / opt.rate_hz, &spec);
  }
  if (!err.empty()) {
    spdlog::error("{}", err);
    return 1;
  }

  zmq::context_t context(io_threads);
  if (realtime_io) {  // independent of --no-realtime (the loop thread's own policy)
    const int priority = std::min(80, sched_get_priority_max(SCHED_FIFO));
    if (conica::net::set_io_threads_fifo(context, priority)) {
      spdlog::info("ZeroMQ I/O threads run SCHED_FIFO priority {}", priority);
    } else {
      spdlog::info("SCHED_FIFO refused for the ZeroMQ I/O threads; they run at normal priority");
    }
  }
  {
    conica::net::Server server(context, opt);
    if (err = server.load(spec); err.empty()) err = server.start();
    if (!err.empty()) {
      spdlog::error("{}", err);
      return 1;
    }
    // Wait for a signal or the deadline.
    timespec end{};
    clock_gettime(CLOCK_MONOTONIC, &end);
    end.tv_sec += static_cast<time_t>(seconds);
    end.tv_nsec +=
        static_cast<long>((seconds - static_cast<double>(static_cast<time_t>(seconds))) * 1e9);
    if (end.tv_nsec >= 1000000000L) {
      end.tv_sec += 1;
      end.tv_nsec -= 1000000000L;
    }
    for (;;) {
      timespec wait{0, 200000000};  // re-check the deadline every 0.2 s
      const int sig = sigtimedwait(&signals, nullptr, &wait);
      if (sig == SIGINT || sig == SIGTERM) {
        spdlog::info("signal {}: shutting down", sig);
        break;
      }
      if (seconds > 0) {
        timespec now{};
        clock_gettime(CLOCK_MONOTONIC, &now);
        if (now.tv_sec > end.tv_sec || (now.tv_sec == end.tv_sec && now.tv_nsec >= end.tv_nsec))
          break;
      }
    }
    server.stop();  // closes the sockets (linger 0) before the context goes
    const auto s = server.stats();
    spdlog::info("stopped after {} ticks ({} missed), {} probes, {} errors", s.ticks,
                 s.missed_ticks, s.probes_received, s.errors);
  }
  return 0;
}
