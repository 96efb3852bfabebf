// The 1 kHz haptic server: a fixed-rate loop that steps the body and three ZeroMQ sockets.
//
//   probe   ROUTER  ClientMessage{probe} -> ServerMessage{force | error}, answered as the update
//                   arrives (between ticks) with the contact force at the new pose against the
//                   current node positions; the next tick integrates with it
//   state   PUB     [topic "F"][ServerMessage{state}] every tick (probes, stats), and
//                   [topic "S"][ServerMessage{state}] with node positions at positions_hz
//   control ROUTER  ClientMessage{control} -> ServerMessage{control_reply | error}
//
// The fixed-rate loop itself is loop::FixedRateLoop (server/loop, no wire): one tick is serve
// (answer probes and apply control as they arrive, until the absolute deadline) -> swap in a
// scene LOAD_SCENE prepared on a worker thread -> input -> step -> publish; an overrun skips the
// missed deadlines and counts them, dt stays fixed. The Server puts it on a thread with the real
// clock (CLOCK_MONOTONIC) and net::ZmqTransport (the sockets and the codec), and logs: bad
// messages are answered with ServerMessage{error}, counted by kind and logged once per kind per
// 10 s; they never change the rate or the state.
//
// The Server owns its sockets; the zmq::context_t is the caller's (inproc endpoints need the
// client to share it). start() binds and starts the loop thread; stop() joins it and closes the
// sockets; a Server can be started again.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>
#include <zmq.hpp>

#include "core/body.h"
#include "core/model.h"
#include "net/codec.h"

namespace conica::loop {
class FixedRateLoop;
class SteadyClock;
}  // namespace conica::loop

namespace conica::net {

class ZapHandler;

struct ServerOptions {
  std::string probe_endpoint = "tcp://127.0.0.1:5555";
  std::string state_endpoint = "tcp://127.0.0.1:5556";
  std::string control_endpoint = "tcp://127.0.0.1:5557";
  double rate_hz = 1000;              // loop rate; the model's dt should be 1 / rate_hz
  double positions_hz = 60;           // "S" frames with node positions (0: never)
  double log_period_s = 10;           // loop statistics at info level (0: never)
  int max_message_bytes = 64 * 1024;  // larger client messages: TOO_LARGE (transport drops them)
  int pub_sndhwm = 16;                // messages queued per subscriber before PUB drops
  double box_margin = 0.25;  // m: probe positions must lie within the body box grown by this
  bool realtime = false;     // try SCHED_FIFO and mlockall (logged at info when refused)
  // Between ticks, spin on the sockets (ZMQ_EVENTS, receive with ZMQ_DONTWAIT) instead of
  // sleeping in ppoll on their file descriptors: no wake-up on a probe's arrival, at the price of
  // a whole core (only sensible with a core to spare; logged at start).
  bool busy_poll = false;
  // With busy_poll: after answering a probe (and after a tick with no probe in the last period)
  // the loop first waits in ppoll, as without busy poll, for (1 - busy_poll_fraction) of a
  // period, then spins. A SCHED_FIFO loop that spins all the time is stopped by the kernel's
  // real-time throttling (sched_rt_runtime_us: by default 50 ms in every second); resting keeps
  // it under that budget, and a client at the loop's rate still finds it spinning.
  double busy_poll_fraction = 1.0;
  int window = 2048;              // ticks in the rolling statistics window
  bool refuse_slow_scene = true;  // refuse a scene whose median step cost exceeds the period
  // LOAD_SCENE: path -> spec; returns an error message (empty on success). Unset: refused.
  std::function<std::string(const std::string&, BodySpec*)> scene_loader;
  // CURVE (net/curve.h): the server's z85 secret key and the z85 public keys of the clients it
  // accepts. Empty secret: plain ZeroMQ. Set: all three sockets encrypt, and a client whose key
  // is not listed is refused at the handshake (counted in curve_refused(), logged).
  std::string curve_secret_key;
  std::vector<std::string> curve_client_keys;
};

// Resolved endpoints (with the ports the OS picked for "tcp://host:*").
struct Endpoints {
  std::string probe, state, control;
};

class Server {
 public:
  Server(zmq::context_t& context, ServerOptions options);
  ~Server();
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  // Builds the model, measures the step cost on a copy (50 steps) and makes it the scene. Before
  // start() only; LOAD_SCENE does the same on a worker thread while running and the loop swaps
  // the scene in at a tick boundary. Returns an error message or "".
  std::string load(const BodySpec& spec);

  // Binds the sockets and starts the loop thread. Returns an error message or "".
  std::string start();
  // Stops the loop and closes the sockets. Idempotent; safe with clients still connected.
  void stop();
  bool running() const { return thread_.joinable(); }

  Endpoints endpoints() const;
  // The latest statistics snapshot (refreshed a few times per second by the loop).
  LoopStatsData stats() const;
  // Median step cost measured at the last load, us (0 before one).
  double measured_step_us() const;
  // CURVE handshakes refused and accepted since start() (0 without CURVE).
  std::uint64_t curve_refused() const;
  std::uint64_t curve_accepted() const;
  // The current model (valid until the next load; do not call while LOAD_SCENE may run).
  const Model& model() const;

 private:
  class Events;  // the loop's Observer: statistics snapshot and logging

  zmq::context_t& context_;
  ServerOptions options_;
  std::unique_ptr<loop::SteadyClock> clock_;
  std::unique_ptr<Events> events_;
  std::unique_ptr<loop::FixedRateLoop> loop_;  // the scene, commands, ticks; kept across runs
  std::unique_ptr<ZapHandler> zap_;  // CURVE only; bound before the sockets, closed after them
  std::thread thread_;
  std::atomic<bool> stop_{false};
  mutable std::mutex mutex_;  // guards endpoints_ and stats_
  Endpoints endpoints_;
  LoopStatsData stats_;
};

}  // namespace conica::net
