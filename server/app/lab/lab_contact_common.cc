// conica-lab contact: the top surface of a scene's body (press points, lattice spacing) and
// runs of one tool driven along a target path, with their CSV output.
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "app/lab/lab_contact.h"
#include "core/body.h"
#include "core/contact.h"
#include "core/step.h"

namespace conica::lab::contact {

// ---------------------------------------------------------------- geometry of the top surface

namespace {

Vec3 tri_normal(const Model& m, int t) {
  const auto& f = m.surface[t];
  return (m.rest[f[1]] - m.rest[f[0]]).cross(m.rest[f[2]] - m.rest[f[0]]).normalized();
}

}  // namespace

Top find_top(const Model& m) {
  Top top;
  double zmax = -std::numeric_limits<double>::infinity(), zmin = -zmax;
  for (const Vec3& x : m.rest) {
    zmax = std::max(zmax, x.z());
    zmin = std::min(zmin, x.z());
  }
  const double tol = 1e-6 * std::max(1e-3, zmax - zmin);
  for (int t = 0; t < static_cast<int>(m.surface.size()); ++t) {
    const auto& f = m.surface[t];
    bool flat = tri_normal(m, t).z() > 0.99;
    for (int a = 0; a < 3; ++a) flat = flat && m.rest[f[a]].z() > zmax - tol;
    if (flat) top.tris.push_back(t);
  }
  if (top.tris.empty()) {  // not a flat-topped body: upward faces in the top tenth
    for (int t = 0; t < static_cast<int>(m.surface.size()); ++t) {
      const auto& f = m.surface[t];
      const double zc = (m.rest[f[0]].z() + m.rest[f[1]].z() + m.rest[f[2]].z()) / 3;
      if (tri_normal(m, t).z() > 0.7 && zc > zmax - 0.1 * (zmax - zmin)) top.tris.push_back(t);
    }
  }
  if (top.tris.empty()) return top;
  double xlo = std::numeric_limits<double>::infinity(), xhi = -xlo, ylo = xlo, yhi = -xlo;
  for (int t : top.tris)
    for (int i : m.surface[t]) {
      xlo = std::min(xlo, m.rest[i].x());
      xhi = std::max(xhi, m.rest[i].x());
      ylo = std::min(ylo, m.rest[i].y());
      yhi = std::max(yhi, m.rest[i].y());
    }
  top.spacing = surface_spacing(m, top.tris);
  top.cx = 0.5 * (xlo + xhi);
  top.cy = 0.5 * (ylo + yhi);
  auto dxy = [&](const Vec3& p) { return std::hypot(p.x() - top.cx, p.y() - top.cy); };
  double best = std::numeric_limits<double>::infinity();
  for (int t : top.tris)
    for (int i : m.surface[t])
      if (dxy(m.rest[i]) < best - 1e-12) {
        best = dxy(m.rest[i]);
        top.node = m.rest[i];
      }
  best = std::numeric_limits<double>::infinity();
  int tbest = top.tris[0];
  for (int t : top.tris) {
    const auto& f = m.surface[t];
    const Vec3 c = (m.rest[f[0]] + m.rest[f[1]] + m.rest[f[2]]) / 3;
    if (dxy(c) < best - 1e-12) {
      best = dxy(c);
      tbest = t;
    }
  }
  const auto& f = m.surface[tbest];
  top.face = (m.rest[f[0]] + m.rest[f[1]] + m.rest[f[2]]) / 3;
  // The longest edge; a second top triangle sharing it makes a quad with it.
  int e = 0;
  for (int a = 1; a < 3; ++a)
    if ((m.rest[f[(a + 1) % 3]] - m.rest[f[a]]).norm() >
        (m.rest[f[(e + 1) % 3]] - m.rest[f[e]]).norm())
      e = a;
  const int i = f[e], j = f[(e + 1) % 3], k = f[(e + 2) % 3];
  for (int t : top.tris) {
    if (t == tbest) continue;
    const auto& g = m.surface[t];
    const bool has_i = g[0] == i || g[1] == i || g[2] == i;
    const bool has_j = g[0] == j || g[1] == j || g[2] == j;
    if (!has_i || !has_j) continue;
    int other = -1;
    for (int a = 0; a < 3; ++a)
      if (g[a] != i && g[a] != j) other = g[a];
    top.face = (m.rest[i] + m.rest[j] + m.rest[k] + m.rest[other]) / 4;
    top.quad = true;
    break;
  }
  return top;
}

bool surface_span(const Model& m, double x, double y, double* ztop, double* zbot) {
  *ztop = -std::numeric_limits<double>::infinity();
  *zbot = std::numeric_limits<double>::infinity();
  for (const auto& f : m.surface) {
    const Vec3 &a = m.rest[f[0]], &b = m.rest[f[1]], &c = m.rest[f[2]];
    const double det = (b.x() - a.x()) * (c.y() - a.y()) - (c.x() - a.x()) * (b.y() - a.y());
    if (std::abs(det) < 1e-18) continue;
    const double u = ((x - a.x()) * (c.y() - a.y()) - (c.x() - a.x()) * (y - a.y())) / det;
    const double v = ((b.x() - a.x()) * (y - a.y()) - (x - a.x()) * (b.y() - a.y())) / det;
    const double eps = 1e-9;
    if (u < -eps || v < -eps || u + v > 1 + eps) continue;
    const double z = a.z() + u * (b.z() - a.z()) + v * (c.z() - a.z());
    *ztop = std::max(*ztop, z);
    *zbot = std::min(*zbot, z);
  }
  return *ztop >= *zbot;
}

// ---------------------------------------------------------------- runs

std::string with_tool(BodySpec spec, double radius, ToolShape shape, Model* m,
                      ContactModel contact) {
  ProbeSpec p;
  if (!spec.probes.empty()) p = spec.probes[0];
  p.radius = radius;
  p.contact = contact;
  p.shape = shape;
  p.axis = -Vec3::UnitZ();
  p.stiffness = 0;
  p.coupling = 0;
  spec.probes = {p};
  return build_model(spec, m);
}

Run drive(const Model& m, long ticks, double ref, const std::function<Vec3(long)>& target) {
  Run r;
  r.s.reserve(ticks);
  State s = make_state(m);
  Workspace ws(m);
  const auto t0 = std::chrono::steady_clock::now();
  for (long k = 0; k < ticks; ++k) {
    const Vec3 c = target(k);
    set_probe(s, 0, c);
    step(m, s, ws);
    const ProbeState& p = s.probes[0];
    Sample q;
    q.tick = static_cast<long>(s.tick);
    q.t = s.time;
    q.tool_depth = ref - c.z();
    q.proxy_depth = ref - p.proxy.z();
    q.penetration = p.depth;
    q.target_x = c.x();
    q.f = p.force;
    q.contacts = p.contacts;
    r.max_penetration = std::max(r.max_penetration, p.depth);
    r.s.push_back(q);
  }
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.rollbacks = s.counters.rollbacks;
  return r;
}

bool write_csv(const Opts& o, const std::string& name, const Run& r) {
  if (o.out_dir.empty()) return true;
  const std::string path = o.out_dir + "/" + name + ".csv";
  FILE* f = std::fopen(path.c_str(), "w");
  if (!f) {
    std::fprintf(stderr, "%s: cannot write %s\n", kCmd, path.c_str());
    return false;
  }
  std::fputs("tick,t,tool_depth_mm,proxy_depth_mm,fx,fy,fz,contacts,penetration_mm\n", f);
  for (const Sample& q : r.s)
    std::fprintf(f, "%ld,%.6f,%.6f,%.6f,%.9g,%.9g,%.9g,%d,%.6f\n", q.tick, q.t, q.tool_depth * 1e3,
                 q.proxy_depth * 1e3, q.f.x(), q.f.y(), q.f.z(), q.contacts, q.penetration * 1e3);
  std::fclose(f);
  return true;
}

std::string fmt(const char* f, double v) {
  char b[64];
  std::snprintf(b, sizeof b, f, v);
  return b;
}

void mean_sd(const std::vector<double>& v, double* mean, double* rel_sd) {
  double s = 0, s2 = 0;
  for (double x : v) s += x;
  *mean = v.empty() ? 0 : s / v.size();
  for (double x : v) s2 += (x - *mean) * (x - *mean);
  const double sd = v.empty() ? 0 : std::sqrt(s2 / v.size());
  *rel_sd = *mean != 0 ? sd / std::abs(*mean) : 0;
}

}  // namespace conica::lab::contact
