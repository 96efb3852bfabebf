// The clients' side of the wire: encoding ProbeUpdate, decoding ForceReply / Error, a DEALER
// connection to the probe ROUTER and a DEALER to the control ROUTER, and monotonic time helpers.
// Only this folder includes zmq.hpp and messages.pb.h; programs see plain structs in SI units.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <zmq.hpp>

#include "common/types.h"
#include "conica/v1/messages.pb.h"
#include "net/curve.h"

namespace conica::client {

inline constexpr std::uint32_t kProtocolVersion = 1;

// CLOCK_MONOTONIC, ns (the clock the protocol's *_time_ns fields use).
std::int64_t now_ns();
// Sleeps until the absolute CLOCK_MONOTONIC time t_ns (retries on EINTR).
void sleep_until_ns(std::int64_t t_ns);

// A decoded ForceReply, SI units.
struct ForceSample {
  std::uint32_t client_id = 0, probe_id = 0;
  std::uint64_t sequence = 0;
  std::uint64_t client_send_time_ns = 0, server_recv_time_ns = 0, server_reply_time_ns = 0;
  std::uint64_t tick = 0;
  Vec3 force = Vec3::Zero();      // N on the probe
  Mat3 stiffness = Mat3::Zero();  // N/m, d force / d position
  bool has_stiffness = false;     // false when the reply carried no 9-value matrix
  bool contact = false;
  Vec3 position = Vec3::Zero();  // m, where the force was computed
};

// ClientMessage{probe}. radius 0 keeps the scene's.
void encode_probe(std::uint32_t client_id, std::uint32_t probe_id, std::uint64_t sequence,
                  std::uint64_t send_time_ns, const Vec3& position, double radius,
                  v1::ClientMessage* msg);

enum class ReplyKind { kForce, kError, kOther, kMalformed };
// Decodes a ServerMessage into `scratch`; kForce fills `force`, kError fills `error` (the
// server's message, with its code and echoed sequence).
ReplyKind decode_reply(const void* data, std::size_t size, v1::ServerMessage* scratch,
                       ForceSample* force, std::string* error);

// CURVE (server/net/curve.h): the server's public key and this client's key pair, read from
// ZeroMQ certificates (conica-keygen, conica-server --generate-keys or pyzmq's
// zmq.auth.create_certificates): the server's NAME.key and this client's NAME.key_secret.
// Disabled when empty.
struct CurveClient {
  std::string server_public;  // z85, 40 characters
  net::CurveKeyPair keys;     // this client's public and secret key, z85
  bool enabled() const { return !server_public.empty(); }
};

// Reads --curve-server-pub and --curve-key: both empty leaves `out` disabled; otherwise both
// files must be readable key files, the first with the server's public key (and no secret),
// the second with this client's public and secret key. Returns "" or "FILE: what is wrong".
std::string load_curve_client(const std::string& server_pub_file, const std::string& key_file,
                              CurveClient* out);

// The one place client sockets get CURVE: sets the server key and this client's key pair on
// `socket` (before connect). Does nothing when `curve` is disabled.
void apply_curve(zmq::socket_t& socket, const CurveClient& curve);

// Waits until `socket` can be read or the absolute time deadline_ns passes (ppoll on ZMQ_FD,
// sub-millisecond). Returns true when a message is ready.
bool wait_readable(zmq::socket_t& socket, std::int64_t deadline_ns);

// A DEALER to the probe ROUTER. Sends never block (a full queue is reported as false).
class ProbeConnection {
 public:
  ProbeConnection(zmq::context_t& context, const std::string& endpoint, std::uint32_t client_id,
                  const CurveClient& curve = {});
  bool send(std::uint32_t probe_id, std::uint64_t sequence, std::uint64_t send_time_ns,
            const Vec3& position, double radius = 0);
  // Receives one message if one is ready before deadline_ns (absolute; now_ns() for a poll).
  // Returns kOther when nothing arrived.
  ReplyKind receive(std::int64_t deadline_ns, ForceSample* force, std::string* error,
                    bool* got_message);
  zmq::socket_t& socket() { return socket_; }
  std::uint32_t client_id() const { return client_id_; }

 private:
  zmq::socket_t socket_;
  std::uint32_t client_id_;
  v1::ClientMessage out_;
  v1::ServerMessage in_;
  std::string buffer_;
};

// Asks the control ROUTER for a ControlRequest of `kind` and waits up to timeout_ms for the reply.
bool control_request(zmq::context_t& context, const std::string& endpoint,
                     v1::ControlRequest::Kind kind, int timeout_ms, v1::ControlReply* reply,
                     std::string* error, const CurveClient& curve = {});

// Human-readable multi-line summary of LoopStats (tick lateness, missed ticks, step cost, ...).
std::string describe_stats(const v1::LoopStats& s);

}  // namespace conica::client
