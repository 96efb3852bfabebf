// The one place where protobuf meets the loop's typed messages (loop/messages.h) and the core:
// decoding and validating client messages, and encoding replies, state frames and control
// replies. Nothing else in conica includes messages.pb.h except the ZeroMQ transport that owns
// the messages (net/zmq_transport.h).
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
#include "loop/messages.h"

namespace conica::net {

inline constexpr std::uint32_t kProtocolVersion = 1;

// The loop's plain types under their wire-side names.
using ErrorKind = loop::ErrorKind;  // numbered as Error.Code on the wire
using loop::kNumErrorCodes;         // Error.Code values 0..7
using DecodeError = loop::Rejection;
using ProbeLimits = loop::ProbeLimits;
using ProbeInput = loop::ProbeUpdate;  // a probe update (validated by decode_probe)
using LoopStatsData = loop::LoopStats;
using loop::body_box;

const char* error_kind_name(ErrorKind kind);

// Parses bytes into `msg` (size > max_bytes: kTooLarge, unparseable: kMalformed) and checks the
// protocol version.
bool parse_client(const void* data, std::size_t size, std::size_t max_bytes, v1::ClientMessage* msg,
                  DecodeError* err);

// A parsed message on the probe socket, the wire's part: must hold a ProbeUpdate with a
// position and a finite velocity if it has one. The scene's part is loop::check_probe.
bool decode_probe_update(const v1::ClientMessage& msg, ProbeInput* out, DecodeError* err);

// Both parts: a ProbeUpdate with a position, a known probe id and sane values.
bool decode_probe(const v1::ClientMessage& msg, const ProbeLimits& limits, ProbeInput* out,
                  DecodeError* err);

// A parsed message on the control socket: must hold a ControlRequest of a known kind.
bool decode_control(const v1::ClientMessage& msg, const v1::ControlRequest** out, DecodeError* err);

// A decoded ControlRequest as the loop's typed command (SET_PARAMETER with a name the loop does
// not know: Parameter::kUnknown, refused by the loop).
void to_command(const v1::ControlRequest& request, loop::ControlRequest* out);

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

// ServerMessage{control_reply}: ok, message, statistics, node count, and the mesh when asked.
void encode_control_result(const loop::ControlResult& result, v1::ServerMessage* out);

}  // namespace conica::net
