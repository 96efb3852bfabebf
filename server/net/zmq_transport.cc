#include "net/zmq_transport.h"

#include <google/protobuf/arena.h>
#include <poll.h>
#include <spdlog/spdlog.h>
#include <time.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>

#include "net/curve.h"

namespace conica::net {
namespace {

using loop::TimeNs;

constexpr std::uint8_t kDelimiter = 1;  // Route::flags: the sender uses an empty delimiter (REQ)

timespec to_timespec(TimeNs ns) {
  timespec ts;
  ts.tv_sec = static_cast<time_t>(ns / 1000000000ull);
  ts.tv_nsec = static_cast<long>(ns % 1000000000ull);
  return ts;
}

// "tcp://HOST:PORT": is HOST a loopback address? Other transports (inproc, ipc) are local.
bool is_loopback(const std::string& endpoint) {
  const std::string tcp = "tcp://";
  if (endpoint.rfind(tcp, 0) != 0) return true;
  std::string host = endpoint.substr(tcp.size());
  host = host.substr(0, host.rfind(':'));
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']')
    host = host.substr(1, host.size() - 2);
  return host.rfind("127.", 0) == 0 || host == "localhost" || host == "::1";
}

// A spin-wait hint to the CPU (busy polling).
inline void cpu_relax() {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_ia32_pause();
#elif defined(__aarch64__)
  asm volatile("yield");
#endif
}

bool readable(zmq::socket_t& s) { return (s.get(zmq::sockopt::events) & ZMQ_POLLIN) != 0; }

}  // namespace

ZmqTransport::ZmqTransport(zmq::context_t& context, const ServerOptions& options,
                           loop::Clock& clock)
    : context_(context), opt_(options), clock_(clock) {
  arena_block_.resize(4 * static_cast<std::size_t>(std::max(opt_.max_message_bytes, 4096)));
  google::protobuf::ArenaOptions ao;
  ao.initial_block = arena_block_.data();
  ao.initial_block_size = arena_block_.size();
  arena_ = std::make_unique<google::protobuf::Arena>(ao);
  out_.resize(64 * 1024);
  period_ns_ = static_cast<TimeNs>(std::llround(1e9 / opt_.rate_hz));
  rest_ns_ = static_cast<TimeNs>((1.0 - opt_.busy_poll_fraction) * static_cast<double>(period_ns_));
}

ZmqTransport::~ZmqTransport() { close(); }

std::string ZmqTransport::bind(Endpoints* resolved) {
  auto common = [&](zmq::socket_t& s) {
    s.set(zmq::sockopt::linger, 0);
    if (!opt_.curve_secret_key.empty()) set_curve_server(s, opt_.curve_secret_key);
  };
  try {
    probe_ = zmq::socket_t(context_, zmq::socket_type::router);
    pub_ = zmq::socket_t(context_, zmq::socket_type::pub);
    control_ = zmq::socket_t(context_, zmq::socket_type::router);
    for (zmq::socket_t* s : {&probe_, &pub_, &control_}) common(*s);
    for (zmq::socket_t* s : {&probe_, &control_}) {
      s->set(zmq::sockopt::maxmsgsize, static_cast<int64_t>(opt_.max_message_bytes));
      s->set(zmq::sockopt::router_mandatory, 0);  // a vanished client: the reply is dropped
    }
    pub_.set(zmq::sockopt::sndhwm, opt_.pub_sndhwm);
    const std::pair<zmq::socket_t*, const std::string*> binds[] = {
        {&probe_, &opt_.probe_endpoint},
        {&pub_, &opt_.state_endpoint},
        {&control_, &opt_.control_endpoint}};
    std::string* out[] = {&resolved->probe, &resolved->state, &resolved->control};
    for (int k = 0; k < 3; ++k) {
      const std::string& e = *binds[k].second;
      if (!is_loopback(e))
        spdlog::warn("binding {} on a non-loopback address: reachable from other machines{}", e,
                     opt_.curve_secret_key.empty()
                         ? ", unauthenticated and unencrypted (see --curve-server-key)"
                         : " (CURVE: listed clients only)");
      try {
        binds[k].first->bind(e);
      } catch (const zmq::error_t& err) {
        return "cannot bind " + e + ": " + err.what();
      }
      *out[k] = binds[k].first->get(zmq::sockopt::last_endpoint);
    }
    probe_fd_ = probe_.get(zmq::sockopt::fd);
    control_fd_ = control_.get(zmq::sockopt::fd);
  } catch (const zmq::error_t& err) {
    return std::string("zmq: ") + err.what();
  }
  return {};
}

// Unbinding first releases an inproc endpoint at once; closing alone leaves it to ZeroMQ's
// reaper thread, so a restart in the same context could find it still taken.
void ZmqTransport::close() {
  for (zmq::socket_t* s : {&probe_, &pub_, &control_}) {
    if (s->handle() == nullptr) continue;
    try {
      const std::string e = s->get(zmq::sockopt::last_endpoint);
      if (!e.empty()) s->unbind(e);
    } catch (const zmq::error_t&) {
      // not bound (a failed bind): nothing to release
    }
    s->close();
  }
}

// ---- incoming ---------------------------------------------------------------------------

bool ZmqTransport::poll(TimeNs deadline, loop::Incoming* in) {
  const bool only_look = clock_.now_ns() >= deadline;
  for (;;) {
    control_first_ = !control_first_;
    const bool got = control_first_ ? receive(control_, loop::Channel::kControl, in) ||
                                          receive(probe_, loop::Channel::kProbe, in)
                                    : receive(probe_, loop::Channel::kProbe, in) ||
                                          receive(control_, loop::Channel::kControl, in);
    const TimeNs t = clock_.now_ns();
    if (got) {
      if (in->route.channel == loop::Channel::kProbe &&
          std::holds_alternative<loop::ProbeUpdate>(in->message)) {
        last_probe_ns_ = t;
        if (only_look) probe_in_input_ = true;
        if (opt_.busy_poll) rest_after(t);
      }
      return true;
    }
    if (t >= deadline) return false;
    if (opt_.busy_poll && t >= rest_until_ns_) {
      // ZMQ_EVENTS processes the I/O thread's commands, so a message that arrived is seen
      // here without any file-descriptor wake-up.
      if (!readable(probe_) && !readable(control_)) cpu_relax();
      continue;
    }
    // ZMQ_FD is edge-triggered: it fires when ZMQ_EVENTS may have changed. After draining to
    // EAGAIN, check the events once more before sleeping on it.
    if (readable(probe_) || readable(control_)) continue;
    pollfd fds[2] = {{probe_fd_, POLLIN, 0}, {control_fd_, POLLIN, 0}};
    TimeNs wake = deadline;
    if (opt_.busy_poll) wake = std::min(wake, rest_until_ns_);  // then spin again
    const timespec timeout = to_timespec(wake - t);
    if (ppoll(fds, 2, &timeout, nullptr) < 0 && errno != EINTR) {
      clock_.sleep_until(deadline);  // cannot poll: keep the rate anyway
      return false;
    }
  }
}

// Receives one multipart message without blocking; false when none is waiting. Extra frames
// beyond kMaxFrames are drained and reported as n = kMaxFrames + 1.
bool ZmqTransport::recv_multipart(zmq::socket_t& s, int* n) {
  auto r = s.recv(frames_[0], zmq::recv_flags::dontwait);
  if (!r) return false;
  *n = 1;
  while (frames_[*n - 1].more()) {
    if (*n < kMaxFrames) {
      (void)s.recv(frames_[*n], zmq::recv_flags::none);  // parts arrive atomically
      ++*n;
    } else {
      zmq::message_t extra;
      (void)s.recv(extra, zmq::recv_flags::none);
      if (!extra.more()) {
        *n = kMaxFrames + 1;
        break;
      }
    }
  }
  return true;
}

bool ZmqTransport::receive(zmq::socket_t& s, loop::Channel channel, loop::Incoming* in) {
  int n = 0;
  if (!recv_multipart(s, &n)) return false;
  loop::Route& route = in->route;
  route.channel = channel;
  // Reply envelope: [identity] or [identity][empty delimiter] (REQ clients) before the payload.
  int payload = -1;
  if (n == 2) payload = 1;
  if (n == 3 && frames_[1].size() == 0) payload = 2;
  const std::size_t id_size = frames_[0].size();
  route.routable = (payload > 0 || (n >= 2 && n <= kMaxFrames)) && id_size <= route.bytes.size();
  route.flags = payload == 2 ? kDelimiter : 0;
  route.size = static_cast<std::uint16_t>(std::min(id_size, route.bytes.size()));
  std::memcpy(route.bytes.data(), frames_[0].data(), route.size);
  if (payload < 0) {
    in->message = loop::Rejection{ErrorKind::kMalformed, "expected [identity][payload] frames", 0};
    return true;
  }
  auto* msg = google::protobuf::Arena::CreateMessage<v1::ClientMessage>(arena_.get());
  DecodeError err;
  bool ok = parse_client(frames_[payload].data(), frames_[payload].size(),
                         static_cast<std::size_t>(opt_.max_message_bytes), msg, &err);
  if (ok && channel == loop::Channel::kProbe) {
    ProbeInput update;
    if ((ok = decode_probe_update(*msg, &update, &err))) in->message = update;
  } else if (ok) {
    const v1::ControlRequest* req = nullptr;
    if ((ok = decode_control(*msg, &req, &err)))
      to_command(*req, &in->message.emplace<loop::ControlRequest>());
  }
  arena_->Reset();
  if (!ok) in->message = err;
  return true;
}

// ---- outgoing ---------------------------------------------------------------------------

bool ZmqTransport::send(const loop::Route& to, const v1::ServerMessage& msg) {
  zmq::socket_t& s = to.channel == loop::Channel::kProbe ? probe_ : control_;
  const std::size_t size = msg.ByteSizeLong();
  if (out_.size() < size) out_.resize(size);
  msg.SerializeWithCachedSizesToArray(out_.data());
  try {
    constexpr auto more = zmq::send_flags::sndmore | zmq::send_flags::dontwait;
    bool ok = s.send(zmq::const_buffer(to.bytes.data(), to.size), more).has_value();
    if (ok && (to.flags & kDelimiter)) ok = s.send(zmq::const_buffer(nullptr, 0), more).has_value();
    if (ok)
      ok = s.send(zmq::const_buffer(out_.data(), size), zmq::send_flags::dontwait).has_value();
    return ok;
  } catch (const zmq::error_t&) {
    return false;  // EHOSTUNREACH and kin: the client is gone
  }
}

bool ZmqTransport::reply(const loop::Route& to, const loop::ForceReply& r) {
  encode_force(r.update, r.probe, r.tick, r.recv_ns, r.reply_ns, &force_msg_);
  return send(to, force_msg_);
}

bool ZmqTransport::reply(const loop::Route& to, const loop::ControlResult& r) {
  encode_control_result(r, &control_msg_);
  return send(to, control_msg_);
}

bool ZmqTransport::reply(const loop::Route& to, const loop::Rejection& e) {
  encode_error(e, &error_msg_);
  return send(to, error_msg_);
}

void ZmqTransport::publish(const loop::StateFrame& f) {
  encode_state(*f.model, *f.state, f.with_positions, *f.stats, &state_msg_);
  const std::size_t size = state_msg_.ByteSizeLong();
  if (out_.size() < size) out_.resize(size);
  state_msg_.SerializeWithCachedSizesToArray(out_.data());
  const char topic = f.with_positions ? 'S' : 'F';
  try {
    // PUB never blocks: at the high-water mark a subscriber's frames are dropped.
    if (pub_.send(zmq::const_buffer(&topic, 1),
                  zmq::send_flags::sndmore | zmq::send_flags::dontwait))
      (void)pub_.send(zmq::const_buffer(out_.data(), size), zmq::send_flags::dontwait);
  } catch (const zmq::error_t&) {
  }
  if (opt_.busy_poll && !f.with_positions) {
    // The end of a tick. No client at the rate, or one just answered in the input stage: rest
    // first.
    const TimeNs t = clock_.now_ns();
    if (t - last_probe_ns_ > period_ns_ || probe_in_input_) rest_after(t);
    probe_in_input_ = false;
  }
}

}  // namespace conica::net
