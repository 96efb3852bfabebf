#include "loop/memory_transport.h"

#include <algorithm>
#include <cstring>
#include <utility>

namespace conica::loop {
namespace {

Route route_of(std::uint32_t client, Channel channel) {
  Route r;
  r.channel = channel;
  r.size = sizeof(client);
  std::memcpy(r.bytes.data(), &client, sizeof(client));
  return r;
}

std::uint32_t client_of(const Route& r) {
  std::uint32_t client = 0;
  std::memcpy(&client, r.bytes.data(), sizeof(client));
  return client;
}

}  // namespace

void MemoryTransport::enqueue(TimeNs at_ns, std::uint32_t client, Channel channel,
                              Incoming message) {
  message.route = route_of(client, channel);
  auto pos = std::upper_bound(queue_.begin(), queue_.end(), at_ns,
                              [](TimeNs t, const Queued& q) { return t < q.at_ns; });
  queue_.insert(pos, Queued{at_ns, std::move(message)});
}

void MemoryTransport::send_probe(TimeNs at_ns, std::uint32_t client, const ProbeUpdate& update) {
  Incoming in;
  in.message = update;
  enqueue(at_ns, client, Channel::kProbe, std::move(in));
}

void MemoryTransport::send_control(TimeNs at_ns, std::uint32_t client, std::uint64_t sequence,
                                   Command command) {
  Incoming in;
  ControlRequest& request = in.message.emplace<ControlRequest>();
  request.sequence = sequence;
  request.command = std::move(command);
  enqueue(at_ns, client, Channel::kControl, std::move(in));
}

void MemoryTransport::send_undecodable(TimeNs at_ns, std::uint32_t client, Channel channel,
                                       Rejection why) {
  Incoming in;
  in.message = why;
  enqueue(at_ns, client, channel, std::move(in));
}

bool MemoryTransport::poll(TimeNs deadline_ns, Incoming* in) {
  for (;;) {
    const TimeNs t = clock_.now_ns();
    if (!queue_.empty() && queue_.front().at_ns <= t) {
      *in = std::move(queue_.front().message);
      queue_.pop_front();
      return true;
    }
    if (t >= deadline_ns) return false;
    TimeNs wake = deadline_ns;
    if (!queue_.empty()) wake = std::min(wake, queue_.front().at_ns);
    clock_.sleep_until(wake);
  }
}

template <class T>
bool MemoryTransport::record(const Route& to, const T& what) {
  Sent s;
  s.at_ns = clock_.now_ns();
  s.client = client_of(to);
  s.channel = to.channel;
  s.what = what;
  sent_.push_back(std::move(s));
  return true;
}

bool MemoryTransport::reply(const Route& to, const ForceReply& r) { return record(to, r); }
bool MemoryTransport::reply(const Route& to, const ControlResult& r) { return record(to, r); }
bool MemoryTransport::reply(const Route& to, const Rejection& r) { return record(to, r); }

void MemoryTransport::publish(const StateFrame& frame) {
  Frame f;
  f.at_ns = clock_.now_ns();
  if (on_publish) on_publish(frame);
  f.tick = frame.state->tick;
  f.time = frame.state->time;
  f.num_nodes = frame.model->num_nodes();
  f.with_positions = frame.with_positions;
  if (frame.with_positions) f.positions = frame.state->x;
  f.probes = frame.state->probes;
  f.stats = *frame.stats;
  frames_.push_back(std::move(f));
}

}  // namespace conica::loop
