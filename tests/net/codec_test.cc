// The codec: every rejection path of a probe update and a control request, the body box, and
// that encoders fill what the wire promises.
#include "net/codec.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "core/body.h"
#include "net/builtin_scenes.h"

namespace conica::net {
namespace {

v1::ClientMessage Probe(double x, double y, double z) {
  v1::ClientMessage m;
  m.set_protocol_version(1);
  auto* p = m.mutable_probe();
  p->set_sequence(42);
  p->set_client_id(3);
  p->mutable_position()->set_x(x);
  p->mutable_position()->set_y(y);
  p->mutable_position()->set_z(z);
  return m;
}

ProbeLimits Limits() {
  ProbeLimits l;
  l.box_min = Vec3(-1, -1, -1);
  l.box_max = Vec3(1, 1, 1);
  l.num_probes = 1;
  return l;
}

ErrorKind DecodeKind(const v1::ClientMessage& m, const ProbeLimits& l = Limits()) {
  ProbeInput in;
  DecodeError err;
  EXPECT_FALSE(decode_probe(m, l, &in, &err));
  return err.kind;
}

TEST(CodecTest, GoodProbeDecodes) {
  ProbeInput in;
  DecodeError err;
  v1::ClientMessage m = Probe(0.1, 0.2, 0.3);
  m.mutable_probe()->set_radius(0.01);
  ASSERT_TRUE(decode_probe(m, Limits(), &in, &err)) << err.message;
  EXPECT_EQ(in.sequence, 42u);
  EXPECT_EQ(in.client_id, 3u);
  EXPECT_EQ(in.position, Vec3(0.1, 0.2, 0.3));
  EXPECT_EQ(in.radius, 0.01);
}

TEST(CodecTest, RejectsBadProbeValues) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_EQ(DecodeKind(Probe(nan, 0, 0)), ErrorKind::kBadValue);
  EXPECT_EQ(DecodeKind(Probe(0, inf, 0)), ErrorKind::kBadValue);
  EXPECT_EQ(DecodeKind(Probe(0, 0, -inf)), ErrorKind::kBadValue);
  ProbeLimits wide = Limits();
  wide.box_min = Vec3::Constant(-1e12);
  wide.box_max = Vec3::Constant(1e12);
  EXPECT_EQ(DecodeKind(Probe(0, 0, 1e9), wide), ErrorKind::kBadValue);  // |x| > 1e3 m
  EXPECT_EQ(DecodeKind(Probe(0, 0, 1.5)), ErrorKind::kBadValue);        // outside the box
  for (double r : {-1e-3, 1.5, nan, inf}) {
    v1::ClientMessage m = Probe(0, 0, 0);
    m.mutable_probe()->set_radius(r);
    EXPECT_EQ(DecodeKind(m), ErrorKind::kBadValue) << r;
  }
  v1::ClientMessage v = Probe(0, 0, 0);
  v.mutable_probe()->mutable_velocity()->set_x(nan);
  EXPECT_EQ(DecodeKind(v), ErrorKind::kBadValue);
  v1::ClientMessage unknown = Probe(0, 0, 0);
  unknown.mutable_probe()->set_probe_id(1);
  EXPECT_EQ(DecodeKind(unknown), ErrorKind::kUnknownProbe);
  v1::ClientMessage nopos;
  nopos.set_protocol_version(1);
  nopos.mutable_probe()->set_sequence(5);
  ProbeInput in;
  DecodeError err;
  EXPECT_FALSE(decode_probe(nopos, Limits(), &in, &err));
  EXPECT_EQ(err.kind, ErrorKind::kBadRequest);
  EXPECT_EQ(err.sequence, 5u);  // echoed
}

TEST(CodecTest, ParseChecksSizeBytesAndVersion) {
  v1::ClientMessage msg;
  DecodeError err;
  std::string good = Probe(0, 0, 0).SerializeAsString();
  EXPECT_TRUE(parse_client(good.data(), good.size(), 1024, &msg, &err));
  EXPECT_FALSE(parse_client(good.data(), good.size(), good.size() - 1, &msg, &err));
  EXPECT_EQ(err.kind, ErrorKind::kTooLarge);
  EXPECT_FALSE(parse_client("", 0, 1024, &msg, &err));
  EXPECT_EQ(err.kind, ErrorKind::kMalformed);
  const char garbage[] = "\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff";
  EXPECT_FALSE(parse_client(garbage, sizeof garbage, 1024, &msg, &err));
  EXPECT_EQ(err.kind, ErrorKind::kMalformed);
  v1::ClientMessage v2 = Probe(0, 0, 0);
  v2.set_protocol_version(2);
  std::string s2 = v2.SerializeAsString();
  EXPECT_FALSE(parse_client(s2.data(), s2.size(), 1024, &msg, &err));
  EXPECT_EQ(err.kind, ErrorKind::kUnsupportedVersion);
}

TEST(CodecTest, ServerMessagesSentAsRequestsAreRefused) {
  // A ForceReply parses as a ClientMessage{probe} whose fields are all unknown: no position.
  v1::ServerMessage force;
  force.set_protocol_version(1);
  force.mutable_force()->set_sequence(9);
  force.mutable_force()->mutable_force()->set_z(1);
  force.mutable_force()->mutable_position()->set_z(1);
  v1::ServerMessage state;
  state.set_protocol_version(1);
  state.mutable_state()->set_tick(3);
  for (const v1::ServerMessage& sm : {force, state}) {
    const std::string bytes = sm.SerializeAsString();
    v1::ClientMessage msg;
    DecodeError err;
    ProbeInput in;
    const bool ok = parse_client(bytes.data(), bytes.size(), 1024, &msg, &err) &&
                    decode_probe(msg, Limits(), &in, &err);
    EXPECT_FALSE(ok);
  }
}

TEST(CodecTest, ControlNeedsAKnownKindOnTheControlSocket) {
  const v1::ControlRequest* req = nullptr;
  DecodeError err;
  EXPECT_FALSE(decode_control(Probe(0, 0, 0), &req, &err));
  EXPECT_EQ(err.kind, ErrorKind::kWrongType);
  v1::ClientMessage c;
  c.set_protocol_version(1);
  c.mutable_control()->set_kind(static_cast<v1::ControlRequest::Kind>(99));
  EXPECT_FALSE(decode_control(c, &req, &err));
  EXPECT_EQ(err.kind, ErrorKind::kBadRequest);
  c.mutable_control()->set_kind(v1::ControlRequest::GET_STATS);
  EXPECT_TRUE(decode_control(c, &req, &err));
  EXPECT_EQ(req, &c.control());
  ProbeInput in;
  EXPECT_FALSE(decode_probe(c, Limits(), &in, &err));
  EXPECT_EQ(err.kind, ErrorKind::kWrongType);
}

TEST(CodecTest, BodyBoxAndStateFrame) {
  BodySpec spec;
  ASSERT_EQ(builtin_scene("cube", 1e-3, &spec), "");
  Model model;
  ASSERT_EQ(build_model(spec, &model), "");
  ProbeLimits l;
  body_box(model, 0.1, &l);
  EXPECT_TRUE(l.box_min.isApprox(Vec3(-0.1, -0.1, -0.1)));
  EXPECT_TRUE(l.box_max.isApprox(Vec3(0.14, 0.14, 0.14)));
  EXPECT_EQ(l.num_probes, 1);

  State state = make_state(model);
  state.tick = 17;
  state.probes[0].force = Vec3(1, 2, 3);
  LoopStatsData stats;
  stats.ticks = 5;
  stats.errors_by_code[4] = 2;
  stats.body.steps = 7;
  stats.body.late_ticks = 2;
  stats.body.estimates = 3;
  stats.body.factorizations = 4;
  stats.body.rollbacks = 1;
  stats.body.proxy_fallbacks = 6;
  stats.body.step_us = 812.5;
  v1::ServerMessage msg;
  for (bool positions : {true, false, true}) {  // reuse: fields are overwritten, not appended
    encode_state(model, state, positions, stats, &msg);
    const v1::StateFrame& f = msg.state();
    EXPECT_EQ(f.tick(), 17u);
    EXPECT_EQ(f.num_nodes(), 320u);
    EXPECT_EQ(f.positions_size(), positions ? 960 : 0);
    ASSERT_EQ(f.probes_size(), 1);
    EXPECT_EQ(f.probes(0).force().z(), 3);
    EXPECT_EQ(f.stats().ticks(), 5u);
    ASSERT_EQ(f.stats().errors_by_code_size(), kNumErrorCodes);
    EXPECT_EQ(f.stats().errors_by_code(4), 2u);
    EXPECT_EQ(f.stats().body_steps(), 7u);
    EXPECT_EQ(f.stats().body_late_ticks(), 2u);
    EXPECT_EQ(f.stats().body_estimates(), 3u);
    EXPECT_EQ(f.stats().body_factorizations(), 4u);
    EXPECT_EQ(f.stats().body_rollbacks(), 1u);
    EXPECT_EQ(f.stats().body_proxy_fallbacks(), 6u);
    EXPECT_EQ(f.stats().body_step_us(), 812.5);
  }
  EXPECT_FLOAT_EQ(msg.state().positions(3 * 319 + 2), 0.04f);  // last node: the top corner
}

}  // namespace
}  // namespace conica::net
