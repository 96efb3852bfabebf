#include "core/boundary.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/step.h"

namespace conica {

Vec3 motion_displacement(const NodeMotion& motion, double t) {
  const auto& ts = motion.time;
  const auto& d = motion.displacement;
  if (ts.empty()) return Vec3::Zero();
  if (!(t > ts.front())) return d.front();
  if (t >= ts.back()) return d.back();
  const auto it = std::upper_bound(ts.begin(), ts.end(), t);
  const size_t j = static_cast<size_t>(it - ts.begin());
  const double w = (t - ts[j - 1]) / (ts[j] - ts[j - 1]);
  return (1 - w) * d[j - 1] + w * d[j];
}

std::string make_motion(const std::vector<double>& time, const std::vector<Vec3>& displacement,
                        int axes, NodeMotion* motion) {
  if (time.empty()) return "a path needs at least one waypoint";
  if (time.size() != displacement.size())
    return "path: " + std::to_string(time.size()) + " times but " +
           std::to_string(displacement.size()) + " displacements";
  if (axes < 1 || axes > 7) return "path: axes must be 1..7";
  for (size_t k = 0; k < time.size(); ++k) {
    if (!std::isfinite(time[k])) return "path waypoint " + std::to_string(k) + ": time not finite";
    if (!displacement[k].allFinite())
      return "path waypoint " + std::to_string(k) + ": displacement not finite";
    if (k > 0 && !(time[k] > time[k - 1]))
      return "path waypoint " + std::to_string(k) + ": times must increase (s)";
  }
  motion->axes = axes;
  motion->time = time;
  motion->displacement = displacement;
  return {};
}

std::string bond_plates(const std::vector<Vec3>& rest, Model* model) {
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (const Vec3& x : rest) {
    lo = lo.cwiseMin(x);
    hi = hi.cwiseMax(x);
  }
  const double size = rest.empty() ? 0.0 : (hi - lo).norm();
  for (size_t k = 0; k < model->planes.size(); ++k) {
    PlaneSpec& p = model->planes[k];
    p.bonded_nodes.clear();
    if (!p.bonded) continue;
    if (!(p.normal.norm() > 0)) return "plane " + std::to_string(k) + ": normal must be nonzero";
    if (!(p.bond_tolerance >= 0) || !std::isfinite(p.bond_tolerance))
      return "plane " + std::to_string(k) + ": bond tolerance must be >= 0 m";
    const Vec3 n = p.normal.normalized();
    const double tol = p.bond_tolerance > 0 ? p.bond_tolerance : 1e-6 * size;
    for (int i = 0; i < static_cast<int>(rest.size()); ++i)
      if (std::abs(n.dot(rest[i]) - p.offset) <= tol) {
        p.bonded_nodes.push_back(i);
        model->fixed[i] = 7;
      }
    if (p.bonded_nodes.empty())
      return "plane " + std::to_string(k) +
             " is bonded but touches no node at rest (its face must lie on the body)";
  }
  return {};
}

bool has_boundary_motion(const Model& m) {
  if (!m.motions.empty()) return true;
  for (const PlaneSpec& p : m.planes)
    if (p.bonded) return true;
  return false;
}

void apply_boundary_motion(const Model& m, State& s, double t) {
  for (const NodeMotion& mo : m.motions) {
    const Vec3 d = motion_displacement(mo, t);
    for (int i : mo.nodes)
      for (int a = 0; a < 3; ++a)
        if ((mo.axes >> a) & 1) {
          s.x[i][a] = m.rest[i][a] + d[a];
          s.v[i][a] = 0;
        }
  }
  for (size_t k = 0; k < m.planes.size(); ++k) {
    const PlaneSpec& p = m.planes[k];
    if (!p.bonded) continue;
    const Vec3 d = (s.planes[k].offset - p.offset) * p.normal + s.planes[k].slide -
                   p.normal.dot(s.planes[k].slide) * p.normal;
    for (int i : p.bonded_nodes) {
      s.x[i] = m.rest[i] + d;
      s.v[i].setZero();
    }
  }
}

void add_bonded_reactions(const Model& m, State& s, const Workspace& ws) {
  for (size_t k = 0; k < m.planes.size(); ++k) {
    const PlaneSpec& p = m.planes[k];
    if (!p.bonded) continue;
    Vec3 f = Vec3::Zero();
    for (int i : p.bonded_nodes) f += ws.force[i];
    s.planes[k].force += f;
    s.planes[k].contacts += static_cast<int>(p.bonded_nodes.size());
  }
}

}  // namespace conica
