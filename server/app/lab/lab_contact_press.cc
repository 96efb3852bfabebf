// conica-lab contact: the experiments on the scenes' own bodies: presses at the top (press), a
// sphere dragged along +x (drag), each integrator's hold (hold) and the quasi-static check.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "app/lab/lab_contact.h"
#include "core/body.h"

namespace conica::lab::contact {

// ---------------------------------------------------------------- press

namespace {

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

}  // namespace

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
        if (run.rollbacks > 0)  // steps that blew up were redone: the drag is not a result
          std::printf(
              "| %s | %.3g | %.3g | %.3g | - | - | - | %.3f | %llu (unstable: no result) | %.1f "
              "|\n",
              sc.name.c_str(), R * 1e3, factor, df, run.max_penetration / R,
              static_cast<unsigned long long>(run.rollbacks), run.seconds);
        else
          std::printf("| %s | %.3g | %.3g | %.3g | %.4g | %.3g | %.3g | %.3f | 0 | %.1f |\n",
                      sc.name.c_str(), R * 1e3, factor, df, mz,
                      mz != 0 ? 100 * (hi - lo) / mz : 0.0, mx, run.max_penetration / R,
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
    const char* sep = i ? ", " : "";
    diffs += sep;
    diffs += fmt("%.2g", 100 * d);
    for (int k = 0; k < 2; ++k) {
      forces[k] += sep;
      forces[k] += fmt("%.4g", at[k][i]);
    }
  }
  for (int k = 0; k < 2; ++k)
    std::printf("| press %s, R %.3g x s, node | %.3g | %s | %s | %s |\n", sc.name.c_str(), factor,
                o.speed_mm_s / (k + 1), forces[k].c_str(), k == 0 ? diffs.c_str() : "",
                k == 0 ? fmt("%.3g", 100 * worst).c_str() : "");
  std::fflush(stdout);
  return 0;
}

}  // namespace conica::lab::contact
