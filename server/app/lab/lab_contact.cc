// conica-lab contact: measurements of the surface contact (core/contact.h) on scene files.
//  press  normal quasi-static presses along -z into the top of the body, then a hold, with the
//         scene's own integrator; tool radius = factor x the top surface's lattice spacing, at the
//         top node nearest the top's centre and at a face centre near it.
//  hertz  a block's E and nu from a small-strain frictionless plate compression, then a sphere and
//         a flat punch pressed quasi-statically, force against proxy depth compared with Hertz
//         F = 4/3 E* sqrt(R) d^1.5 and Sneddon F = 2 a E* d (E* = E / (1 - nu^2)).
//  drag   a sphere pressed in, then dragged along +x at constant target height across node
//         spacings: the normal force's ripple.
//  hold   each integrator on the scene: a press and a hold, the hold force's steadiness.
// Prints one markdown table row per case (stdout); --out-dir writes one CSV per case:
// tick,t,tool_depth_mm,proxy_depth_mm,fx,fy,fz,contacts,penetration_mm (force on the device, N;
// depths from the rest surface at the press point, positive into the body).
#include <sys/stat.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "app/lab/lab.h"
#include "core/body.h"
#include "core/contact.h"
#include "core/step.h"
#include "io/scene.h"
#include "lab/compression.h"

#ifndef CONICA_SOURCE_DIR
#define CONICA_SOURCE_DIR "."
#endif

namespace conica::lab {
namespace {

constexpr const char* kCmd = "conica-lab contact";

struct Opts {
  std::vector<std::string> scenes;
  bool suite = false;
  std::vector<std::string> experiments;
  std::string out_dir;
  // press
  double speed_mm_s = 5;
  std::vector<double> radius_factors = {0.25, 0.5, 1, 2};
  std::vector<std::string> positions = {"node", "face"};
  double max_depth_fraction = 0.5;
  double hold_s = 1;
  // hertz
  std::vector<double> size_mm = {60, 60, 30};
  std::vector<double> spacings_mm = {5, 2.5};
  std::vector<int> cells;
  bool hertz_on_scene = false;
  double sphere_radius_mm = 10;
  double punch_radius_mm = 5;
  int hertz_steps = 20;
  int hertz_settle = 5;
  double hertz_dt_ms = 1000;
  int hertz_newton = 4;
  int hertz_cg = 200;
  double compression_strain = 0.01;
  // drag
  std::vector<double> drag_factors = {0.25, 1};
  std::vector<double> drag_depths = {0.2, 1};
  double drag_spacings = 5;
  // hold
  double hold_radius_mm = 10;
  double hold_depth_mm = 4;
  double hold_press_s = 0.8;
  double hold_hold_s = 2;
  // speed check
  bool speed_check = false;
};

std::string stem(const std::string& path) {
  std::string s = path.substr(path.find_last_of('/') + 1);
  const size_t dot = s.rfind('.');
  return dot == std::string::npos ? s : s.substr(0, dot);
}

std::string find_scene(const std::string& rel) {
  if (FILE* f = std::fopen(rel.c_str(), "r")) {
    std::fclose(f);
    return rel;
  }
  return std::string(CONICA_SOURCE_DIR) + "/" + rel;
}

struct Scene {
  std::string path, name;
  BodySpec spec;
};

// ---------------------------------------------------------------- geometry of the top surface

struct Top {
  std::vector<int> tris;     // surface triangles of the top face
  double spacing = 0;        // m, median of their two shorter edges
  double cx = 0, cy = 0;     // m, centre of the top's (x, y) bounding box
  Vec3 node = Vec3::Zero();  // the top node nearest the centre
  Vec3 face = Vec3::Zero();  // the face point near the centre (quad centre or triangle centroid)
  bool quad = false;         // face is the centre of a quad of two triangles
};

Vec3 tri_normal(const Model& m, int t) {
  const auto& f = m.surface[t];
  return (m.rest[f[1]] - m.rest[f[0]]).cross(m.rest[f[2]] - m.rest[f[0]]).normalized();
}

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
  std::vector<double> edges;
  double xlo = std::numeric_limits<double>::infinity(), xhi = -xlo, ylo = xlo, yhi = -xlo;
  for (int t : top.tris) {
    const auto& f = m.surface[t];
    double l[3];
    for (int a = 0; a < 3; ++a) {
      l[a] = (m.rest[f[(a + 1) % 3]] - m.rest[f[a]]).norm();
      xlo = std::min(xlo, m.rest[f[a]].x());
      xhi = std::max(xhi, m.rest[f[a]].x());
      ylo = std::min(ylo, m.rest[f[a]].y());
      yhi = std::max(yhi, m.rest[f[a]].y());
    }
    std::sort(l, l + 3);
    edges.push_back(l[0]);
    edges.push_back(l[1]);
  }
  std::nth_element(edges.begin(), edges.begin() + edges.size() / 2, edges.end());
  top.spacing = edges[edges.size() / 2];
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

// The rest surface's highest and lowest z on the vertical line through (x, y).
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

struct Sample {
  long tick = 0;
  double t = 0, tool_depth = 0, proxy_depth = 0, penetration = 0, target_x = 0;
  Vec3 f = Vec3::Zero();
  int contacts = 0;
};

struct Run {
  std::vector<Sample> s;
  std::uint64_t rollbacks = 0;
  double seconds = 0;  // wall time
  double max_penetration = 0;
};

// Builds spec with one surface-contact tool (replacing the scene's probes).
std::string with_tool(BodySpec spec, double radius, ToolShape shape, Model* m,
                      ContactModel contact = ContactModel::kSurface) {
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

// Steps `ticks` ticks with the device target target(k) (k = 0..ticks-1). Depths are ref - z.
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

// ---------------------------------------------------------------- press

struct PressResult {
  Run run;
  double first_force = -1;   // m of tool depth
  bool positive = true;      // force > 0 at every tick once 0.1 mm in
  int drops = 0;             // press ticks whose force fell by more than 1 % of its running
                             // maximum since the tick before
  double max_drop = 0;       // largest such fall / running max
  double last_drop = -1;     // m, tool depth of the last such tick
  double shortfall = 0;      // largest (running max - force) / running max over the press
  double shortfall_at = -1;  // m, tool depth where it is reached
  double hold_mean = 0, hold_rel_sd = 0;
  double end_force = 0;
};

PressResult press(const Model& m, const Vec3& at, double ref, double R, double speed, double depth,
                  double hold_s) {
  const double dt = m.options.dt;
  const long press_ticks = std::max(1L, std::lround(depth / (speed * dt)));
  const long hold_ticks = std::lround(hold_s / dt);
  PressResult pr;
  pr.run = drive(m, press_ticks + 1 + hold_ticks, ref, [&](long k) {
    const double d = depth * std::min(1.0, static_cast<double>(k) / press_ticks);
    return Vec3(at.x(), at.y(), ref - d);
  });
  double run_max = 0, prev = 0;
  std::vector<double> hold;
  for (long k = 0; k < static_cast<long>(pr.run.s.size()); ++k) {
    const Sample& q = pr.run.s[k];
    const double f = q.f.z();
    if (pr.first_force < 0 && f > 0) pr.first_force = q.tool_depth;
    if (q.tool_depth > 1e-4 && !(f > 0)) pr.positive = false;
    if (k <= press_ticks) {
      run_max = std::max(run_max, f);
      if (q.tool_depth > 1e-4 && prev - f > 0.01 * run_max) {
        ++pr.drops;
        pr.max_drop = std::max(pr.max_drop, (prev - f) / run_max);
        pr.last_drop = q.tool_depth;
      }
      if (q.tool_depth > 1e-4 && run_max > 0 && (run_max - f) / run_max > pr.shortfall) {
        pr.shortfall = (run_max - f) / run_max;
        pr.shortfall_at = q.tool_depth;
      }
      prev = f;
      if (k == press_ticks) pr.end_force = f;
    } else if (k > press_ticks + hold_ticks / 2) {
      hold.push_back(f);
    }
  }
  mean_sd(hold, &pr.hold_mean, &pr.hold_rel_sd);
  (void)R;
  return pr;
}

int run_press(const Opts& o, const std::vector<Scene>& scenes) {
  std::printf("\n### press\n\n");
  std::printf(
      "| scene | R_mm | R/s | position | first force at_mm | F>0 from 0.1 mm | drops >1 %% "
      "| max drop %% | last drop at_mm | max shortfall %% | at_mm | F at max depth (N) | max pen/R "
      "| rollbacks | hold F (N) | hold "
      "std/mean %% | wall s |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  std::fflush(stdout);
  for (const Scene& sc : scenes) {
    Model probe_model;
    if (std::string e = with_tool(sc.spec, 1e-3, ToolShape::kSphere, &probe_model); !e.empty()) {
      std::fprintf(stderr, "%s: --scene %s: %s\n", kCmd, sc.path.c_str(), e.c_str());
      return 2;
    }
    const Top top = find_top(probe_model);
    if (top.tris.empty()) {
      std::fprintf(stderr, "%s: --scene %s: no upward top surface to press\n", kCmd,
                   sc.path.c_str());
      return 2;
    }
    for (double factor : o.radius_factors) {
      const double R = factor * top.spacing;
      Model m;
      if (std::string e = with_tool(sc.spec, R, ToolShape::kSphere, &m); !e.empty()) {
        std::fprintf(stderr, "%s: --scene %s: %s\n", kCmd, sc.path.c_str(), e.c_str());
        return 2;
      }
      for (const std::string& pos : o.positions) {
        const Vec3 at = pos == "node" ? top.node : top.face;
        double zt, zb;
        if (!surface_span(m, at.x(), at.y(), &zt, &zb)) {
          std::fprintf(stderr, "%s: %s: no surface under the %s point\n", kCmd, sc.name.c_str(),
                       pos.c_str());
          return 1;
        }
        const double depth = o.max_depth_fraction * (zt - zb);
        const PressResult pr = press(m, at, zt + R, R, o.speed_mm_s * 1e-3, depth, o.hold_s);
        const std::string posname =
            pos == "node" ? "node" : (top.quad ? "quad centre" : "tri centroid");
        std::printf(
            "| %s | %.3g | %.3g | %s | %s | %s | %d | %.3g | %s | %.3g | %s | %.4g | %.3f | %llu | "
            "%.4g | "
            "%.3g | %.1f |\n",
            sc.name.c_str(), R * 1e3, factor, posname.c_str(),
            pr.first_force < 0 ? "none" : fmt("%.3f", pr.first_force * 1e3).c_str(),
            pr.positive ? "yes" : "NO", pr.drops, 100 * pr.max_drop,
            pr.last_drop < 0 ? "-" : fmt("%.3f", pr.last_drop * 1e3).c_str(), 100 * pr.shortfall,
            pr.shortfall_at < 0 ? "-" : fmt("%.2f", pr.shortfall_at * 1e3).c_str(), pr.end_force,
            pr.run.max_penetration / R, static_cast<unsigned long long>(pr.run.rollbacks),
            pr.hold_mean, 100 * pr.hold_rel_sd, pr.run.seconds);
        std::fflush(stdout);
        if (!write_csv(o, "press-" + sc.name + "-r" + fmt("%g", factor) + "-" + pos, pr.run))
          return 1;
      }
    }
  }
  return 0;
}

// ---------------------------------------------------------------- hertz

struct Block {
  std::string label;
  BodySpec spec;  // clamped base, implicit Euler
  double thickness = 0;
  double spacing = 0;
};

SolverOptions hertz_options(const Opts& o) {
  SolverOptions so;
  so.integrator = Integrator::kImplicitEuler;
  so.dt = o.hertz_dt_ms * 1e-3;
  so.newton_iterations = o.hertz_newton;
  so.cg_iterations = o.hertz_cg;
  so.cg_tolerance = 1e-10;
  so.mass_damping = 0;
  return so;
}

// E and nu of the block's body by a frictionless plate compression to `strain`: base held along
// z only (one base corner pinned in x, y, a second in y), a rigid top plate moved down, then held
// until static. E = (F / A) / e with e from the top nodes' mean travel; nu from the mid-height
// nodes' lateral spread.
bool plate_modulus(const Opts& o, const BodySpec& block, double* E, double* nu, double* strain_out,
                   std::string* err) {
  BodySpec spec = block;
  spec.probes.clear();
  spec.planes.clear();
  for (auto& g : spec.groups) g.card.damping = 0, g.card.maxwell_k = 0, g.card.maxwell_tau = 0;
  Vec3 lo = spec.mesh.nodes[0], hi = lo;
  for (const Vec3& x : spec.mesh.nodes) lo = lo.cwiseMin(x), hi = hi.cwiseMax(x);
  const double tol = 1e-6 * (hi - lo).norm();
  FixedSelector base;
  base.kind = FixedSelector::Kind::kPlane;
  base.normal = Vec3::UnitZ();
  base.offset = lo.z();
  base.tolerance = tol;
  base.axes = 4;
  // Pins: the base node nearest the min corner (x, y) and the one nearest (max x, min y) (y).
  auto nearest = [&](const Vec3& p) {
    int best = 0;
    for (int i = 0; i < static_cast<int>(spec.mesh.nodes.size()); ++i)
      if ((spec.mesh.nodes[i] - p).norm() < (spec.mesh.nodes[best] - p).norm()) best = i;
    return best;
  };
  FixedSelector pin, pin2;
  pin.kind = pin2.kind = FixedSelector::Kind::kNodes;
  pin.nodes = {nearest(lo)};
  pin.axes = 3;
  pin2.nodes = {nearest(Vec3(hi.x(), lo.y(), lo.z()))};
  pin2.axes = 2;
  spec.fixed = {base, pin, pin2};
  ensure_top_plate(&spec);
  // Long steps: each implicit step is Newton on the static equilibrium (as the homogenised cell).
  spec.options.dt = 1.0;
  spec.options.newton_iterations = 2;
  spec.options.cg_iterations = 400;
  spec.options.cg_tolerance = 1e-12;
  spec.options.max_speed = 1e9;
  Model m;
  if (std::string e = build_model(spec, &m); !e.empty()) {
    *err = "compression model: " + e;
    return false;
  }
  m.planes[0].stiffness = std::max(m.planes[0].stiffness, rigid_plate_stiffness(m, false));
  const double h = hi.z() - lo.z();
  const double travel = o.compression_strain * h;
  State s = make_state(m);
  Workspace ws(m);
  const int ramp = 10, settle = 40;
  for (int k = 1; k <= ramp + settle; ++k) {
    s.planes[0].offset = -hi.z() + travel * std::min(1.0, static_cast<double>(k) / ramp);
    step(m, s, ws);
  }
  compute_forces(m, s, ws);
  const double F = -m.planes[0].normal.dot(s.planes[0].force);
  // Axial strain from the top nodes' travel; lateral from the mid-height layer's width.
  double top_travel = 0;
  int ntop = 0;
  double zmid = lo.z() + 0.5 * h, dmid = std::numeric_limits<double>::infinity();
  for (const Vec3& x : m.rest) dmid = std::min(dmid, std::abs(x.z() - zmid));
  double w0x[2] = {1e9, -1e9}, w0y[2] = {1e9, -1e9}, w1x[2] = {1e9, -1e9}, w1y[2] = {1e9, -1e9};
  for (int i = 0; i < m.num_nodes(); ++i) {
    const Vec3 &r = m.rest[i], &x = s.x[i];
    if (r.z() > hi.z() - tol) top_travel += r.z() - x.z(), ++ntop;
    if (std::abs(std::abs(r.z() - zmid) - dmid) < tol) {
      w0x[0] = std::min(w0x[0], r.x()), w0x[1] = std::max(w0x[1], r.x());
      w0y[0] = std::min(w0y[0], r.y()), w0y[1] = std::max(w0y[1], r.y());
      w1x[0] = std::min(w1x[0], x.x()), w1x[1] = std::max(w1x[1], x.x());
      w1y[0] = std::min(w1y[0], x.y()), w1y[1] = std::max(w1y[1], x.y());
    }
  }
  const double e_ax = top_travel / std::max(1, ntop) / h;
  const double e_lat =
      0.5 * ((w1x[1] - w1x[0]) / (w0x[1] - w0x[0]) - 1 + (w1y[1] - w1y[0]) / (w0y[1] - w0y[0]) - 1);
  const double area = (hi.x() - lo.x()) * (hi.y() - lo.y());
  *E = F / area / e_ax;
  *nu = e_lat / e_ax;
  *strain_out = e_ax;
  if (s.counters.rollbacks > 0) {
    *err = "compression rolled back";
    return false;
  }
  return true;
}

int run_hertz(const Opts& o, const std::vector<Scene>& scenes) {
  const Scene& sc = scenes.front();
  std::vector<Block> blocks;
  if (o.hertz_on_scene) {
    Block b;
    b.label = sc.name;
    b.spec = sc.spec;
    b.spec.options = hertz_options(o);
    Model tmp;
    if (std::string e = with_tool(b.spec, 1e-3, ToolShape::kSphere, &tmp); !e.empty()) {
      std::fprintf(stderr, "%s: --scene %s: %s\n", kCmd, sc.path.c_str(), e.c_str());
      return 2;
    }
    const Top t = find_top(tmp);
    double zt, zb;
    surface_span(tmp, t.cx, t.cy, &zt, &zb);
    b.thickness = zt - zb;
    b.spacing = t.spacing;
    blocks.push_back(b);
  } else {
    const Vec3 size(o.size_mm[0] * 1e-3, o.size_mm[1] * 1e-3, o.size_mm[2] * 1e-3);
    std::vector<std::array<int, 3>> cells;
    if (!o.cells.empty()) {
      cells.push_back({o.cells[0], o.cells[1], o.cells[2]});
    } else {
      for (double s : o.spacings_mm)
        cells.push_back({std::max(1, static_cast<int>(std::lround(o.size_mm[0] / s))),
                         std::max(1, static_cast<int>(std::lround(o.size_mm[1] / s))),
                         std::max(1, static_cast<int>(std::lround(o.size_mm[2] / s)))});
    }
    for (const auto& c : cells) {
      Block b;
      b.spec.mesh = make_box_lattice(size, c);
      b.spec.density = sc.spec.density;
      b.spec.groups = sc.spec.groups;
      b.spec.mapping = sc.spec.mapping;
      b.spec.bulk_modulus = sc.spec.bulk_modulus;
      b.spec.spread_modulus = sc.spec.spread_modulus;
      b.spec.shear_modulus = sc.spec.shear_modulus;
      FixedSelector base;
      base.kind = FixedSelector::Kind::kPlane;
      b.spec.fixed = {base};
      b.spec.options = hertz_options(o);
      b.thickness = size.z();
      b.spacing = size.z() / c[2];
      b.label = fmt("%.4g", size.x() * 1e3) + "x" + fmt("%.4g", size.y() * 1e3) + "x" +
                fmt("%.4g", size.z() * 1e3) + " mm, " + std::to_string(c[0]) + "x" +
                std::to_string(c[1]) + "x" + std::to_string(c[2]);
      blocks.push_back(b);
    }
  }
  std::printf("\n### hertz\n\n");
  std::printf(
      "Card of %s; implicit Euler, dt %.3g ms, %d Newton x %d CG (tolerance 1e-10), no "
      "mass damping (each step close to a static solve); press to 0.1 R in %d equal depth levels, "
      "each held %d more steps and read at its last. Errors over proxy depth d in [0.02 R, 0.1 R], "
      "R = "
      "%.3g mm (sphere and punch alike).\n\n",
      sc.name.c_str(), o.hertz_dt_ms, o.hertz_newton, o.hertz_cg, o.hertz_steps, o.hertz_settle,
      o.sphere_radius_mm);
  std::printf(
      "| block | spacing_mm | nodes | E (Pa) | cell E (Pa) | nu | E* (Pa) | model E* (Pa) | tool | "
      "contact radius / thickness | max proxy depth_mm | max faces | mean err %% | max err %% | "
      "err at 0.1 R %% | max pen/R "
      "| rollbacks | wall s |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  std::fflush(stdout);
  const double R = o.sphere_radius_mm * 1e-3, a = o.punch_radius_mm * 1e-3;
  for (const Block& b : blocks) {
    double E, nu, strain;
    std::string err;
    if (!plate_modulus(o, b.spec, &E, &nu, &strain, &err)) {
      std::fprintf(stderr, "%s: hertz %s: %s\n", kCmd, b.label.c_str(), err.c_str());
      return 1;
    }
    const double Es = E / (1 - nu * nu);
    // Cross-check: the homogenised (affine) cell's uniaxial modulus at the same strain.
    double E_cell = 0;
    {
      Model cell;
      if (make_uniaxial_cell(b.spec.groups, b.spec.mapping, b.spacing, &cell, b.spec.bulk_modulus,
                             b.spec.shear_modulus)
              .empty())
        E_cell = cell_stress_curve(cell, {o.compression_strain}).front() / o.compression_strain;
    }
    for (int tool = 0; tool < 2; ++tool) {
      const bool sphere = tool == 0;
      const double r = sphere ? R : a;
      Model m;
      if (std::string e = with_tool(b.spec, r, sphere ? ToolShape::kSphere : ToolShape::kPunch, &m);
          !e.empty()) {
        std::fprintf(stderr, "%s: hertz %s: %s\n", kCmd, b.label.c_str(), e.c_str());
        return 1;
      }
      const Top t = find_top(m);
      double zt, zb;
      surface_span(m, t.cx, t.cy, &zt, &zb);
      const double ref = zt + (sphere ? r : 0);
      const double depth = 0.1 * R;
      const long levels = o.hertz_steps, per = o.hertz_settle + 1;
      const Run run = drive(m, levels * per, ref, [&](long k) {
        return Vec3(t.cx, t.cy, ref - depth * static_cast<double>(k / per + 1) / levels);
      });
      double sum = 0, worst = 0, at_end = 0, max_proxy = 0;
      int n = 0, max_contacts = 0;
      for (const Sample& q : run.s)
        max_proxy = std::max(max_proxy, q.proxy_depth),
        max_contacts = std::max(max_contacts, q.contacts);
      for (long k = per - 1; k < static_cast<long>(run.s.size()); k += per) {
        const Sample& q = run.s[k];
        const double d = q.proxy_depth;
        if (d < 0.02 * R || d > 0.1 * R * (1 + 1e-9)) continue;
        const double th =
            sphere ? 4.0 / 3.0 * Es * std::sqrt(R) * std::pow(d, 1.5) : 2 * a * Es * d;
        const double rel = q.f.z() / th - 1;
        sum += std::abs(rel);
        worst = std::max(worst, std::abs(rel));
        at_end = rel;
        ++n;
      }
      const double contact_radius = sphere ? std::sqrt(R * 0.1 * R) : a;
      std::printf(
          "| %s | %.3g | %d | %.5g | %.5g | %.4f | %.5g | %.5g | %s | %.3f | %.3f | %d | %s | "
          "%s | %s | %.3f | %llu | %.1f |\n",
          b.label.c_str(), b.spacing * 1e3, m.num_nodes(), E, E_cell, nu, Es, m.contact_modulus,
          sphere ? fmt("sphere R %.3g mm", r * 1e3).c_str()
                 : fmt("punch a %.3g mm", r * 1e3).c_str(),
          contact_radius / b.thickness, max_proxy * 1e3, max_contacts,
          n ? fmt("%.2f", 100 * sum / n).c_str() : "n/a",
          n ? fmt("%.2f", 100 * worst).c_str() : "n/a",
          n ? fmt("%+.2f", 100 * at_end).c_str() : "n/a", run.max_penetration / r,
          static_cast<unsigned long long>(run.rollbacks), run.seconds);
      std::fflush(stdout);
      if (!write_csv(o,
                     "hertz-" + fmt("%g", b.spacing * 1e3) + "mm-" + (sphere ? "sphere" : "punch"),
                     run))
        return 1;
    }
  }
  return 0;
}

// ---------------------------------------------------------------- drag

int run_drag(const Opts& o, const std::vector<Scene>& scenes) {
  std::printf("\n### drag\n\n");
  std::printf(
      "Pressed at %.3g mm/s, 0.2 s settle, then dragged along +x at %.3g mm/s across %.3g "
      "spacings at constant target height, along the node row nearest the top's centre; "
      "ripple = (max - min) / mean of the normal force over the middle three spacings.\n\n",
      o.speed_mm_s, o.speed_mm_s, o.drag_spacings);
  std::printf(
      "| scene | R_mm | R/s | depth/R | mean Fz (N) | ripple %% | mean Fx (N) | max pen/R | "
      "rollbacks | wall s |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|\n");
  std::fflush(stdout);
  for (const Scene& sc : scenes) {
    Model pm;
    if (std::string e = with_tool(sc.spec, 1e-3, ToolShape::kSphere, &pm); !e.empty()) {
      std::fprintf(stderr, "%s: --scene %s: %s\n", kCmd, sc.path.c_str(), e.c_str());
      return 2;
    }
    const Top top = find_top(pm);
    if (top.tris.empty()) {
      std::fprintf(stderr, "%s: --scene %s: no top surface\n", kCmd, sc.path.c_str());
      return 2;
    }
    const double s = top.spacing, len = o.drag_spacings * s;
    const double x0 = top.cx - 0.5 * len, y0 = top.node.y();
    for (double factor : o.drag_factors) {
      const double R = factor * s;
      Model m;
      if (std::string e = with_tool(sc.spec, R, ToolShape::kSphere, &m); !e.empty()) {
        std::fprintf(stderr, "%s: --scene %s: %s\n", kCmd, sc.path.c_str(), e.c_str());
        return 2;
      }
      double zt, zb;
      if (!surface_span(m, x0, y0, &zt, &zb)) zt = top.node.z();
      const double ref = zt + R;
      for (double df : o.drag_depths) {
        const double depth = df * R, v = o.speed_mm_s * 1e-3, dt = m.options.dt;
        const long tp = std::max(1L, std::lround(depth / (v * dt)));
        const long ts = std::lround(0.2 / dt);
        const long td = std::max(1L, std::lround(len / (v * dt)));
        const Run run = drive(m, tp + ts + td + 1, ref, [&](long k) {
          const double d = depth * std::min(1.0, static_cast<double>(k) / tp);
          const double x = x0 + len * std::clamp(static_cast<double>(k - tp - ts) / td, 0.0, 1.0);
          return Vec3(x, y0, ref - d);
        });
        std::vector<double> fz, fx;
        for (long k = tp + ts; k < static_cast<long>(run.s.size()); ++k) {
          const Sample& q = run.s[k];
          if (q.target_x < x0 + s - 1e-12 || q.target_x > x0 + len - s + 1e-12) continue;
          fz.push_back(q.f.z());
          fx.push_back(q.f.x());
        }
        double mz, rz, mx, rx;
        mean_sd(fz, &mz, &rz);
        mean_sd(fx, &mx, &rx);
        const double lo = fz.empty() ? 0 : *std::min_element(fz.begin(), fz.end());
        const double hi = fz.empty() ? 0 : *std::max_element(fz.begin(), fz.end());
        std::printf("| %s | %.3g | %.3g | %.3g | %.4g | %.3g | %.3g | %.3f | %llu | %.1f |\n",
                    sc.name.c_str(), R * 1e3, factor, df, mz, mz != 0 ? 100 * (hi - lo) / mz : 0.0,
                    mx, run.max_penetration / R, static_cast<unsigned long long>(run.rollbacks),
                    run.seconds);
        std::fflush(stdout);
        if (!write_csv(o, "drag-" + sc.name + "-r" + fmt("%g", factor) + "-d" + fmt("%g", df), run))
          return 1;
      }
    }
  }
  return 0;
}

// ---------------------------------------------------------------- hold

int run_hold(const Opts& o, const std::vector<Scene>& scenes) {
  std::printf("\n### hold\n\n");
  std::printf(
      "A %.3g mm sphere at the top centre pressed to %.3g mm over %.3g s, held %.3g s; "
      "statistics over the hold's last second (the scene's time step and budgets).\n\n",
      o.hold_radius_mm, o.hold_depth_mm, o.hold_press_s, o.hold_hold_s);
  std::printf(
      "| scene | integrator | F at end of press (N) | hold F (N) | hold std/mean %% | "
      "max pen/R | rollbacks | wall s |\n");
  std::printf("|---|---|---|---|---|---|---|---|\n");
  std::fflush(stdout);
  const double R = o.hold_radius_mm * 1e-3, depth = o.hold_depth_mm * 1e-3;
  for (const Scene& sc : scenes) {
    // The last row: explicit Euler with the node contact, a control for the integrator itself.
    for (int row = 0; row < 4; ++row) {
      const Integrator integ = row == 0   ? Integrator::kSymplecticEuler
                               : row == 2 ? Integrator::kImplicitEuler
                                          : Integrator::kExplicitEuler;
      const bool nodes = row == 3;
      BodySpec spec = sc.spec;
      spec.options.integrator = integ;
      Model m;
      if (std::string e = with_tool(spec, R, ToolShape::kSphere, &m,
                                    nodes ? ContactModel::kNodes : ContactModel::kSurface);
          !e.empty()) {
        std::fprintf(stderr, "%s: --scene %s: %s\n", kCmd, sc.path.c_str(), e.c_str());
        return 2;
      }
      const Top top = find_top(m);
      double zt, zb;
      if (!surface_span(m, top.cx, top.cy, &zt, &zb)) zt = top.node.z();
      const double ref = zt + R, dt = m.options.dt;
      const long tp = std::max(1L, std::lround(o.hold_press_s / dt));
      const long th = std::lround(o.hold_hold_s / dt);
      const Run run = drive(m, tp + 1 + th, ref, [&](long k) {
        return Vec3(top.cx, top.cy, ref - depth * std::min(1.0, static_cast<double>(k) / tp));
      });
      std::vector<double> f;
      const long last = std::lround(1.0 / dt);
      for (long k = std::max(tp + 1, static_cast<long>(run.s.size()) - last);
           k < static_cast<long>(run.s.size()); ++k)
        f.push_back(run.s[k].f.z());
      double mean, rel;
      mean_sd(f, &mean, &rel);
      std::printf("| %s | %s%s | %.4g | %.4g | %.3g | %.3f | %llu | %.1f |\n", sc.name.c_str(),
                  integrator_name(integ), nodes ? " (control: NODES contact)" : "", run.s[tp].f.z(),
                  mean, 100 * rel, run.max_penetration / R,
                  static_cast<unsigned long long>(run.rollbacks), run.seconds);
      std::fflush(stdout);
      if (!write_csv(o,
                     std::string("hold-") + sc.name + "-" + integrator_name(integ) +
                         (nodes ? "-nodes" : ""),
                     run))
        return 1;
    }
  }
  return 0;
}

// ---------------------------------------------------------------- quasi-static check

// Force against tool depth at `speed` and half of it: the largest difference at tool depths
// 1 mm, 2 mm, ... up to the press depth (press, scene's integrator).
int run_speed_check(const Opts& o, const std::vector<Scene>& scenes) {
  const Scene& sc = scenes.front();
  std::printf("\n### quasi-static check\n\n");
  std::printf(
      "| case | speed_mm_s | F at 12.5, 25, ..., 100 %% of the depth (N) | abs. difference vs "
      "half speed at each, %% | max %% |\n|---|---|---|---|---|\n");
  Model pm;
  if (std::string e = with_tool(sc.spec, 1e-3, ToolShape::kSphere, &pm); !e.empty()) {
    std::fprintf(stderr, "%s: --scene %s: %s\n", kCmd, sc.path.c_str(), e.c_str());
    return 2;
  }
  const Top top = find_top(pm);
  const double factor = o.radius_factors.front(), R = factor * top.spacing;
  Model m;
  with_tool(sc.spec, R, ToolShape::kSphere, &m);
  double zt, zb;
  surface_span(m, top.node.x(), top.node.y(), &zt, &zb);
  const double depth = o.max_depth_fraction * (zt - zb);
  std::vector<double> at[2];
  for (int k = 0; k < 2; ++k) {
    const double v = o.speed_mm_s * 1e-3 / (k + 1);
    const PressResult pr = press(m, top.node, zt + R, R, v, depth, 0);
    for (int qi = 1; qi <= 8; ++qi) {
      const double q = qi / 8.0;
      // Force at the tick whose tool depth is nearest q x depth.
      double best = 1e9, f = 0;
      for (const Sample& s : pr.run.s)
        if (std::abs(s.tool_depth - q * depth) < best)
          best = std::abs(s.tool_depth - q * depth), f = s.f.z();
      at[k].push_back(f);
    }
  }
  double worst = 0;
  std::string diffs, forces[2];
  for (size_t i = 0; i < at[0].size(); ++i) {
    const double d = std::abs(at[0][i] - at[1][i]) / std::abs(at[1][i]);
    worst = std::max(worst, d);
    diffs += (i ? ", " : "") + fmt("%.2g", 100 * d);
    for (int k = 0; k < 2; ++k) forces[k] += (i ? ", " : "") + fmt("%.4g", at[k][i]);
  }
  for (int k = 0; k < 2; ++k)
    std::printf("| press %s, R %.3g x s, node | %.3g | %s | %s | %s |\n", sc.name.c_str(), factor,
                o.speed_mm_s / (k + 1), forces[k].c_str(), k == 0 ? diffs.c_str() : "",
                k == 0 ? fmt("%.3g", 100 * worst).c_str() : "");
  std::fflush(stdout);
  return 0;
}

bool valid(const Opts& o, std::string* why) {
  auto positive = [](const std::vector<double>& v) {
    return !v.empty() &&
           std::all_of(v.begin(), v.end(), [](double x) { return x > 0 && std::isfinite(x); });
  };
  if (!positive(o.radius_factors))
    return *why = "--radius-factors: every factor must be > 0", false;
  for (const std::string& p : o.positions)
    if (p != "node" && p != "face")
      return *why = "--positions: unknown position '" + p + "' (node, face)", false;
  if (o.positions.empty()) return *why = "--positions: give node and/or face", false;
  if (!(o.speed_mm_s > 0)) return *why = "--speed-mm-s must be > 0", false;
  if (!(o.max_depth_fraction > 0 && o.max_depth_fraction < 1))
    return *why = "--max-depth-fraction must be in (0, 1)", false;
  if (!(o.hold_s >= 0)) return *why = "--hold-s must be >= 0", false;
  if (o.size_mm.size() != 3 || !positive(o.size_mm))
    return *why = "--size: three lengths > 0 (mm)", false;
  if (!positive(o.spacings_mm)) return *why = "--spacing-mm: every spacing must be > 0", false;
  if (!o.cells.empty() &&
      (o.cells.size() != 3 || *std::min_element(o.cells.begin(), o.cells.end()) < 1))
    return *why = "--cells: three counts >= 1", false;
  if (!(o.sphere_radius_mm > 0)) return *why = "--sphere-radius-mm must be > 0", false;
  if (!(o.punch_radius_mm > 0)) return *why = "--punch-radius-mm must be > 0", false;
  if (o.hertz_steps < 5) return *why = "--hertz-steps must be >= 5", false;
  if (o.hertz_settle < 0) return *why = "--hertz-settle must be >= 0", false;
  if (!(o.hertz_dt_ms > 0)) return *why = "--hertz-dt-ms must be > 0", false;
  if (o.hertz_newton < 1 || o.hertz_cg < 1)
    return *why = "--hertz-newton and --hertz-cg must be >= 1", false;
  if (!(o.compression_strain > 0 && o.compression_strain < 0.2))
    return *why = "--compression-strain must be in (0, 0.2)", false;
  if (!positive(o.drag_factors)) return *why = "--drag-factors: every factor must be > 0", false;
  if (!positive(o.drag_depths)) return *why = "--drag-depths: every depth must be > 0", false;
  if (!(o.drag_spacings > 2)) return *why = "--drag-spacings must be > 2", false;
  if (!(o.hold_radius_mm > 0)) return *why = "--hold-radius-mm must be > 0", false;
  if (!(o.hold_depth_mm > 0)) return *why = "--hold-depth-mm must be > 0", false;
  if (!(o.hold_press_s > 0) || !(o.hold_hold_s >= 1))
    return *why = "--hold-press-s must be > 0 and --hold-hold-s >= 1", false;
  return true;
}

}  // namespace

void register_contact(CLI::App& app, Runner* run) {
  auto o = std::make_shared<Opts>();
  CLI::App* cmd = app.add_subcommand(
      "contact", "Measure the surface contact: presses, Hertz and Sneddon, drags, holds");
  cmd->add_option("--scene", o->scenes,
                  "scene file(s) (.pbtxt); --suite: paper-cube, "
                  "paper-cube-hooke, anisotropic-block");
  cmd->add_flag("--suite", o->suite,
                "every experiment (press, hertz, drag, hold, a quasi-static "
                "check) on the default scenes");
  cmd->add_option("--experiment", o->experiments, "press, hertz, drag, hold, speed (repeatable)")
      ->delimiter(',');
  cmd->add_option("--out-dir", o->out_dir, "write one CSV per case here");
  cmd->add_option("--speed-mm-s", o->speed_mm_s, "press and drag speed")->capture_default_str();
  cmd->add_option("--radius-factors", o->radius_factors, "press radii / top lattice spacing")
      ->delimiter(',')
      ->capture_default_str();
  cmd->add_option("--positions", o->positions, "press positions: node, face")
      ->delimiter(',')
      ->capture_default_str();
  cmd->add_option("--max-depth-fraction", o->max_depth_fraction,
                  "press depth / body height under the press point")
      ->capture_default_str();
  cmd->add_option("--hold-s", o->hold_s, "press: hold after the press (s)")->capture_default_str();
  cmd->add_option("--size", o->size_mm, "hertz block size x,y,z (mm)")
      ->delimiter(',')
      ->capture_default_str();
  cmd->add_option("--spacing-mm", o->spacings_mm, "hertz block lattice spacings (mm)")
      ->delimiter(',')
      ->capture_default_str();
  cmd->add_option("--cells", o->cells,
                  "hertz: one block of these cells x,y,z (overrides "
                  "--spacing-mm)")
      ->delimiter(',');
  cmd->add_flag("--hertz-on-scene", o->hertz_on_scene,
                "hertz on the scene's own body instead of a block");
  cmd->add_option("--sphere-radius-mm", o->sphere_radius_mm, "hertz sphere R")
      ->capture_default_str();
  cmd->add_option("--punch-radius-mm", o->punch_radius_mm, "hertz punch radius")
      ->capture_default_str();
  cmd->add_option("--hertz-steps", o->hertz_steps, "hertz: depth levels of the press to 0.1 R")
      ->capture_default_str();
  cmd->add_option("--hertz-settle", o->hertz_settle,
                  "hertz: steps held at each level before it is read")
      ->capture_default_str();
  cmd->add_option("--hertz-dt-ms", o->hertz_dt_ms, "hertz implicit step")->capture_default_str();
  cmd->add_option("--hertz-newton", o->hertz_newton, "hertz Newton iterations per step")
      ->capture_default_str();
  cmd->add_option("--hertz-cg", o->hertz_cg, "hertz CG iterations per Newton iteration")
      ->capture_default_str();
  cmd->add_option("--compression-strain", o->compression_strain,
                  "hertz: plate compression strain for E and nu")
      ->capture_default_str();
  cmd->add_option("--drag-factors", o->drag_factors, "drag radii / spacing")
      ->delimiter(',')
      ->capture_default_str();
  cmd->add_option("--drag-depths", o->drag_depths, "drag depths / R")
      ->delimiter(',')
      ->capture_default_str();
  cmd->add_option("--drag-spacings", o->drag_spacings, "drag length in node spacings")
      ->capture_default_str();
  cmd->add_option("--hold-radius-mm", o->hold_radius_mm, "hold sphere radius")
      ->capture_default_str();
  cmd->add_option("--hold-depth-mm", o->hold_depth_mm, "hold press depth")->capture_default_str();
  cmd->add_option("--hold-press-s", o->hold_press_s, "hold: press duration")->capture_default_str();
  cmd->add_option("--hold-hold-s", o->hold_hold_s, "hold: hold duration (>= 1 s)")
      ->capture_default_str();
  cmd->callback([o, run] {
    *run = [o]() -> int {
      std::string why;
      if (!valid(*o, &why)) {
        std::fprintf(stderr, "%s: %s\n", kCmd, why.c_str());
        return 2;
      }
      std::vector<std::string> exps = o->experiments;
      if (o->suite && exps.empty()) exps = {"press", "hertz", "drag", "hold", "speed"};
      if (exps.empty()) {
        std::fprintf(stderr, "%s: give --experiment press|hertz|drag|hold|speed or --suite\n",
                     kCmd);
        return 2;
      }
      for (const std::string& e : exps)
        if (e != "press" && e != "hertz" && e != "drag" && e != "hold" && e != "speed") {
          std::fprintf(stderr,
                       "%s: --experiment: unknown experiment '%s' (press, hertz, drag, "
                       "hold, speed)\n",
                       kCmd, e.c_str());
          return 2;
        }
      std::vector<std::string> paths = o->scenes;
      const bool defaults = paths.empty();
      if (defaults) {
        if (!o->suite) {
          std::fprintf(stderr, "%s: --scene is required (or --suite for the default scenes)\n",
                       kCmd);
          return 2;
        }
        paths = {find_scene("configs/paper-cube.pbtxt"),
                 find_scene("configs/paper-cube-hooke.pbtxt"),
                 find_scene("configs/anisotropic-block.pbtxt")};
      }
      std::vector<Scene> scenes;
      for (const std::string& p : paths) {
        Scene sc;
        sc.path = p;
        sc.name = stem(p);
        if (std::string e = io::load_scene(p, &sc.spec); !e.empty()) {
          std::fprintf(stderr, "%s: --scene %s: %s\n", kCmd, p.c_str(), e.c_str());
          return 2;
        }
        scenes.push_back(std::move(sc));
      }
      if (!o->out_dir.empty()) {
        ::mkdir(o->out_dir.c_str(), 0755);
        struct stat st;
        if (::stat(o->out_dir.c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) {
          std::fprintf(stderr, "%s: --out-dir %s: cannot create\n", kCmd, o->out_dir.c_str());
          return 2;
        }
      }
      // The suite's hold, hertz and speed check use the first scene (the paper cube).
      const std::vector<Scene> first(scenes.begin(), scenes.begin() + 1);
      for (const std::string& e : exps) {
        int rc = 0;
        if (e == "press") rc = run_press(*o, scenes);
        if (e == "hertz") rc = run_hertz(*o, scenes);
        if (e == "drag") rc = run_drag(*o, scenes);
        if (e == "hold") rc = run_hold(*o, defaults ? first : scenes);
        if (e == "speed") rc = run_speed_check(*o, scenes);
        if (rc != 0) return rc;
      }
      return 0;
    };
  });
}

}  // namespace conica::lab
