// The loop's Transport over ZeroMQ and protobuf (see net/server.h for the sockets):
//   probe   ROUTER  [identity]([empty])[ClientMessage{probe}] -> ProbeUpdate, replies the same way
//   control ROUTER  ClientMessage{control} -> ControlRequest
//   state   PUB     [topic "F" | "S"][ServerMessage{state}]
// poll() looks at both ROUTER sockets in turn (neither starves the other) and otherwise sleeps in
// ppoll on their ZMQ_FD until a message may be there or the deadline comes; with busy_poll it
// spins on ZMQ_EVENTS instead, resting in ppoll for (1 - busy_poll_fraction) of a period after
// each probe and after a tick with no probe in the last period. Decoding parses on an arena with
// a preallocated first block and encoding reuses one message per kind, so a steady stream
// allocates nothing. Frames that are not an [identity]([empty])[payload] envelope, and payloads
// the codec refuses, come to the loop as Rejections.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>
#include <zmq.hpp>

#include "loop/clock.h"
#include "loop/transport.h"
#include "net/codec.h"
#include "net/server.h"

namespace google::protobuf {
class Arena;
}

namespace conica::net {

class ZmqTransport final : public loop::Transport {
 public:
  // `clock` is the loop's (deadlines are on it; CLOCK_MONOTONIC for ppoll's timeouts).
  ZmqTransport(zmq::context_t& context, const ServerOptions& options, loop::Clock& clock);
  ~ZmqTransport() override;
  ZmqTransport(const ZmqTransport&) = delete;
  ZmqTransport& operator=(const ZmqTransport&) = delete;

  // Creates and binds the three sockets; fills the resolved endpoints. Error message or "".
  std::string bind(Endpoints* resolved);
  // Unbinds and closes the sockets (linger 0). Idempotent.
  void close();

  bool poll(loop::TimeNs deadline_ns, loop::Incoming* in) override;
  bool reply(const loop::Route& to, const loop::ForceReply& reply) override;
  bool reply(const loop::Route& to, const loop::ControlResult& result) override;
  bool reply(const loop::Route& to, const loop::Rejection& error) override;
  void publish(const loop::StateFrame& frame) override;

 private:
  static constexpr int kMaxFrames = 4;  // [identity][delimiter][payload] at most, one spare

  bool receive(zmq::socket_t& s, loop::Channel channel, loop::Incoming* in);
  bool recv_multipart(zmq::socket_t& s, int* n);
  bool send(const loop::Route& to, const v1::ServerMessage& msg);
  void rest_after(loop::TimeNs t) { rest_until_ns_ = t + rest_ns_; }

  zmq::context_t& context_;
  const ServerOptions& opt_;
  loop::Clock& clock_;
  zmq::socket_t probe_, pub_, control_;
  int probe_fd_ = -1, control_fd_ = -1;
  bool control_first_ = false;  // which socket poll() looks at first, alternating

  std::vector<char> arena_block_;
  std::unique_ptr<google::protobuf::Arena> arena_;
  v1::ServerMessage force_msg_, error_msg_, state_msg_, control_msg_;
  std::vector<std::uint8_t> out_;
  std::array<zmq::message_t, kMaxFrames> frames_;

  // Busy poll (see above).
  loop::TimeNs period_ns_ = 1'000'000, rest_ns_ = 0, rest_until_ns_ = 0, last_probe_ns_ = 0;
  bool probe_in_input_ = false;  // a probe came in a tick's input stage (a poll that only looked)
};

}  // namespace conica::net
