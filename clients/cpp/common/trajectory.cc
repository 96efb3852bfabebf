#include "common/trajectory.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

#include "io/probe_script.h"

namespace conica::client {

bool parse_trajectory(std::istream& in, const std::string& name, std::vector<TrajectoryRow>* rows,
                      std::string* error) {
  rows->clear();
  std::ostringstream text;
  text << in.rdbuf();
  auto parsed = io::parse_probe_rows(text.str(), name, io::client_trajectory_format());
  if (!parsed) {
    *error = parsed.error();
    return false;
  }
  rows->reserve(parsed.value().size());
  for (const io::ProbeScriptRow& r : parsed.value()) rows->push_back({r.t, r.probe, r.x, r.line});
  return true;
}

bool load_trajectory(const std::string& path, std::vector<TrajectoryRow>* rows,
                     std::string* error) {
  std::ifstream f(path, std::ios::binary);
  if (!f) {
    *error = path + ": cannot open";
    return false;
  }
  return parse_trajectory(f, path, rows, error);
}

namespace {

// A script given as signed depth d(t) and lateral offset s(t) along sweep_dir.
class DepthScript : public ProbeSource {
 public:
  DepthScript(const ScriptParams& p, std::string kind) : p_(p), kind_(std::move(kind)) {
    const double a = p.approach, d = p.depth, v = p.speed;
    t_in_ = (a + d) / v;
    if (kind_ == "press") {
      end_ = t_in_ + p.hold;
    } else if (kind_ == "ramp") {
      end_ = 2 * t_in_;
    } else if (kind_ == "sine") {
      t_in_ = a / v;
      end_ = t_in_ + p.cycles / p.freq;
    } else {  // sweep
      end_ = t_in_ + p.length / v + t_in_;
    }
  }

  bool next(const Feedback*, Sample* out) override {
    const double t = k_ * p_.dt;
    if (t > end_ + 1e-12) return false;
    ++k_;
    double d = 0, s = 0;
    const double a = p_.approach, v = p_.speed;
    if (kind_ == "press") {
      d = t < t_in_ ? -a + v * t : p_.depth;
    } else if (kind_ == "ramp") {
      d = t < t_in_ ? -a + v * t : p_.depth - v * (t - t_in_);
    } else if (kind_ == "sine") {
      d = t < t_in_ ? -a + v * t
                    : 0.5 * p_.depth * (1 - std::cos(2 * M_PI * p_.freq * (t - t_in_)));
    } else {
      const double t_slide = p_.length / v;
      if (t < t_in_) {
        d = -a + v * t;
      } else if (t < t_in_ + t_slide) {
        d = p_.depth;
        s = v * (t - t_in_);
      } else {
        d = p_.depth - v * (t - t_in_ - t_slide);
        s = p_.length;
      }
    }
    out->t = t;
    out->position = p_.at + d * p_.axis + s * p_.sweep_dir;
    return true;
  }

 private:
  ScriptParams p_;
  std::string kind_;
  double t_in_ = 0, end_ = 0;
  long k_ = 0;
};

// Force-controlled hold (see the header).
class CreepScript : public ProbeSource {
 public:
  explicit CreepScript(const ScriptParams& p) : p_(p), d_(-p.approach) {}

  bool next(const Feedback* last, Sample* out) override {
    const double t = k_ * p_.dt;
    const double n = last ? -last->force.dot(p_.axis) : 0.0;  // N, pushing back along -axis
    if (!holding_ && n >= p_.target_force) {
      holding_ = true;
      t_hold_ = t;
    }
    if (holding_ && t - t_hold_ > p_.hold) return false;
    if (!holding_ && d_ >= p_.depth) {  // never reached the target: hold at the depth limit
      holding_ = true;
      t_hold_ = t;
    }
    if (k_ > 0) {
      double rate = holding_ ? p_.gain * (p_.target_force - n) : p_.speed;
      rate = std::clamp(rate, -p_.speed, p_.speed);
      d_ = std::min(p_.depth, d_ + rate * p_.dt);
    }
    ++k_;
    out->t = t;
    out->position = p_.at + d_ * p_.axis;
    return true;
  }

 private:
  ScriptParams p_;
  double d_;
  bool holding_ = false;
  double t_hold_ = 0;
  long k_ = 0;
};

class Replay : public ProbeSource {
 public:
  Replay(std::vector<TrajectoryRow> rows, double dt) : rows_(std::move(rows)), dt_(dt) {}
  bool next(const Feedback*, Sample* out) override {
    if (k_ >= rows_.size()) return false;
    // The next row when it is at most one sample period ahead (a hair of slack for round-off),
    // otherwise one period further along the straight line to it.
    if (k_ == 0 || !(dt_ > 0) || rows_[k_].t - t_ <= dt_ * (1 + 1e-9)) {
      t_ = rows_[k_].t;
      out->t = t_;
      out->position = rows_[k_].position;
      ++k_;
      return true;
    }
    const TrajectoryRow &a = rows_[k_ - 1], &b = rows_[k_];
    t_ += dt_;
    const double w = (t_ - a.t) / (b.t - a.t);
    out->t = t_;
    out->position = a.position + w * (b.position - a.position);
    return true;
  }

 private:
  std::vector<TrajectoryRow> rows_;
  double dt_;
  std::size_t k_ = 0;  // next row to reach
  double t_ = 0;       // s, time of the last sample
};

}  // namespace

std::vector<std::string> script_names() { return {"press", "ramp", "sine", "sweep", "creep"}; }

std::unique_ptr<ProbeSource> make_script(const std::string& name, const ScriptParams& in,
                                         std::string* error) {
  ScriptParams p = in;
  auto bad = [&](const std::string& what) -> std::unique_ptr<ProbeSource> {
    *error = name + ": " + what;
    return nullptr;
  };
  if (!(p.axis.norm() > 0)) return bad("axis must be non-zero");
  p.axis.normalize();
  if (!(p.dt > 0) || p.dt > 1) return bad("dt must be in (0, 1] s");
  if (!(p.speed > 0)) return bad("speed must be > 0 m/s");
  if (!(p.depth >= 0) || p.depth > 0.5) return bad("depth must be in [0, 0.5] m");
  if (!(p.approach >= 0) || p.approach > 0.5) return bad("approach must be in [0, 0.5] m");
  if (!(p.hold >= 0)) return bad("hold must be >= 0 s");
  if (name == "press" || name == "ramp") return std::make_unique<DepthScript>(p, name);
  if (name == "sine") {
    if (!(p.freq > 0) || !(p.cycles > 0)) return bad("freq and cycles must be > 0");
    return std::make_unique<DepthScript>(p, name);
  }
  if (name == "sweep") {
    Vec3 s = p.sweep_dir - p.sweep_dir.dot(p.axis) * p.axis;
    if (!(s.norm() > 1e-9)) return bad("sweep direction must not be parallel to the axis");
    p.sweep_dir = s.normalized();
    if (!(p.length >= 0)) return bad("length must be >= 0 m");
    return std::make_unique<DepthScript>(p, name);
  }
  if (name == "creep") {
    if (!(p.target_force > 0)) return bad("target force must be > 0 N");
    if (!(p.gain > 0)) return bad("gain must be > 0 m/(N s)");
    return std::make_unique<CreepScript>(p);
  }
  *error = "unknown script \"" + name + "\" (press, ramp, sine, sweep, creep)";
  return nullptr;
}

std::unique_ptr<ProbeSource> make_replay(std::vector<TrajectoryRow> rows_of_probe, double dt) {
  return std::make_unique<Replay>(std::move(rows_of_probe), dt);
}

}  // namespace conica::client
