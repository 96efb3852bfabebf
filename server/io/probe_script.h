// Probe trajectories from CSV, the one parser for the server (conica-lab run, the fuzz target)
// and the clients (conica-probe --trajectory):
//
//   # comment lines and blank lines are skipped
//   t,probe,x,y,z          header (required by default; optional for the clients)
//   0.0,0,0.02,0.02,0.05   t in seconds, 0-based probe index, position in metres (or, for
//                          relative scripts, fractions of the body's bounding box)
//
// Per probe, time must increase (strictly by default; the clients allow repeated times). Errors
// name the file, line and column of the offending field: "moves.csv:7:12: field y: \"abc\" is
// not a finite number".
//
// As keyframes (ProbeScript): between keyframes the position is interpolated linearly; before a
// probe's first keyframe it is absent, after its last it holds.
#pragma once

#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "core/mesh.h"
#include "io/result.h"

namespace conica::io {

// One data row of the CSV, in file order.
struct ProbeScriptRow {
  double t = 0;           // s
  int probe = 0;          // 0-based probe index
  Vec3 x = Vec3::Zero();  // m (or fractions of the bounding box for relative scripts)
  int line = 0;           // 1-based line in the file
};

struct ProbeScriptFormat {
  // Required: the first non-comment line must be exactly t,probe,x,y,z. Optional: a first line
  // that starts with 't' is taken as the header and skipped.
  bool header_required = true;
  // Per probe: t must increase (true) or only not go backwards (false).
  bool strictly_increasing = true;
  int max_probe = 63;  // largest probe index accepted
  // |x|, |y|, |z| above this are refused as "not in metres" (a millimetre file); infinity: no
  // check.
  double max_abs_position_m = std::numeric_limits<double>::infinity();
};

// The conica-probe --trajectory format: optional header, repeated times allowed, any probe
// index up to 10^6, positions within 100 m of the origin.
ProbeScriptFormat client_trajectory_format();

Result<std::vector<ProbeScriptRow>> parse_probe_rows(std::string_view text, const std::string& name,
                                                     const ProbeScriptFormat& format = {});
// "path: cannot open probe script" when the file cannot be read.
Result<std::vector<ProbeScriptRow>> read_probe_rows(const std::string& path,
                                                    const ProbeScriptFormat& format = {});

struct Keyframe {
  double t = 0;  // s
  Vec3 x = Vec3::Zero();
};

struct ProbeScript {
  std::vector<std::vector<Keyframe>> probes;  // per probe index, sorted by t

  // Position of `probe` at time t; false if it is not present yet.
  bool position(int probe, double t, Vec3* x) const;
  double end_time() const;
};

// The default format (header required, strictly increasing times, probes 0..63) as keyframes.
Result<ProbeScript> parse_probe_script(std::string_view text, const std::string& name);
Result<ProbeScript> read_probe_script(const std::string& path);

// Maps fractions of [lo, hi] to positions: x = lo + f (hi - lo), per axis.
void make_absolute(ProbeScript& script, const Vec3& lo, const Vec3& hi);

}  // namespace conica::io
