// conica-lab calibrate: fits a scene's conical card to measured force-displacement curves (the
// phantom CSV format: header lines, then columns `Compression (mm)`, `Load (N)`). Several files
// are averaged on a common displacement grid. Prints progress; the last line is
// `average relative error: X %` (full body when it ran, else the surrogate). Writes the fitted
// card as a scene fragment and, with --scene-out, the whole scene with it.
//
// The pipeline's ends are here: the scene and the curves are read through server/io
// (io/scene.h, io/curve_reader.h), the fit runs in server/lab (calibrate(), its stages in
// lab/calibration_stages.h), and the card and scene go out through io/scene_writer.h.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "app/lab/lab.h"
#include "io/curve_reader.h"
#include "io/scene.h"
#include "io/scene_writer.h"
#include "lab/calibration.h"

namespace conica::lab {

void add_full_body_check_options(CLI::App* cmd, FitOptions* fit) {
  cmd->add_option("--escalate-above", fit->escalate_above,
                  "static: the one-card fit's full body (quasi-static, --body-samples increments) "
                  "above this mean relative error, or unsettled, escalates to --escalate-cards "
                  "family cards checked through the full body (0: no full-body check)")
      ->capture_default_str();
  cmd->add_option("--escalate-cards", fit->escalate_cards,
                  "family cards of the escalation (2: edges | diagonals, 3: edges | face | body "
                  "diagonals; 1: none, the one-card body check only)")
      ->capture_default_str();
  cmd->add_option("--escalate-mapping", fit->escalate_mapping,
                  "output space-mapping steps through the full body in the escalation")
      ->capture_default_str();
  cmd->add_option("--body-samples", fit->body_samples,
                  "increments of the full-body check (a divisor of --points)")
      ->capture_default_str();
  cmd->add_option("--stability-margin", fit->stability_margin,
                  "the material stays strongly elliptic under compression to this x max strain "
                  "(the shear term raised where needed; 0: off)")
      ->capture_default_str();
}

void register_calibrate(CLI::App& app, Runner* run) {
  struct Opts {
    std::vector<std::string> data;
    std::string scene, out, scene_out, curves, plot;
    FitOptions fit;  // the options that map one to one, with the library's defaults
    double rate_mm_per_min = 500;
    bool free_moduli = false, no_precompression = false;
    std::string method = "grid";
  };
  auto o = std::make_shared<Opts>();
  CLI::App* cmd = app.add_subcommand(
      "calibrate", "Fit a scene's conical spring card to measured force-displacement curves");
  cmd->add_option("--scene", o->scene, "scene file (.pbtxt)")->required();
  cmd->add_option("--data", o->data, "compression test CSV (repeat for several)")->required();
  cmd->add_option("--method", o->method,
                  "static: the surrogate at --poisson-grid ratios, the full body by static "
                  "equilibrium solves and --space-mapping steps (about a minute); grid: the "
                  "full-body grid of dynamic runs and Levenberg-Marquardt through it (--full-grid "
                  "and the options after it; tens of minutes)")
      ->check(CLI::IsMember({"static", "grid"}))
      ->capture_default_str();
  cmd->add_option("--poisson-grid", o->fit.poisson_grid,
                  "static: Poisson ratios of the surrogate search, from 0.49 down to --poisson-min")
      ->capture_default_str();
  cmd->add_option("--max-strain", o->fit.max_strain, "fit up to this strain")
      ->capture_default_str();
  cmd->add_option("--skip-strain", o->fit.skip_strain,
                  "leave grid points below this strain out of the error (seating toe)")
      ->capture_default_str();
  cmd->add_option("--points", o->fit.points, "displacement grid points")->capture_default_str();
  cmd->add_option("--full-iterations", o->fit.full_iterations,
                  "Levenberg-Marquardt iterations through the full body (0: verify only, "
                  "-1: surrogate only)")
      ->capture_default_str();
  cmd->add_option("--cards", o->fit.cards,
                  "conical cards: 1 (one for all springs), 2 (edges | diagonals), 3 (edges | face "
                  "diagonals | body diagonals)")
      ->capture_default_str();
  cmd->add_flag("--tie-taper", o->fit.tie_taper, "the cards share one taper");
  cmd->add_flag("--free-moduli", o->free_moduli,
                "with several cards: fit every family modulus (default: tied by the lattice's "
                "isotropy condition 4 E_edge = E_face + 8/9 E_body)");
  cmd->add_flag("--no-precompression", o->no_precompression,
                "keep every card's pre-compression at 0 (the plain conical law) instead of "
                "fitting it");
  cmd->add_option("--verify-candidates", o->fit.verify_candidates,
                  "with several cards: surrogate optima checked in the full body")
      ->capture_default_str();
  cmd->add_option("--full-grid", o->fit.full_grid,
                  "one card: tapers x strokes of a grid compressed in the full body before its "
                  "refinement (N x N runs; 0: none)")
      ->capture_default_str();
  cmd->add_option("--full-grid-pre", o->fit.full_grid_pre,
                  "pre-compressions in that grid: 0 and N - 1 more up to its bound (N x N x M "
                  "runs; 1: plain law only)")
      ->capture_default_str();
  cmd->add_option("--full-grid-poisson", o->fit.full_grid_poisson,
                  "Poisson ratios in that grid, from --poisson-min up to the scene's own (N x N x "
                  "M x P runs; 1: the scene's only; not with --poisson)")
      ->capture_default_str();
  cmd->add_option("--poisson-min", o->fit.poisson_min, "lowest Poisson ratio of that grid")
      ->capture_default_str();
  add_full_body_check_options(cmd, &o->fit);
  cmd->add_option("--static-stroke-margin", o->fit.static_stroke_margin,
                  "static: a card's stroke is at least this times its springs' largest strain")
      ->capture_default_str();
  cmd->add_option("--max-layer-spread", o->fit.max_layer_spread,
                  "full-body runs whose node layers spread by more than this fraction of the "
                  "half width at the end (leaned, buckled) are not used")
      ->capture_default_str();
  cmd->add_option("--threads", o->fit.threads,
                  "full-body grid runs in parallel (0: one per hardware thread)")
      ->capture_default_str();
  cmd->add_option("--space-mapping", o->fit.space_mapping,
                  "output space mapping steps after the full-body check (one full compression "
                  "each; 0: none)")
      ->capture_default_str();
  cmd->add_option(
      "--poisson", o->fit.poisson,
      "small-strain Poisson ratio of the body, kept by a volume stiffness "
      "(bulk_modulus) that scales with the cards (default: the scene's own and, through "
      "the full-body grid, lower ones down to --poisson-min; a scene without "
      "bulk_modulus gets none)");
  cmd->add_option("--rate-mm-per-min", o->rate_mm_per_min, "plate speed of the full-body runs")
      ->capture_default_str();
  cmd->add_option("--out", o->out, "write the fitted card here (scene fragment)")->required();
  cmd->add_option("--scene-out", o->scene_out,
                  "also write the scene with the fitted groups and volume terms (read back to "
                  "check it loads)");
  cmd->add_option("--curves", o->curves,
                  "write displacement_mm,data_N,surrogate_N,full_N on the grid to this CSV");
  cmd->add_option("--plot", o->plot, "draw data and model curves to this PNG (needs --curves)");
  cmd->callback([o, run, cmd] {
    *run = [o, cmd]() -> int {
      // Read: the scene, then every curve against the body's height (units, reach).
      auto scene = io::read_scene(o->scene);
      if (!scene) {
        std::fprintf(stderr, "conica-lab calibrate: %s\n", scene.error().c_str());
        return 2;
      }
      BodySpec spec = scene.value().spec;
      ensure_top_plate(&spec);
      io::CurveRequest request;
      request.max_strain = o->fit.max_strain;
      if (Model body; build_model(spec, &body).empty() && !body.planes.empty())
        request.height = plate_height(body);
      std::vector<Curve> curves;
      if (!read_measured_curves("conica-lab calibrate", o->data, request, &curves)) return 2;
      FitOptions fo = o->fit;
      if (o->method == "static") {
        fo.method = FitMethod::kStatic;
        // Two chains (one per thread) of two space-mapping steps unless asked otherwise.
        if (cmd->count("--space-mapping") == 0) fo.space_mapping = 2;
        if (cmd->count("--verify-candidates") == 0) fo.verify_candidates = 2;
      }
      fo.isotropic = !o->free_moduli;
      fo.fit_precompression = !o->no_precompression;
      fo.rate = o->rate_mm_per_min * 1e-3 / 60;
      fo.progress = [](const std::string& s) {
        std::printf("%s\n", s.c_str());
        std::fflush(stdout);
      };
      const FitResult r = calibrate(spec, curves, fo);
      if (!r.error.empty()) {
        std::fprintf(stderr, "conica-lab calibrate: %s\n", r.error.c_str());
        return 2;
      }
      char full[32] = "not run";
      if (r.full_error >= 0) std::snprintf(full, sizeof full, "%.3f %%", 100 * r.full_error);
      std::string head = "# Fitted by conica-lab calibrate to " + std::to_string(curves.size()) +
                         " curve(s) up to strain " + std::to_string(o->fit.max_strain) + ", " +
                         std::to_string(r.cards.size()) + " card(s).\n";
      char line[512];
      for (size_t c = 0; c < r.cards.size(); ++c) {
        const ConicalLaw law(r.cards[c]);
        std::snprintf(line, sizeof line,
                      "# Card %zu: E_c = K0/L0 = %.6g Pa, taper D1/D2 = %.6g, stroke S/L0 = %.6g, "
                      "pre-compression delta0/S = %.6g (K0 = %.6g N/m, S = %.6g m, delta0 = "
                      "%.6g m, stiffness at rest %.6g N/m).\n",
                      c + 1, r.shapes[c].modulus, r.shapes[c].taper, r.shapes[c].stroke,
                      r.shapes[c].precompression, law.k0(), law.stroke(), law.precompression(),
                      law.rest_stiffness());
        head += line;
      }
      std::snprintf(line, sizeof line,
                    "# Lattice: C11 %.6g Pa, C12 = C44 %.6g Pa, E %.6g Pa, Poisson %.4g, Zener "
                    "ratio 2 C44 / (C11 - C12) = %.4g (1: isotropic); volume stiffness %.6g Pa, "
                    "shear stiffness %.6g Pa, body Poisson %.4g.\n"
                    "# Average relative error (strain >= %g): surrogate %.3f %%, full body %s.\n",
                    r.moduli.c11, r.moduli.c12, r.moduli.young, r.moduli.poisson,
                    r.moduli.anisotropy, r.bulk_modulus, r.shear_modulus, r.poisson,
                    o->fit.skip_strain, 100 * r.surrogate_error, full);
      head += line;
      if (r.floor.error >= 0) {
        std::snprintf(line, sizeof line,
                      "# Column floor (best sum of conical laws along the load, none past its "
                      "stroke): %.3f %%; with pre-compressed laws %.3f %%.\n",
                      100 * r.floor.error, 100 * r.floor_precompressed.error);
        head += line;
      }
      // Write: the fitted material (volume terms and conical groups) as a scene fragment.
      BodySpec material;
      material.bulk_modulus = r.bulk_modulus;
      material.spread_modulus = r.spread_modulus;
      material.shear_modulus = r.shear_modulus;
      material.shear_stiffening = r.shear_stiffening;
      for (const auto& g : r.groups)
        if (g.card.law == LawKind::kConical) material.groups.push_back(g);
      if (std::string e = io::write_text_file(o->out, head + io::material_text(material));
          !e.empty()) {
        std::fprintf(stderr, "conica-lab calibrate: %s\n", e.c_str());
        return 1;
      }
      if (!o->scene_out.empty()) {
        io::SceneFile fitted = scene.value();
        fitted.spec.groups = r.groups;
        fitted.spec.bulk_modulus = r.bulk_modulus;
        fitted.spec.spread_modulus = r.spread_modulus;
        fitted.spec.shear_modulus = r.shear_modulus;
        fitted.spec.shear_stiffening = r.shear_stiffening;
        const std::string dir = std::filesystem::path(o->scene_out).parent_path().string();
        if (std::string e = io::write_text_file(
                o->scene_out, head + io::scene_text(fitted, dir.empty() ? "." : dir));
            !e.empty()) {
          std::fprintf(stderr, "conica-lab calibrate: %s\n", e.c_str());
          return 1;
        }
        if (auto back = io::read_scene(o->scene_out); !back) {
          std::fprintf(stderr, "conica-lab calibrate: the written scene does not load: %s\n",
                       back.error().c_str());
          return 1;
        }
        std::printf("fitted scene written to %s\n", o->scene_out.c_str());
      }
      std::printf(
          "fitted group(s) written to %s; lattice Zener ratio %.4g, Poisson %.4g; body "
          "Poisson %.4g with bulk_modulus %.6g Pa\n",
          o->out.c_str(), r.moduli.anisotropy, r.moduli.poisson, r.poisson, r.bulk_modulus);
      if (!o->curves.empty()) {
        std::ofstream cv(o->curves);
        cv << "displacement_mm,data_N,surrogate_N,full_N\n";
        char line[160];
        for (size_t k = 0; k < r.grid.size(); ++k) {
          std::snprintf(line, sizeof line, "%.6f,%.9g,%.9g,%.9g\n", r.grid[k] * 1e3, r.data[k],
                        r.surrogate[k], r.full.empty() ? NAN : r.full[k]);
          cv << line;
        }
        if (!cv) {
          std::fprintf(stderr, "conica-lab calibrate: cannot write %s\n", o->curves.c_str());
          return 1;
        }
      }
      if (!o->plot.empty() && !o->curves.empty()) {
        const int rc = run_plot_script(
            "plot_curves", "--out '" + o->plot + "' --title 'Calibration: " + o->scene +
                               "' --xlabel 'plate travel (mm)' --ylabel 'force (N)' --columns "
                               "data_N,surrogate_N,full_N --labels 'measured (mean),cell "
                               "surrogate,full body' '" +
                               o->curves + "'");
        if (rc != 0) return rc;
      }
      if (r.floor.error >= 0)
        std::printf(
            "column floor (best sum of conical laws along the load): %.3f %%, with "
            "pre-compressed laws: %.3f %%\n",
            100 * r.floor.error, 100 * r.floor_precompressed.error);
      std::printf("average relative error: %.3f %%\n",
                  100 * (r.full_error >= 0 ? r.full_error : r.surrogate_error));
      return 0;
    };
  });
}

}  // namespace conica::lab
