#include "lab/tradeoff.h"

#include <time.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>
#include <sstream>

#include "core/conical.h"
#include "core/step.h"

namespace conica::lab {
namespace {

double thread_cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  const size_t k = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(k), v.end());
  double m = v[k];
  if (v.size() % 2 == 0)
    m = 0.5 * (m + *std::max_element(v.begin(), v.begin() + static_cast<long>(k)));
  return m;
}

// Runs `ticks` ticks: `drive(state, tick)` sets the loads before each, `read(state, ws)` gives the
// force after it (outside the timed part).
template <class Drive, class Read>
Trace run(const Model& m, long ticks, Drive drive, Read read) {
  Trace tr;
  State s = make_state(m);
  Workspace ws(m);
  std::vector<double> tick_us;
  tick_us.reserve(static_cast<size_t>(ticks));
  tr.force.reserve(static_cast<size_t>(ticks));
  const double cpu0 = thread_cpu_seconds();
  for (long k = 0; k < ticks; ++k) {
    drive(s, k);
    const auto t0 = std::chrono::steady_clock::now();
    step(m, s, ws);
    tick_us.push_back(1e6 *
                      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    tr.force.push_back(read(s, ws));
    tr.finite &= tr.force.back().allFinite();
  }
  // CPU time includes the force read-out; it is small against a tick (one force pass at most).
  tr.cpu_us_mean = ticks > 0 ? 1e6 * (thread_cpu_seconds() - cpu0) / static_cast<double>(ticks) : 0;
  tr.tick_us_median = median(tick_us);
  tr.rollbacks = s.counters.rollbacks;
  return tr;
}

}  // namespace

Trace run_compression(const Model& m, double strain, double ramp_s, long ticks) {
  double top = -std::numeric_limits<double>::infinity(), bottom = -top;
  for (const Vec3& x : m.rest) {
    top = std::max(top, x.z());
    bottom = std::min(bottom, x.z());
  }
  const double height = top - bottom;
  std::vector<int> face;
  for (int i = 0; i < m.num_nodes(); ++i)
    if (m.rest[i].z() >= top - 1e-9 * height) face.push_back(i);
  const double dt = m.options.dt;
  auto drive = [&](State& s, long k) {
    const double t = dt * static_cast<double>(k + 1);  // plate position at the end of the tick
    const double z = top - strain * height * std::min(1.0, t / ramp_s);
    for (int i : face) s.x[i].z() = z;
  };
  auto read = [&](State& s, Workspace& ws) {
    compute_forces(m, s, ws);
    double f = 0;
    for (int i : face) f += ws.force[i].z();
    return Vec3(0, 0, f);
  };
  return run(m, ticks, drive, read);
}

Trace run_indentation(const Model& m, const Vec3& at, const Vec3& axis, double depth, double ramp_s,
                      long ticks) {
  const double dt = m.options.dt;
  auto drive = [&](State& s, long k) {
    const double t = dt * static_cast<double>(k + 1);
    set_probe(s, 0, at + axis * depth * std::min(1.0, t / ramp_s));
  };
  auto read = [&](State& s, Workspace&) { return s.probes[0].force; };
  return run(m, ticks, drive, read);
}

BodySpec compression_body(const BodySpec& material, const Vec3& size,
                          const std::array<int, 3>& cells) {
  BodySpec b;
  b.mesh = make_box_lattice(size, cells);
  b.density = material.density;
  b.mapping = material.mapping;
  b.options = material.options;
  b.groups = material.groups;
  for (auto& g : b.groups) g.regions.clear();
  FixedSelector base, top;
  base.kind = top.kind = FixedSelector::Kind::kPlane;
  base.normal = top.normal = Vec3::UnitZ();
  base.offset = 0;
  top.offset = size.z();
  base.tolerance = top.tolerance = 1e-9 * size.z();
  base.axes = 7;  // clamped
  top.axes = 4;   // held in z by the plate, free to slide
  b.fixed = {base, top};
  return b;
}

BodySpec hooke_twin(const BodySpec& spec) {
  BodySpec b = spec;
  for (auto& g : b.groups) {
    SpringCard& c = g.card;
    if (c.law != LawKind::kConical) continue;
    const double k0 = c.k0();
    const double L = c.conical.L0;
    c.law = LawKind::kHooke;
    c.hooke_k = k0;
    c.hooke_length = L;
  }
  return b;
}

double force_error(const std::vector<Vec3>& f, const std::vector<Vec3>& ref) {
  const size_t n = std::min(f.size(), ref.size());
  double peak = 0, err = 0;
  for (size_t k = 0; k < n; ++k) {
    if (!f[k].allFinite() || !ref[k].allFinite()) return std::numeric_limits<double>::quiet_NaN();
    peak = std::max(peak, ref[k].norm());
    err = std::max(err, (f[k] - ref[k]).norm());
  }
  if (peak == 0) return err == 0 ? 0 : std::numeric_limits<double>::infinity();
  return err / peak;
}

double force_rms_error(const std::vector<Vec3>& f, const std::vector<Vec3>& ref) {
  const size_t n = std::min(f.size(), ref.size());
  double diff2 = 0, ref2 = 0;
  for (size_t k = 0; k < n; ++k) {
    if (!f[k].allFinite() || !ref[k].allFinite()) return std::numeric_limits<double>::quiet_NaN();
    diff2 += (f[k] - ref[k]).squaredNorm();
    ref2 += ref[k].squaredNorm();
  }
  if (ref2 == 0) return diff2 == 0 ? 0 : std::numeric_limits<double>::infinity();
  return std::sqrt(diff2 / ref2);
}

double register_principal_axes(std::vector<Vec3>* nodes, const std::vector<Vec3>& target) {
  auto frame = [](const std::vector<Vec3>& p, Vec3* c, Mat3* axes, Vec3* sd) {
    *c = Vec3::Zero();
    for (const Vec3& x : p) *c += x;
    *c /= static_cast<double>(p.size());
    Mat3 cov = Mat3::Zero();
    for (const Vec3& x : p) cov += (x - *c) * (x - *c).transpose();
    cov /= static_cast<double>(p.size());
    Eigen::SelfAdjointEigenSolver<Mat3> es(cov);
    *axes = es.eigenvectors();  // columns, ascending variance
    *sd = es.eigenvalues().cwiseMax(0).cwiseSqrt();
  };
  Vec3 cs, ct, sds, sdt;
  Mat3 as, at;
  frame(*nodes, &cs, &as, &sds);
  frame(target, &ct, &at, &sdt);
  const double scale = (sdt.array() / sds.array()).mean();
  auto mean_nearest = [&](const std::vector<Vec3>& mapped) {
    double sum = 0;
    for (const Vec3& y : target) {
      double best = std::numeric_limits<double>::infinity();
      for (const Vec3& x : mapped) best = std::min(best, (x - y).squaredNorm());
      sum += std::sqrt(best);
    }
    return sum / static_cast<double>(target.size());
  };
  double best = std::numeric_limits<double>::infinity();
  std::vector<Vec3> best_nodes;
  for (int signs = 0; signs < 8; ++signs) {
    const Vec3 sg((signs & 1) ? -1 : 1, (signs & 2) ? -1 : 1, (signs & 4) ? -1 : 1);
    const Mat3 R = at * sg.asDiagonal() * as.transpose();
    if (R.determinant() < 0) continue;  // a reflection, not a rotation
    std::vector<Vec3> mapped(nodes->size());
    for (size_t i = 0; i < nodes->size(); ++i) mapped[i] = ct + scale * R * ((*nodes)[i] - cs);
    const double d = mean_nearest(mapped);
    if (d < best) {
      best = d;
      best_nodes = std::move(mapped);
    }
  }
  *nodes = std::move(best_nodes);
  return best;
}

std::string tradeoff_csv_header() {
  return "scene,resolution,nodes,springs,integrator,newton,cg,substeps,law,step_us,error,stable,"
         "cpu_us,rollbacks,rms_error\n";
}

std::string to_csv(const TradeoffRow& r) {
  char buf[512];
  std::snprintf(buf, sizeof buf, "%s,%s,%d,%d,%s,%d,%d,%d,%s,%.4g,%.6g,%d,%.4g,%llu,%.6g\n",
                r.scene.c_str(), r.resolution.c_str(), r.nodes, r.springs, r.integrator.c_str(),
                r.newton, r.cg, r.substeps, r.law.c_str(), r.step_us, r.error, r.stable ? 1 : 0,
                r.cpu_us, static_cast<unsigned long long>(r.rollbacks), r.rms_error);
  return buf;
}

bool parse_tradeoff_csv(const std::string& text, std::vector<TradeoffRow>* rows,
                        std::string* error) {
  rows->clear();
  std::istringstream in(text);
  std::string line;
  auto split = [](const std::string& s) {
    std::vector<std::string> out;
    std::string cell;
    std::istringstream ls(s);
    while (std::getline(ls, cell, ',')) {
      while (!cell.empty() && (cell.back() == '\r' || cell.back() == ' ')) cell.pop_back();
      while (!cell.empty() && cell.front() == ' ') cell.erase(cell.begin());
      out.push_back(cell);
    }
    if (!s.empty() && s.back() == ',') out.emplace_back();
    return out;
  };
  if (!std::getline(in, line)) {
    *error = "empty: no header";
    return false;
  }
  const std::vector<std::string> header = split(line);
  std::map<std::string, size_t> col;
  for (size_t i = 0; i < header.size(); ++i) col[header[i]] = i;
  const char* required[] = {"scene", "resolution", "nodes", "springs", "integrator", "newton",
                            "cg",    "substeps",   "law",   "step_us", "error",      "stable"};
  for (const char* name : required)
    if (!col.count(name)) {
      *error = std::string("line 1: no column '") + name + "' in the header";
      return false;
    }
  int lineno = 1;
  while (std::getline(in, line)) {
    ++lineno;
    if (line.empty() || line == "\r") continue;
    const std::vector<std::string> c = split(line);
    if (c.size() < header.size()) {
      *error = "line " + std::to_string(lineno) + ": " + std::to_string(c.size()) +
               " columns, the header has " + std::to_string(header.size());
      return false;
    }
    auto num = [&](const char* name, double* v) {
      const std::string& s = c[col.at(name)];
      char* end = nullptr;
      *v = std::strtod(s.c_str(), &end);
      if (s.empty() || end != s.c_str() + s.size()) {
        *error =
            "line " + std::to_string(lineno) + ": column '" + name + "': not a number: '" + s + "'";
        return false;
      }
      return true;
    };
    TradeoffRow r;
    r.scene = c[col.at("scene")];
    r.resolution = c[col.at("resolution")];
    r.integrator = c[col.at("integrator")];
    r.law = c[col.at("law")];
    double nodes, springs, newton, cg, substeps, stable;
    if (!num("nodes", &nodes) || !num("springs", &springs) || !num("newton", &newton) ||
        !num("cg", &cg) || !num("substeps", &substeps) || !num("step_us", &r.step_us) ||
        !num("error", &r.error) || !num("stable", &stable))
      return false;
    if (col.count("cpu_us") && !num("cpu_us", &r.cpu_us)) return false;
    double rb = 0;
    if (col.count("rollbacks") && !num("rollbacks", &rb)) return false;
    if (col.count("rms_error") && !num("rms_error", &r.rms_error)) return false;
    r.nodes = static_cast<int>(nodes);
    r.springs = static_cast<int>(springs);
    r.newton = static_cast<int>(newton);
    r.cg = static_cast<int>(cg);
    r.substeps = static_cast<int>(substeps);
    r.stable = stable != 0;
    r.rollbacks = static_cast<std::uint64_t>(rb);
    if (r.substeps < 1 || r.springs < 0 || r.nodes < 0 || !(r.step_us >= 0)) {
      *error = "line " + std::to_string(lineno) + ": substeps < 1, negative count or step time";
      return false;
    }
    rows->push_back(r);
  }
  return true;
}

double front_error(const TradeoffRow& r) {
  return std::isfinite(r.rms_error) ? r.rms_error : r.error;
}

std::vector<int> pareto_front(const std::vector<TradeoffRow>& rows) {
  std::vector<int> ok;
  for (int i = 0; i < static_cast<int>(rows.size()); ++i)
    if (rows[i].stable && std::isfinite(front_error(rows[i]))) ok.push_back(i);
  std::vector<int> front;
  for (int i : ok) {
    bool dominated = false;
    const double eb = front_error(rows[i]);
    for (int j : ok) {
      if (j == i) continue;
      const TradeoffRow &a = rows[j], &b = rows[i];
      const double ea = front_error(a);
      if (a.step_us <= b.step_us && ea <= eb && (a.step_us < b.step_us || ea < eb)) {
        dominated = true;
        break;
      }
    }
    if (!dominated) front.push_back(i);
  }
  std::sort(front.begin(), front.end(), [&](int a, int b) {
    return rows[a].step_us != rows[b].step_us ? rows[a].step_us < rows[b].step_us
                                              : front_error(rows[a]) < front_error(rows[b]);
  });
  return front;
}

Plan plan(const std::vector<TradeoffRow>& rows, const PlanRequest& q) {
  Plan p;
  std::vector<PlanCandidate> all;
  for (int i = 0; i < static_cast<int>(rows.size()); ++i) {
    const TradeoffRow& r = rows[i];
    if (r.scene != q.scene || r.law != q.law || !r.stable || !std::isfinite(r.error)) continue;
    all.push_back({i, r.step_us * q.cost_scale, r.error});
  }
  p.candidates = static_cast<int>(all.size());
  auto cheaper = [](const PlanCandidate& a, const PlanCandidate& b) {
    return a.cost_us != b.cost_us ? a.cost_us < b.cost_us : a.error < b.error;
  };
  std::sort(all.begin(), all.end(), cheaper);
  std::vector<PlanCandidate> meet;
  for (const PlanCandidate& c : all)
    if (c.error <= q.tolerance && c.cost_us <= q.budget_us) meet.push_back(c);
  if (!meet.empty()) {
    p.found = true;
    p.chosen = meet[0];
    for (size_t k = 1; k < meet.size() && p.runners_up.size() < 3; ++k)
      p.runners_up.push_back(meet[k]);
    return p;
  }
  // Nothing meets both: the cheapest accurate enough, and the most accurate affordable one.
  for (const PlanCandidate& c : all)
    if (c.error <= q.tolerance) {
      p.closest.push_back(c);
      break;
    }
  const PlanCandidate* best = nullptr;
  for (const PlanCandidate& c : all)
    if (c.cost_us <= q.budget_us && (!best || c.error < best->error)) best = &c;
  if (best) p.closest.push_back(*best);
  if (p.closest.empty() && !all.empty()) p.closest.push_back(all[0]);
  return p;
}

}  // namespace conica::lab
