// conica-server: the 1 kHz haptic simulation server (see server/net/server.h for the sockets).
//   conica-server                       built-in cube on the default loopback endpoints
//   conica-server --scene FILE          a scene file
//   conica-server --builtin liver --probe-endpoint tcp://127.0.0.1:6000 --seconds 10
#include <signal.h>
#include <spdlog/spdlog.h>
#include <time.h>

#include <CLI/CLI.hpp>
#include <cerrno>
#include <cstdio>
#include <string>
#include <zmq.hpp>

#include "net/builtin_scenes.h"
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
  app.get_option("--scene")->excludes("--builtin");
  CLI11_PARSE(app, argc, argv);

  spdlog::set_level(spdlog::level::from_str(log_level));
  opt.realtime = !no_realtime;
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

  zmq::context_t context(1);
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
