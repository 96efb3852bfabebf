#include "net/codec.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace conica::net {
namespace {

void set_vec(const Vec3& v, v1::Vec3* out) {
  out->set_x(v.x());
  out->set_y(v.y());
  out->set_z(v.z());
}

bool finite(const v1::Vec3& v) {
  return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z());
}

bool fail(DecodeError* err, ErrorKind kind, const char* message, std::uint64_t sequence = 0) {
  err->kind = kind;
  err->message = message;
  err->sequence = sequence;
  return false;
}

}  // namespace

const char* error_kind_name(ErrorKind kind) {
  switch (kind) {
    case ErrorKind::kMalformed:
      return "malformed";
    case ErrorKind::kWrongType:
      return "wrong type";
    case ErrorKind::kTooLarge:
      return "too large";
    case ErrorKind::kBadValue:
      return "bad value";
    case ErrorKind::kUnknownProbe:
      return "unknown probe";
    case ErrorKind::kUnsupportedVersion:
      return "unsupported version";
    case ErrorKind::kBadRequest:
      return "bad request";
  }
  return "?";
}

bool parse_client(const void* data, std::size_t size, std::size_t max_bytes, v1::ClientMessage* msg,
                  DecodeError* err) {
  if (size > max_bytes) return fail(err, ErrorKind::kTooLarge, "message larger than the limit");
  if (size == 0) return fail(err, ErrorKind::kMalformed, "empty message");
  if (size > static_cast<std::size_t>(std::numeric_limits<int>::max()) ||
      !msg->ParseFromArray(data, static_cast<int>(size)))
    return fail(err, ErrorKind::kMalformed, "not a ClientMessage");
  if (msg->protocol_version() != kProtocolVersion)
    return fail(err, ErrorKind::kUnsupportedVersion, "protocol_version must be 1");
  return true;
}

bool decode_probe_update(const v1::ClientMessage& msg, ProbeInput* out, DecodeError* err) {
  if (msg.body_case() != v1::ClientMessage::kProbe)
    return fail(err, ErrorKind::kWrongType, "the probe socket takes ClientMessage{probe} only");
  const v1::ProbeUpdate& p = msg.probe();
  const std::uint64_t seq = p.sequence();
  // A message of another type can parse as a ProbeUpdate whose fields all went to unknown
  // fields; a probe update always carries a position.
  if (!p.has_position())
    return fail(err, ErrorKind::kBadRequest, "probe update without position", seq);
  if (p.has_velocity() && !finite(p.velocity()))
    return fail(err, ErrorKind::kBadValue, "probe velocity is NaN or Inf", seq);
  const v1::Vec3& x = p.position();
  out->client_id = p.client_id();
  // Ids beyond int range stay out of range (check_probe refuses them).
  out->probe_id = static_cast<int>(std::min<std::uint32_t>(p.probe_id(), 0x7fffffff));
  out->sequence = seq;
  out->send_time_ns = p.send_time_ns();
  out->position = Vec3(x.x(), x.y(), x.z());
  out->radius = p.radius();
  return true;
}

bool decode_probe(const v1::ClientMessage& msg, const ProbeLimits& lim, ProbeInput* out,
                  DecodeError* err) {
  return decode_probe_update(msg, out, err) && loop::check_probe(*out, lim, err);
}

bool decode_control(const v1::ClientMessage& msg, const v1::ControlRequest** out,
                    DecodeError* err) {
  if (msg.body_case() != v1::ClientMessage::kControl)
    return fail(err, ErrorKind::kWrongType, "the control socket takes ClientMessage{control} only");
  const v1::ControlRequest& c = msg.control();
  if (!v1::ControlRequest::Kind_IsValid(c.kind()) ||
      c.kind() == v1::ControlRequest::KIND_UNSPECIFIED)
    return fail(err, ErrorKind::kBadRequest, "unknown control kind", c.sequence());
  *out = &c;
  return true;
}

void to_command(const v1::ControlRequest& req, loop::ControlRequest* out) {
  using K = v1::ControlRequest;
  out->sequence = req.sequence();
  switch (req.kind()) {
    case K::LOAD_SCENE:
      out->command = loop::LoadScene{req.text()};
      return;
    case K::RESET:
      out->command = loop::Reset{};
      return;
    case K::PAUSE:
      out->command = loop::Pause{};
      return;
    case K::RESUME:
      out->command = loop::Resume{};
      return;
    case K::SET_PARAMETER:
      out->command = loop::SetParameter{loop::parameter_from_name(req.name()), req.value()};
      return;
    case K::GET_MESH:
      out->command = loop::GetMesh{};
      return;
    default:  // GET_STATS (decode_control refuses unknown kinds)
      out->command = loop::GetStats{};
  }
}

void encode_stats(const LoopStatsData& s, const Counters& c, v1::LoopStats* out) {
  out->set_ticks(s.ticks);
  out->set_missed_ticks(s.missed_ticks);
  out->set_rate_hz(s.rate_hz);
  out->set_lateness_p50_us(s.lateness_p50_us);
  out->set_lateness_p99_us(s.lateness_p99_us);
  out->set_lateness_max_us(s.lateness_max_us);
  out->set_step_p50_us(s.step_p50_us);
  out->set_step_p99_us(s.step_p99_us);
  out->set_step_max_us(s.step_max_us);
  out->set_input_p50_us(s.input_p50_us);
  out->set_input_p99_us(s.input_p99_us);
  out->set_publish_p50_us(s.publish_p50_us);
  out->set_publish_p99_us(s.publish_p99_us);
  out->set_body_steps(s.body.steps);
  out->set_body_late_ticks(s.body.late_ticks);
  out->set_body_estimates(s.body.estimates);
  out->set_body_factorizations(s.body.factorizations);
  out->set_body_step_us(s.body.step_us);
  out->set_body_proxy_fallbacks(s.body.proxy_fallbacks);
  out->set_body_rollbacks(s.body.rollbacks);
  out->set_rollbacks(c.rollbacks);
  out->set_nan_events(c.nan_events);
  out->set_speed_events(c.speed_events);
  out->set_hard_stops(c.hard_stops);
  out->set_errors(s.errors);
  out->set_probes_received(s.probes_received);
  out->set_replies_sent(s.replies_sent);
  out->set_replies_dropped(s.replies_dropped);
  out->set_replies_held(s.replies_held);
  out->set_paused(s.paused);
  out->set_window(s.window);
  auto* codes = out->mutable_errors_by_code();
  codes->Resize(kNumErrorCodes, 0);  // keeps capacity: no allocation after the first frame
  for (int k = 0; k < kNumErrorCodes; ++k) codes->Set(k, s.errors_by_code[k]);
  auto* stages = out->mutable_stage_ns();
  stages->Resize(kNumStages, 0);
  for (int k = 0; k < kNumStages; ++k) stages->Set(k, c.stage_ns[k]);
}

void encode_force(const ProbeInput& in, const ProbeState& probe, std::uint64_t tick,
                  std::uint64_t recv_ns, std::uint64_t reply_ns, v1::ServerMessage* out) {
  out->set_protocol_version(kProtocolVersion);
  v1::ForceReply* f = out->mutable_force();
  f->set_client_id(in.client_id);
  f->set_probe_id(static_cast<std::uint32_t>(in.probe_id));
  f->set_sequence(in.sequence);
  f->set_client_send_time_ns(in.send_time_ns);
  f->set_server_recv_time_ns(recv_ns);
  f->set_server_reply_time_ns(reply_ns);
  f->set_tick(tick);
  set_vec(probe.force, f->mutable_force());
  auto* k = f->mutable_stiffness()->mutable_m();
  k->Resize(9, 0.0);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) k->Set(3 * r + c, probe.stiffness(r, c));
  f->set_contact(probe.contacts > 0);
  set_vec(probe.center, f->mutable_position());
}

void encode_error(const DecodeError& err, v1::ServerMessage* out) {
  out->set_protocol_version(kProtocolVersion);
  v1::Error* e = out->mutable_error();
  e->set_code(static_cast<v1::Error::Code>(err.kind));
  e->set_message(err.message);
  e->set_sequence(err.sequence);
}

void encode_state(const Model& model, const State& state, bool with_positions,
                  const LoopStatsData& stats, v1::ServerMessage* out) {
  out->set_protocol_version(kProtocolVersion);
  v1::StateFrame* f = out->mutable_state();
  f->set_tick(state.tick);
  f->set_time(state.time);
  f->set_num_nodes(static_cast<std::uint32_t>(model.num_nodes()));
  auto* pos = f->mutable_positions();
  if (with_positions) {
    const int n = model.num_nodes();
    pos->Resize(3 * n, 0.0f);
    float* p = pos->mutable_data();
    for (int i = 0; i < n; ++i)
      for (int a = 0; a < 3; ++a) p[3 * i + a] = static_cast<float>(state.x[i][a]);
  } else {
    pos->Clear();  // keeps capacity
  }
  auto* probes = f->mutable_probes();
  const int np = static_cast<int>(state.probes.size());
  while (probes->size() > np) probes->RemoveLast();
  while (probes->size() < np) probes->Add();
  for (int k = 0; k < np; ++k) {
    v1::ProbeForce* pf = probes->Mutable(k);
    const ProbeState& ps = state.probes[k];
    pf->set_probe_id(static_cast<std::uint32_t>(k));
    set_vec(ps.center, pf->mutable_position());
    set_vec(ps.force, pf->mutable_force());
    pf->set_contact(ps.contacts > 0);
  }
  encode_stats(stats, state.counters, f->mutable_stats());
}

void encode_mesh(const Model& model, v1::ControlReply* out) {
  out->set_num_nodes(static_cast<std::uint32_t>(model.num_nodes()));
  auto* tri = out->mutable_triangles();
  tri->Clear();
  tri->Reserve(static_cast<int>(3 * model.surface.size()));
  for (const auto& t : model.surface)
    for (int i : t) tri->Add(static_cast<std::uint32_t>(i));
  auto* rest = out->mutable_rest_positions();
  rest->Clear();
  rest->Reserve(3 * model.num_nodes());
  for (const Vec3& x : model.rest)
    for (int a = 0; a < 3; ++a) rest->Add(static_cast<float>(x[a]));
}

void encode_control_result(const loop::ControlResult& r, v1::ServerMessage* out) {
  out->set_protocol_version(kProtocolVersion);
  v1::ControlReply* reply = out->mutable_control_reply();
  reply->Clear();  // the control path may allocate
  reply->set_sequence(r.sequence);
  reply->set_ok(r.ok);
  reply->set_message(r.message);
  if (r.mesh) encode_mesh(*r.mesh, reply);
  encode_stats(r.stats, r.counters, reply->mutable_stats());
  reply->set_num_nodes(r.num_nodes);
}

}  // namespace conica::net
