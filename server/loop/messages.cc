#include "loop/messages.h"

#include <cmath>
#include <limits>

namespace conica::loop {
namespace {

bool fail(Rejection* why, ErrorKind kind, const char* message, std::uint64_t sequence) {
  why->kind = kind;
  why->message = message;
  why->sequence = sequence;
  return false;
}

constexpr std::array<std::pair<Parameter, const char*>, 5> kParameterNames = {{
    {Parameter::kDamping, "damping"},
    {Parameter::kGravityX, "gravity_x"},
    {Parameter::kGravityY, "gravity_y"},
    {Parameter::kGravityZ, "gravity_z"},
    {Parameter::kPositionsHz, "positions_hz"},
}};

}  // namespace

void body_box(const Model& model, double margin, ProbeLimits* limits) {
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity());
  Vec3 hi = -lo;
  for (const Vec3& x : model.rest) {
    lo = lo.cwiseMin(x);
    hi = hi.cwiseMax(x);
  }
  if (model.rest.empty()) lo = hi = Vec3::Zero();
  limits->box_min = lo - Vec3::Constant(margin);
  limits->box_max = hi + Vec3::Constant(margin);
  limits->num_probes = static_cast<int>(model.probes.size());
}

bool check_probe(const ProbeUpdate& p, const ProbeLimits& lim, Rejection* why) {
  const std::uint64_t seq = p.sequence;
  if (p.probe_id < 0 || p.probe_id >= lim.num_probes)
    return fail(why, ErrorKind::kUnknownProbe, "no probe with this probe_id in the scene", seq);
  const Vec3& c = p.position;
  if (!c.allFinite()) return fail(why, ErrorKind::kBadValue, "probe position is NaN or Inf", seq);
  if (c.cwiseAbs().maxCoeff() > lim.max_abs_position)
    return fail(why, ErrorKind::kBadValue, "probe position is absurdly far (> 1e3 m)", seq);
  if ((c.array() < lim.box_min.array()).any() || (c.array() > lim.box_max.array()).any())
    return fail(why, ErrorKind::kBadValue, "probe position outside the box around the body", seq);
  const double r = p.radius;
  if (!std::isfinite(r) || r < 0 || r > lim.max_radius)
    return fail(why, ErrorKind::kBadValue, "probe radius must be in (0, 1] m (0 keeps the scene's)",
                seq);
  return true;
}

const char* parameter_name(Parameter p) {
  for (const auto& [q, name] : kParameterNames)
    if (q == p) return name;
  return "?";
}

Parameter parameter_from_name(std::string_view name) {
  for (const auto& [q, n] : kParameterNames)
    if (name == n) return q;
  return Parameter::kUnknown;
}

}  // namespace conica::loop
