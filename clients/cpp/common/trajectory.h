// What a scripted probe does over time: a CSV trajectory or one of the built-in scripts.
//
// CSV trajectory: one row per knot, `t,probe,x,y,z` (s, 0-based probe index, m), read by the
// server's probe-script parser (server/io/probe_script.h) in its client format: an optional
// header line starting with "t", '#' comments and blank lines are skipped, per probe time must
// not go backwards, positions within 100 m (a millimetre file is refused). Errors name the file,
// line and column: "moves.csv:7:9: expected 5 fields ...".
//
// Scripts move a probe along `axis` (unit vector, the pressing direction) through the contact
// point `at` (the probe centre at depth 0). The signed depth d(t) (m, > 0 into the tissue) gives
//   position(t) = at + d(t) axis (+ a lateral offset for sweep)
//   press  d: -approach -> depth at `speed`, then hold for `hold` s
//   ramp   d: -approach -> depth -> -approach at `speed` (load, unload)
//   sine   d: -approach -> 0 at `speed`, then d = depth/2 (1 - cos(2 pi freq t)) for `cycles`
//   sweep  d: -approach -> depth at `speed`, slide `length` m along `sweep_dir` at `speed`,
//          then back out to -approach
//   creep  load-controlled hold: approach at `speed` until the normal force n = -F . axis
//          reaches target_force, then integral control d' = gain (target_force - n) (|d'| <=
//          speed, d <= depth) for `hold` s; the depth drifts as the tissue creeps
// Samples come every dt seconds of script time.
#pragma once

#include <istream>
#include <memory>
#include <string>
#include <vector>

#include "common/types.h"

namespace conica::client {

struct TrajectoryRow {
  double t = 0;   // s
  int probe = 0;  // probe index in the scene
  Vec3 position;  // m
  int line = 0;   // 1-based line in the file
};

// Parses CSV rows; on error returns false and sets `error` to "name:line:column: what".
bool parse_trajectory(std::istream& in, const std::string& name, std::vector<TrajectoryRow>* rows,
                      std::string* error);
bool load_trajectory(const std::string& path, std::vector<TrajectoryRow>* rows, std::string* error);

// The latest reply a source may react to.
struct Feedback {
  double t = 0;               // s, script time of the sample it answers
  Vec3 force = Vec3::Zero();  // N on the probe
  bool contact = false;
};

struct Sample {
  double t = 0;   // s, script time
  Vec3 position;  // m
};

// Produces one probe's samples in order. `last` is the latest reply for this probe (null before
// the first). Returns false when the source has ended.
class ProbeSource {
 public:
  virtual ~ProbeSource() = default;
  virtual bool next(const Feedback* last, Sample* out) = 0;
};

struct ScriptParams {
  Vec3 at = Vec3(0.02, 0.02, 0.045);  // m, probe centre at depth 0 (builtin cube: top face + 5 mm)
  Vec3 axis = Vec3(0, 0, -1);         // unit, pressing direction
  double depth = 0.005;               // m
  double approach = 0.005;            // m, start this far outside
  double speed = 0.01;                // m/s
  double hold = 1.0;                  // s
  double freq = 1.0;                  // Hz (sine)
  double cycles = 3;                  // sine
  double length = 0.01;               // m (sweep)
  Vec3 sweep_dir = Vec3(1, 0, 0);     // unit (sweep); made perpendicular to axis
  double target_force = 0.5;          // N (creep)
  double gain = 0.01;                 // m/(N s) (creep)
  double dt = 1e-3;                   // s between samples
};

std::vector<std::string> script_names();

// A built-in script; null with `error` set when the name or a parameter is bad.
std::unique_ptr<ProbeSource> make_script(const std::string& name, const ScriptParams& params,
                                         std::string* error);

// Replays the rows of one probe (in file order) as knots: every row is sent, and between two rows
// further apart than dt (s) samples every dt follow the straight line between them, as the lab's
// probe scripts do (server/io/probe_script.h). dt <= 0 sends the rows alone.
std::unique_ptr<ProbeSource> make_replay(std::vector<TrajectoryRow> rows_of_probe, double dt);

}  // namespace conica::client
