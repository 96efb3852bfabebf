// Probe trajectories from CSV: header `t,probe,x,y,z` (seconds, 0-based probe index, metres or,
// for relative scripts, fractions of the body's bounding box), one keyframe per row, rows of a
// probe in increasing time. Between keyframes the position is interpolated linearly; before a
// probe's first keyframe it is absent, after its last it holds.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "core/mesh.h"
#include "io/result.h"

namespace conica::io {

struct Keyframe {
  double t = 0;   // s
  Vec3 x = Vec3::Zero();
};

struct ProbeScript {
  std::vector<std::vector<Keyframe>> probes;  // per probe index, sorted by t

  // Position of `probe` at time t; false if it is not present yet.
  bool position(int probe, double t, Vec3* x) const;
  double end_time() const;
};

Result<ProbeScript> parse_probe_script(std::string_view text, const std::string& name);
Result<ProbeScript> read_probe_script(const std::string& path);

// Maps fractions of [lo, hi] to positions: x = lo + f (hi - lo), per axis.
void make_absolute(ProbeScript& script, const Vec3& lo, const Vec3& hi);

}  // namespace conica::io
