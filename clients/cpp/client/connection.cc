#include "client/connection.h"

#include <poll.h>
#include <time.h>

#include <cerrno>
#include <cstdio>

namespace conica::client {

std::int64_t now_ns() {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

void sleep_until_ns(std::int64_t t_ns) {
  timespec ts{static_cast<time_t>(t_ns / 1'000'000'000), static_cast<long>(t_ns % 1'000'000'000)};
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

void encode_probe(std::uint32_t client_id, std::uint32_t probe_id, std::uint64_t sequence,
                  std::uint64_t send_time_ns, const Vec3& position, double radius,
                  v1::ClientMessage* msg) {
  msg->set_protocol_version(kProtocolVersion);
  v1::ProbeUpdate* p = msg->mutable_probe();
  p->set_client_id(client_id);
  p->set_probe_id(probe_id);
  p->set_sequence(sequence);
  p->set_send_time_ns(send_time_ns);
  v1::Vec3* x = p->mutable_position();
  x->set_x(position.x());
  x->set_y(position.y());
  x->set_z(position.z());
  p->set_radius(radius);
}

ReplyKind decode_reply(const void* data, std::size_t size, v1::ServerMessage* m, ForceSample* f,
                       std::string* error) {
  if (!m->ParseFromArray(data, static_cast<int>(size))) {
    *error = "malformed server message (" + std::to_string(size) + " bytes)";
    return ReplyKind::kMalformed;
  }
  if (m->has_error()) {
    const auto& e = m->error();
    *error = "server error " + v1::Error::Code_Name(e.code()) + " (sequence " +
             std::to_string(e.sequence()) + "): " + e.message();
    return ReplyKind::kError;
  }
  if (!m->has_force()) return ReplyKind::kOther;
  const v1::ForceReply& r = m->force();
  f->client_id = r.client_id();
  f->probe_id = r.probe_id();
  f->sequence = r.sequence();
  f->client_send_time_ns = r.client_send_time_ns();
  f->server_recv_time_ns = r.server_recv_time_ns();
  f->server_reply_time_ns = r.server_reply_time_ns();
  f->tick = r.tick();
  f->force = Vec3(r.force().x(), r.force().y(), r.force().z());
  f->has_stiffness = r.stiffness().m_size() == 9;
  f->stiffness.setZero();
  if (f->has_stiffness)
    for (int i = 0; i < 9; ++i) f->stiffness(i / 3, i % 3) = r.stiffness().m(i);  // row-major
  f->contact = r.contact();
  f->position = Vec3(r.position().x(), r.position().y(), r.position().z());
  return ReplyKind::kForce;
}

std::string load_curve_client(const std::string& server_pub_file, const std::string& key_file,
                              CurveClient* out) {
  *out = {};
  if (server_pub_file.empty() && key_file.empty()) return {};
  if (server_pub_file.empty())
    return "--curve-key needs --curve-server-pub (the server's public certificate NAME.key)";
  if (key_file.empty())
    return "--curve-server-pub needs --curve-key (this client's secret certificate "
           "NAME.key_secret)";
  if (!net::curve_available()) return "CURVE requested but this libzmq has no CURVE support";
  net::CurveKeyPair server, mine;
  if (std::string e = net::read_key_file(server_pub_file, &server); !e.empty())
    return e + " (--curve-server-pub: the server's public certificate NAME.key)";
  if (!server.secret_key.empty())
    return server_pub_file +
           ": holds the server's secret key; give the client the server's public certificate "
           "(NAME.key, not NAME.key_secret)";
  if (std::string e = net::read_key_file(key_file, &mine); !e.empty())
    return e + " (--curve-key: this client's secret certificate NAME.key_secret)";
  if (mine.secret_key.empty())
    return key_file +
           ": a public certificate (no secret key); give this client's secret certificate "
           "(NAME.key_secret), not its NAME.key";
  out->server_public = server.public_key;
  out->keys = mine;
  return {};
}

void apply_curve(zmq::socket_t& socket, const CurveClient& curve) {
  if (curve.enabled()) net::set_curve_client(socket, curve.server_public, curve.keys);
}

bool wait_readable(zmq::socket_t& socket, std::int64_t deadline_ns) {
  for (;;) {
    // ZMQ_FD is edge-triggered: always ask ZMQ_EVENTS before sleeping on it.
    if (socket.get(zmq::sockopt::events) & ZMQ_POLLIN) return true;
    const std::int64_t left = deadline_ns - now_ns();
    if (left <= 0) return false;
    pollfd p{socket.get(zmq::sockopt::fd), POLLIN, 0};
    timespec ts{static_cast<time_t>(left / 1'000'000'000), static_cast<long>(left % 1'000'000'000)};
    ppoll(&p, 1, &ts, nullptr);
  }
}

ProbeConnection::ProbeConnection(zmq::context_t& context, const std::string& endpoint,
                                 std::uint32_t client_id, const CurveClient& curve)
    : socket_(context, zmq::socket_type::dealer), client_id_(client_id) {
  socket_.set(zmq::sockopt::linger, 0);
  apply_curve(socket_, curve);
  socket_.set(zmq::sockopt::sndhwm, 100000);
  socket_.set(zmq::sockopt::rcvhwm, 100000);
  socket_.connect(endpoint);
}

bool ProbeConnection::send(std::uint32_t probe_id, std::uint64_t sequence,
                           std::uint64_t send_time_ns, const Vec3& position, double radius) {
  encode_probe(client_id_, probe_id, sequence, send_time_ns, position, radius, &out_);
  out_.SerializeToString(&buffer_);
  return socket_.send(zmq::buffer(buffer_), zmq::send_flags::dontwait).has_value();
}

ReplyKind ProbeConnection::receive(std::int64_t deadline_ns, ForceSample* force, std::string* error,
                                   bool* got_message) {
  *got_message = false;
  zmq::message_t msg;
  if (!socket_.recv(msg, zmq::recv_flags::dontwait)) {
    if (!wait_readable(socket_, deadline_ns)) return ReplyKind::kOther;
    if (!socket_.recv(msg, zmq::recv_flags::dontwait)) return ReplyKind::kOther;
  }
  // A DEALER receives exactly the frames the ROUTER sent after the identity: skip any extra
  // leading empty delimiter a REQ-style server might add.
  while (msg.more() && msg.size() == 0) {
    if (!socket_.recv(msg, zmq::recv_flags::dontwait)) return ReplyKind::kMalformed;
  }
  *got_message = true;
  return decode_reply(msg.data(), msg.size(), &in_, force, error);
}

bool control_request(zmq::context_t& context, const std::string& endpoint,
                     v1::ControlRequest::Kind kind, int timeout_ms, v1::ControlReply* reply,
                     std::string* error, const CurveClient& curve) {
  zmq::socket_t s(context, zmq::socket_type::dealer);
  s.set(zmq::sockopt::linger, 0);
  apply_curve(s, curve);
  s.connect(endpoint);
  v1::ClientMessage m;
  m.set_protocol_version(kProtocolVersion);
  m.mutable_control()->set_kind(kind);
  m.mutable_control()->set_sequence(1);
  const std::string bytes = m.SerializeAsString();
  if (!s.send(zmq::buffer(bytes), zmq::send_flags::dontwait)) {
    *error = "cannot queue the control request to " + endpoint;
    return false;
  }
  const std::int64_t deadline = now_ns() + static_cast<std::int64_t>(timeout_ms) * 1'000'000;
  zmq::message_t in;
  while (wait_readable(s, deadline)) {
    if (!s.recv(in, zmq::recv_flags::dontwait)) continue;
    if (in.size() == 0 && in.more()) continue;
    v1::ServerMessage sm;
    if (!sm.ParseFromArray(in.data(), static_cast<int>(in.size()))) {
      *error = "malformed control reply";
      return false;
    }
    if (sm.has_error()) {
      *error = "server error: " + sm.error().message();
      return false;
    }
    if (!sm.has_control_reply()) continue;
    *reply = sm.control_reply();
    if (!reply->ok()) {
      *error = "request refused: " + reply->message();
      return false;
    }
    return true;
  }
  *error = "no control reply from " + endpoint + " within " + std::to_string(timeout_ms) + " ms";
  return false;
}

std::string describe_stats(const v1::LoopStats& s) {
  char buf[1024];
  std::snprintf(buf, sizeof buf,
                "server loop: %llu ticks at %.0f Hz, missed ticks %llu, window %u ticks\n"
                "  tick lateness  p50 %.1f us  p99 %.1f us  max %.1f us\n"
                "  step cost      p50 %.1f us  p99 %.1f us  max %.1f us\n"
                "  input stage    p50 %.1f us  p99 %.1f us; publish p50 %.1f us  p99 %.1f us\n"
                "  probes received %llu, replies sent %llu, dropped %llu, held %llu, client errors "
                "%llu, rollbacks %llu",
                static_cast<unsigned long long>(s.ticks()), s.rate_hz(),
                static_cast<unsigned long long>(s.missed_ticks()), s.window(), s.lateness_p50_us(),
                s.lateness_p99_us(), s.lateness_max_us(), s.step_p50_us(), s.step_p99_us(),
                s.step_max_us(), s.input_p50_us(), s.input_p99_us(), s.publish_p50_us(),
                s.publish_p99_us(), static_cast<unsigned long long>(s.probes_received()),
                static_cast<unsigned long long>(s.replies_sent()),
                static_cast<unsigned long long>(s.replies_dropped()),
                static_cast<unsigned long long>(s.replies_held()),
                static_cast<unsigned long long>(s.errors()),
                static_cast<unsigned long long>(s.rollbacks()));
  std::string out = buf;
  if (s.body_steps() > 0) {
    std::snprintf(buf, sizeof buf,
                  "\n  body thread    %llu steps, %llu late ticks, %llu estimated answers, %llu "
                  "proxy fallbacks, %llu factorisations, %llu rollbacks, last step %.0f us",
                  static_cast<unsigned long long>(s.body_steps()),
                  static_cast<unsigned long long>(s.body_late_ticks()),
                  static_cast<unsigned long long>(s.body_estimates()),
                  static_cast<unsigned long long>(s.body_proxy_fallbacks()),
                  static_cast<unsigned long long>(s.body_factorizations()),
                  static_cast<unsigned long long>(s.body_rollbacks()), s.body_step_us());
    out += buf;
  }
  return out;
}

}  // namespace conica::client
