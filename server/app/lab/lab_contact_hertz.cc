// conica-lab contact hertz: E and nu of a block by a plate compression, then a sphere and a flat
// punch pressed into it, compared with Hertz and Sneddon.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

#include "app/lab/lab_contact.h"
#include "core/body.h"
#include "core/step.h"
#include "lab/compression.h"

namespace conica::lab::contact {

// ---------------------------------------------------------------- hertz

namespace {

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

}  // namespace

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
      b.spec.shear_stiffening = sc.spec.shear_stiffening;
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
                             b.spec.shear_modulus, b.spec.shear_stiffening)
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

}  // namespace conica::lab::contact
