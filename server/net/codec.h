// The one place where protobuf meets the core: decoding and validating client messages, and
// encoding replies, state frames and control replies. Nothing else in conica includes
// messages.pb.h except the server loop that owns the messages.
//
// Encoders write into caller-owned messages that are reused from tick to tick: they set every
// field they own instead of calling Clear() (which in proto3 frees sub-messages), so a steady
// stream of replies and frames allocates nothing inside protobuf.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>

#include "conica/v1/messages.pb.h"
#include "core/model.h"

namespace conica::net {

inline constexpr std::uint32_t kProtocolVersion = 1;

// Error kinds, numbered as Error.Code on the wire.
enum class ErrorKind : int {
  kMalformed = 1,
  kWrongType = 2,
  kTooLarge = 3,
  kBadValue = 4,
  kUnknownProbe = 5,
  kUnsupportedVersion = 6,
  kBadRequest = 7,
};
inline constexpr int kNumErrorCodes = 8;  // Error.Code values 0..7
const char* error_kind_name(ErrorKind kind);

struct DecodeError {
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

// A validated probe update.
struct ProbeInput {
  std::uint32_t client_id = 0;
  int probe_id = 0;
  std::uint64_t sequence = 0;
  std::uint64_t send_time_ns = 0;
  Vec3 position = Vec3::Zero();  // m
  double radius = 0;             // m; 0 keeps the current radius
};

// Parses bytes into `msg` (size > max_bytes: kTooLarge, unparseable: kMalformed) and checks the
// protocol version.
bool parse_client(const void* data, std::size_t size, std::size_t max_bytes, v1::ClientMessage* msg,
                  DecodeError* err);

// A parsed message on the probe socket: must hold a ProbeUpdate with a position, a known probe
// id and sane values.
bool decode_probe(const v1::ClientMessage& msg, const ProbeLimits& limits, ProbeInput* out,
                  DecodeError* err);

// A parsed message on the control socket: must hold a ControlRequest of a known kind.
bool decode_control(const v1::ClientMessage& msg, const v1::ControlRequest** out, DecodeError* err);

// Loop statistics in core units, filled by the server, encoded into LoopStats.
struct LoopStatsData {
  std::uint64_t ticks = 0, missed_ticks = 0;
  double rate_hz = 0;
  double lateness_p50_us = 0, lateness_p99_us = 0, lateness_max_us = 0;
  double step_p50_us = 0, step_p99_us = 0, step_max_us = 0;
  double input_p50_us = 0, input_p99_us = 0;
  double publish_p50_us = 0, publish_p99_us = 0;
  std::uint64_t errors = 0, probes_received = 0, replies_sent = 0, replies_dropped = 0;
  std::array<std::uint64_t, kNumErrorCodes> errors_by_code{};
  bool paused = false;
  std::uint32_t window = 0;
};

void encode_stats(const LoopStatsData& stats, const Counters& counters, v1::LoopStats* out);

// ServerMessage{force}: the probe's force and stiffness as they are in `probe`.
void encode_force(const ProbeInput& in, const ProbeState& probe, std::uint64_t tick,
                  std::uint64_t recv_ns, std::uint64_t reply_ns, v1::ServerMessage* out);

// ServerMessage{error}.
void encode_error(const DecodeError& err, v1::ServerMessage* out);

// ServerMessage{state}: tick, time, every probe, stats; node positions (float, num_nodes x 3)
// when with_positions, else none.
void encode_state(const Model& model, const State& state, bool with_positions,
                  const LoopStatsData& stats, v1::ServerMessage* out);

// ControlReply{mesh}: surface triangles and rest positions.
void encode_mesh(const Model& model, v1::ControlReply* out);

}  // namespace conica::net
