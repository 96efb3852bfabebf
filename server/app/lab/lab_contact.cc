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
// This file holds the command line; the experiments are in lab_contact_press.cc and
// lab_contact_hertz.cc.
#include "app/lab/lab_contact.h"

#include <sys/stat.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "app/lab/lab.h"
#include "io/scene.h"

#ifndef CONICA_SOURCE_DIR
#define CONICA_SOURCE_DIR "."
#endif

namespace conica::lab {
namespace {

using contact::kCmd;
using contact::Opts;
using contact::run_drag;
using contact::run_hertz;
using contact::run_hold;
using contact::run_press;
using contact::run_speed_check;
using contact::Scene;

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
