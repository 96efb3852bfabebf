// Typed messages between the fixed-rate loop and its transport (loop/transport.h): what arrives
// (probe updates, control commands, messages the transport could not decode) and what leaves
// (force replies, control results, errors, state frames), plus the loop statistics they carry.
// Plain C++ and core types only; server/net/codec.h maps them to and from protobuf.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <variant>

#include "core/model.h"
#include "loop/clock.h"

namespace conica::loop {

// Why a message was refused, numbered as Error.Code on the wire.
enum class ErrorKind : int {
  kMalformed = 1,
  kWrongType = 2,
  kTooLarge = 3,
  kBadValue = 4,
  kUnknownProbe = 5,
  kUnsupportedVersion = 6,
  kBadRequest = 7,
};
inline constexpr int kNumErrorCodes = 8;  // codes 0..7

struct Rejection {
  ErrorKind kind = ErrorKind::kMalformed;
  const char* message = "";    // static text, no allocation
  std::uint64_t sequence = 0;  // echoed when the message got that far
};

// What a probe update may contain. A position passes when it is finite, |x_i| <= max_abs_position
// on every axis and inside [box_min, box_max] (the body's bounding box grown by a margin).
struct ProbeLimits {
  double max_abs_position = 1e3;  // m
  double max_radius = 1.0;        // m; a radius must be in (0, max_radius], 0 keeps the scene's
  Vec3 box_min = Vec3::Constant(-1e3), box_max = Vec3::Constant(1e3);  // m
  int num_probes = 0;
};

// The box around a body's rest positions, grown by `margin` (m) on every side.
void body_box(const Model& model, double margin, ProbeLimits* limits);

// A probe update: probe `probe_id` of the scene moves its centre to `position`.
struct ProbeUpdate {
  std::uint32_t client_id = 0;
  int probe_id = 0;
  std::uint64_t sequence = 0;
  std::uint64_t send_time_ns = 0;  // the client's clock, echoed
  Vec3 position = Vec3::Zero();    // m
  double radius = 0;               // m; 0 keeps the current radius
};

// The scene-dependent checks of a probe update, in this order: known probe id, finite position,
// |x_i| <= max_abs_position, inside the box, radius in [0, max_radius]. No allocation.
bool check_probe(const ProbeUpdate& update, const ProbeLimits& limits, Rejection* why);

// ---- control commands, applied between ticks ----------------------------------------------
enum class Parameter : std::uint8_t {
  kUnknown,
  kDamping,   // model mass damping, 1/s, >= 0
  kGravityX,  // m/s^2
  kGravityY,
  kGravityZ,
  kPositionsHz,  // rate of state frames with node positions, Hz, >= 0 (0: never)
};
const char* parameter_name(Parameter p);  // "damping", "gravity_x", ... ("?" for kUnknown)
Parameter parameter_from_name(std::string_view name);  // kUnknown when not one of those

struct LoadScene {     // prepared off the loop thread, swapped in at a tick boundary
  std::string source;  // what the scene loader reads (a path)
};
struct Reset {};  // back to the rest state
struct Pause {};  // stop stepping (probes are still answered)
struct Resume {};
struct SetParameter {
  Parameter parameter = Parameter::kUnknown;
  double value = 0;
};
struct GetStats {};
struct GetMesh {};  // the reply carries the body's surface
using Command = std::variant<GetStats, LoadScene, Reset, Pause, Resume, SetParameter, GetMesh>;

struct ControlRequest {
  std::uint64_t sequence = 0;  // echoed
  Command command;
};

// ---- routing ------------------------------------------------------------------------------
enum class Channel : std::uint8_t { kProbe, kControl };

// Where a reply goes: filled by the transport when it hands a message over, opaque to the loop
// except for the channel. Fixed size (a ZeroMQ routing id is at most 255 bytes): no allocation.
struct Route {
  static constexpr std::size_t kMaxBytes = 256;
  Channel channel = Channel::kProbe;
  bool routable = true;    // false: the message cannot be answered (no usable envelope)
  std::uint8_t flags = 0;  // transport-specific
  std::uint16_t size = 0;  // bytes used
  std::array<std::uint8_t, kMaxBytes> bytes{};
};

// One message from the transport.
struct Incoming {
  Route route;
  std::variant<ProbeUpdate, ControlRequest, Rejection> message;
};

// ---- statistics ---------------------------------------------------------------------------
// Loop statistics as plain data: counts since the run started, percentiles (us) over the last
// `window` ticks, refreshed a few times per second.
// Multi-rate serving (solver body_rate_hz, loop/body_worker.h): the body thread's counters.
struct BodyStats {
  std::uint64_t steps = 0;            // body steps swapped in
  std::uint64_t late_ticks = 0;       // ticks a body step was due while the last still ran
  std::uint64_t estimates = 0;        // probe answers from the estimate (no local model in reach)
  std::uint64_t factorizations = 0;   // of the body's system
  std::uint64_t rollbacks = 0;        // the body's guard trips (the served state is not stepped:
                                      // its own rollbacks stay 0)
  double step_us = 0;                 // the last body step with its local models
  std::uint64_t proxy_fallbacks = 0;  // surface answers by the proxy moved alone (the joint
                                      // solve ran out far from equilibrium; core/multirate.h)
};

struct LoopStats {
  std::uint64_t ticks = 0, missed_ticks = 0;  // missed: deadlines skipped after an overrun
  double rate_hz = 0;
  double lateness_p50_us = 0, lateness_p99_us = 0, lateness_max_us = 0;  // wake-up vs deadline
  double step_p50_us = 0, step_p99_us = 0, step_max_us = 0;              // physics step
  double input_p50_us = 0, input_p99_us = 0;      // a tick's input stage (messages, replies)
  double publish_p50_us = 0, publish_p99_us = 0;  // a tick's publish stage (state frames)
  std::uint64_t errors = 0, probes_received = 0, replies_sent = 0, replies_dropped = 0;
  // Replies past the loop's reply budget (LoopOptions::reply_budget): the probe's last solved
  // contact, with the position it belongs to, instead of a new solve.
  std::uint64_t replies_held = 0;
  std::array<std::uint64_t, kNumErrorCodes> errors_by_code{};
  bool paused = false;
  std::uint32_t window = 0;  // ticks the percentiles describe
  BodyStats body;            // multi-rate serving; zero otherwise
};

// ---- outgoing -----------------------------------------------------------------------------
// The answer to a probe update: the contact force at the update's pose against the current
// node positions.
struct ForceReply {
  ProbeUpdate update;
  ProbeState probe;                  // force (N), stiffness (N/m), contacts, centre (m)
  std::uint64_t tick = 0;            // simulation tick the force belongs to
  TimeNs recv_ns = 0, reply_ns = 0;  // the loop's clock
};

// The answer to a control request; every one carries the statistics and the body's size.
struct ControlResult {
  std::uint64_t sequence = 0;
  bool ok = true;
  std::string message;
  LoopStats stats;
  Counters counters;
  std::uint32_t num_nodes = 0;
  const Model* mesh = nullptr;  // GetMesh: the body whose surface to send (valid during reply())
};

// A state frame, published every tick (forces) and at the positions rate (with node positions).
// The pointers are valid during publish() only.
struct StateFrame {
  const Model* model = nullptr;
  const State* state = nullptr;
  const LoopStats* stats = nullptr;
  bool with_positions = false;
};

}  // namespace conica::loop
