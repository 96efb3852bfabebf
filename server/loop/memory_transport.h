// A Transport in memory, for driving the loop in-process (tests, offline runs): messages are
// queued with an arrival time on the loop's clock, and everything the loop sends is recorded with
// the time it was sent. poll() waits on the clock (Clock::sleep_until) until the next arrival or
// its deadline, so with a ManualClock a whole run takes no real time. One thread only.
#pragma once

#include <cstdint>
#include <deque>
#include <functional>
#include <variant>
#include <vector>

#include "loop/clock.h"
#include "loop/messages.h"
#include "loop/transport.h"

namespace conica::loop {

class MemoryTransport final : public Transport {
 public:
  explicit MemoryTransport(Clock& clock) : clock_(clock) {}

  // A message from client `client` arriving at `at_ns`. Messages with equal times keep their
  // order.
  void send_probe(TimeNs at_ns, std::uint32_t client, const ProbeUpdate& update);
  void send_control(TimeNs at_ns, std::uint32_t client, std::uint64_t sequence, Command command);
  // A message the wire could not decode (as a real transport hands it over).
  void send_undecodable(TimeNs at_ns, std::uint32_t client, Channel channel, Rejection why);
  std::size_t queued() const { return queue_.size(); }

  struct Sent {
    TimeNs at_ns = 0;
    std::uint32_t client = 0;
    Channel channel = Channel::kProbe;
    std::variant<ForceReply, ControlResult, Rejection> what;  // ControlResult::mesh: see below
  };
  // Every reply in order. A ControlResult's mesh pointer is valid while that scene is in use.
  const std::vector<Sent>& sent() const { return sent_; }

  struct Frame {
    TimeNs at_ns = 0;
    std::uint64_t tick = 0;
    double time = 0;  // s
    int num_nodes = 0;
    bool with_positions = false;
    std::vector<Vec3> positions;  // with_positions only, m
    std::vector<ProbeState> probes;
    LoopStats stats;
  };
  const std::vector<Frame>& frames() const { return frames_; }

  // Called at every publish() before it is recorded (e.g. to advance a ManualClock, as if
  // publishing took that long).
  std::function<void(const StateFrame&)> on_publish;

  bool poll(TimeNs deadline_ns, Incoming* in) override;
  bool reply(const Route& to, const ForceReply& reply) override;
  bool reply(const Route& to, const ControlResult& result) override;
  bool reply(const Route& to, const Rejection& error) override;
  void publish(const StateFrame& frame) override;

 private:
  struct Queued {
    TimeNs at_ns;
    Incoming message;
  };
  void enqueue(TimeNs at_ns, std::uint32_t client, Channel channel, Incoming message);
  template <class T>
  bool record(const Route& to, const T& what);

  Clock& clock_;
  std::deque<Queued> queue_;
  std::vector<Sent> sent_;
  std::vector<Frame> frames_;
};

}  // namespace conica::loop
