#include "lab/viscoelastic.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/step.h"
#include "lab/compression.h"

namespace conica::lab {
namespace {

struct Rig {
  Model m;
  State s;
  double lo = 0;  // rest top of the body along the plate normal
  Vec3 n;
  explicit Rig(const Model& model) : m(model) {
    PlaneSpec& plate = m.planes.at(0);
    n = plate.normal;
    lo = std::numeric_limits<double>::infinity();
    for (const Vec3& x : m.rest) lo = std::min(lo, n.dot(x));
    plate.stiffness = std::max(plate.stiffness, rigid_plate_stiffness(m, true));
    s = make_state(m);
    s.planes[0].offset = lo;
  }
  // One step with the plate at travel u; returns the plate force after the step.
  double advance(Workspace& ws, double u) {
    s.planes[0].offset = lo + u;
    step(m, s, ws);
    compute_forces(m, s, ws);
    return -n.dot(s.planes[0].force);
  }
};

// A history holding its start: t = 0, no displacement, no force.
PlateHistory started_history() {
  PlateHistory h;
  h.time.push_back(0);
  h.displacement.push_back(0);
  h.force.push_back(0);
  return h;
}

}  // namespace

PlateHistory displacement_program(const Model& model, const std::function<double(double)>& u,
                                  double duration) {
  Rig rig(model);
  Workspace ws(rig.m);
  const double dt = rig.m.options.dt;
  const long steps = static_cast<long>(std::ceil(duration / dt - 1e-9));
  PlateHistory h = started_history();
  for (long k = 1; k <= steps; ++k) {
    const double t = dt * static_cast<double>(k);
    const double uk = u(t);
    h.force.push_back(rig.advance(ws, uk));
    h.time.push_back(t);
    h.displacement.push_back(uk);
  }
  return h;
}

PlateHistory force_program(const Model& model, const std::function<double(double)>& force,
                           double duration, double gain) {
  // Instantaneous stiffness: a small trial step on a copy.
  double k_inst = 0;
  {
    Rig trial(model);
    Workspace ws(trial.m);
    double height = 0;
    for (const Vec3& x : trial.m.rest) height = std::max(height, trial.n.dot(x) - trial.lo);
    const double du = 1e-4 * height;
    k_inst = trial.advance(ws, du) / du;
  }
  Rig rig(model);
  Workspace ws(rig.m);
  const double dt = rig.m.options.dt;
  const long steps = static_cast<long>(std::ceil(duration / dt - 1e-9));
  PlateHistory h = started_history();
  double u = 0, f = 0;
  for (long k = 1; k <= steps; ++k) {
    const double t = dt * static_cast<double>(k);
    if (k_inst > 0) u = std::max(0.0, u + gain * (force(t) - f) / k_inst);
    f = rig.advance(ws, u);
    h.time.push_back(t);
    h.displacement.push_back(u);
    h.force.push_back(f);
  }
  return h;
}

double decay_time(const std::vector<double>& t, const std::vector<double>& y, double t0) {
  const double yinf = y.back();
  size_t i0 = 0;
  while (i0 < t.size() && t[i0] < t0) ++i0;
  if (i0 >= t.size()) return std::nan("");
  const double a0 = std::abs(y[i0] - yinf);
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  int n = 0;
  for (size_t i = i0; i < t.size(); ++i) {
    const double a = std::abs(y[i] - yinf);
    if (a > 0.9 * a0 || a < 0.05 * a0) continue;
    const double x = t[i] - t0, l = std::log(a);
    sx += x;
    sy += l;
    sxx += x * x;
    sxy += x * l;
    ++n;
  }
  if (n < 3) return std::nan("");
  const double slope = (n * sxy - sx * sy) / (n * sxx - sx * sx);
  return -1 / slope;
}

double loop_area(const std::vector<double>& u, const std::vector<double>& f, size_t begin,
                 size_t end) {
  double a = 0;
  for (size_t i = begin + 1; i < end; ++i) a += 0.5 * (f[i] + f[i - 1]) * (u[i] - u[i - 1]);
  return a;  // work done on the body over the cycle
}

}  // namespace conica::lab
