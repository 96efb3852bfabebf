// What the server does with one received payload frame, on either socket: parse_client, then
// decode_probe (probe socket) -> probe contact against the built-in cube -> encode_force ->
// serialise, and decode_control (control socket) -> read the request. The same arena setup as
// the server loop (a preallocated first block, reset after each message).
#include <google/protobuf/arena.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <memory>
#include <vector>

#include "core/body.h"
#include "net/builtin_scenes.h"
#include "net/codec.h"
#include "net/probe_contact.h"

namespace {

struct Fixture {
  conica::Model model;
  conica::State state;
  conica::net::ProbeLimits limits;
  std::vector<char> block = std::vector<char>(256 * 1024);
  std::unique_ptr<google::protobuf::Arena> arena;
  conica::v1::ServerMessage reply, error;
  std::vector<std::uint8_t> out = std::vector<std::uint8_t>(64 * 1024);

  Fixture() {
    conica::BodySpec spec;
    if (!conica::net::builtin_scene("cube", 1e-3, &spec).empty() ||
        !conica::build_model(spec, &model).empty())
      std::abort();
    state = conica::make_state(model);
    conica::net::body_box(model, 0.25, &limits);
    google::protobuf::ArenaOptions ao;
    ao.initial_block = block.data();
    ao.initial_block_size = block.size();
    arena = std::make_unique<google::protobuf::Arena>(ao);
  }

  void serialise(const conica::v1::ServerMessage& m) {
    const std::size_t size = m.ByteSizeLong();
    if (out.size() < size) out.resize(size);
    m.SerializeWithCachedSizesToArray(out.data());
  }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static Fixture f;
  using namespace conica::net;
  constexpr std::size_t kMaxBytes = 64 * 1024;  // ServerOptions::max_message_bytes
  DecodeError err;
  auto* msg = google::protobuf::Arena::CreateMessage<conica::v1::ClientMessage>(f.arena.get());
  if (!parse_client(data, size, kMaxBytes, msg, &err)) {
    encode_error(err, &f.error);
    f.serialise(f.error);
    f.arena->Reset();
    return 0;
  }
  ProbeInput in;
  if (decode_probe(*msg, f.limits, &in, &err)) {
    // The server's contract: a decoded probe id indexes the scene's probes, the position is
    // finite and inside the box.
    if (in.probe_id < 0 || in.probe_id >= static_cast<int>(f.state.probes.size())) std::abort();
    if (!in.position.allFinite()) std::abort();
    conica::ProbeState& ps = f.state.probes[in.probe_id];
    const double radius = in.radius > 0 ? in.radius : ps.radius;
    probe_contact(f.model, f.state, in.probe_id, in.position, radius, &ps);
    encode_force(in, ps, 1, 2, 3, &f.reply);
    f.serialise(f.reply);
  } else {
    encode_error(err, &f.error);
    f.serialise(f.error);
  }
  const conica::v1::ControlRequest* req = nullptr;
  if (decode_control(*msg, &req, &err)) {
    if (req == nullptr) std::abort();
    volatile std::size_t n = req->name().size() + req->text().size();
    (void)n;
  }
  f.arena->Reset();
  return 0;
}
