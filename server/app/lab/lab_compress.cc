// conica-lab compress: the phantom compression test on a scene. The scene's first plate is the
// moving top plate (one is added above the body when the scene has none); it moves into the
// body at a constant rate with the scene's own integrator and time step. Writes
// displacement_mm,force_N (plate travel from first contact, force on the plate, compression
// positive).
//   --bonded: both plates bonded to the faces they touch (no slip); implies --quasi-static.
//   --quasi-static: the plate moved in increments, the body at equilibrium after each one
//   (lab/quasi_static.h), instead of at a rate with the scene's integrator.
//   --friction MU: the moving plate with Coulomb friction MU (the base as the scene holds it).
//   --served: a multi-rate scene (solver body_rate_hz) stepped as the server's body thread steps
//   it (its step, Newton cap and factor schedule: lab/compression.h).
//   --data FILE...: the mean of these measured curves on the output grid and the mean relative
//   error of the run against it from --skip-strain on (the calibration's metric).
//   --check-stability: before the run, the body's equilibrium along a quasi-static compression
//   to --to-strain checked for modes that lower its energy (lab/compression.h,
//   compression_equilibria): the strain where the body buckles as a whole, which the material's
//   check at load cannot see.
//   A run that blew up or found no equilibrium fails (exit 3), its curve cut before it.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>

#include "app/lab/lab.h"
#include "core/step.h"
#include "io/curve_reader.h"
#include "io/scene.h"
#include "lab/calibration.h"
#include "lab/compression.h"
#include "lab/quasi_static.h"

namespace conica::lab {

// A line per increment on a long run (past 10 s), with an estimate of the time left.
std::function<void(int, double, double, bool, long)> quasi_static_progress(const char* me,
                                                                           int samples) {
  const auto started = std::chrono::steady_clock::now();
  return [me, samples, started](int j, double u, double rel, bool settled, long steps) {
    const double t =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    if (t < 10) return;
    std::fprintf(stderr,
                 "%s: increment %d of %d, %.4g mm: %s (%.2g of the reaction out of balance), %ld "
                 "implicit steps, %.0f s, about %.0f s left\n",
                 me, j, samples, u * 1e3, settled ? "settled" : "NOT settled", rel, steps, t,
                 t / j * (samples - j));
  };
}

void register_compress(CLI::App& app, Runner* run) {
  struct Opts {
    std::string scene, out = "-", plot;
    double rate_mm_per_min = 500;
    double to_strain = 0.5;
    int samples = 50;
    bool bonded = false, quasi_static = false;
    double friction = 0;
    double tolerance = 1e-4;
    bool static_solve = false;
    double static_tolerance = 1e-5;
    bool served = false;
    bool check_stability = false;
    std::vector<std::string> data;
    double skip_strain = 0.03;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* cmd = app.add_subcommand(
      "compress", "Compress a body between rigid plates and write its force-displacement curve");
  cmd->add_option("--scene", o->scene, "scene file (.pbtxt)")->required();
  cmd->add_option("--rate-mm-per-min", o->rate_mm_per_min, "plate speed, mm/min")
      ->capture_default_str();
  cmd->add_option("--to-strain", o->to_strain, "final plate travel over body height")
      ->capture_default_str();
  cmd->add_option("--samples", o->samples, "curve points after the origin")->capture_default_str();
  cmd->add_option("--out", o->out, "CSV displacement_mm,force_N ('-': stdout)")
      ->capture_default_str();
  cmd->add_option("--plot", o->plot, "also draw the curve to this PNG file");
  cmd->add_flag("--check-stability", o->check_stability,
                "first check the body's equilibrium for buckling modes along a quasi-static "
                "compression to --to-strain (25 increments)");
  cmd->add_flag("--bonded", o->bonded,
                "bond both plates to the faces they touch (no slip); implies --quasi-static");
  cmd->add_option("--friction", o->friction,
                  "Coulomb friction coefficient of the moving plate (0: frictionless; the base "
                  "as the scene holds it)")
      ->capture_default_str();
  cmd->add_flag("--quasi-static", o->quasi_static,
                "move the plate in --samples increments, each brought to equilibrium");
  cmd->add_option("--tolerance", o->tolerance,
                  "quasi-static: out-of-balance force over the reaction to converge")
      ->capture_default_str();
  cmd->add_flag("--static", o->static_solve,
                "static equilibrium at each sample (continuation in strain, no rate terms) "
                "instead of moving the plate at --rate-mm-per-min");
  cmd->add_option("--static-tolerance", o->static_tolerance,
                  "--static: relative change of the plate force that ends a solve")
      ->capture_default_str();
  cmd->add_flag("--served", o->served,
                "a multi-rate scene (solver body_rate_hz) steps as the server's body thread "
                "steps it: its own step, Newton cap and factor schedule");
  cmd->add_option("--data", o->data,
                  "measured curves (displacement_mm,force_N): print the run's mean relative "
                  "error against their mean");
  cmd->add_option("--skip-strain", o->skip_strain, "--data: the error is taken from this strain on")
      ->capture_default_str();
  cmd->callback([o, run] {
    *run = [o]() -> int {
      if (!(o->friction >= 0) || !std::isfinite(o->friction) || (o->friction > 0 && o->bonded)) {
        std::fprintf(stderr,
                     "conica-lab compress: --friction must be >= 0 and is not for --bonded "
                     "plates (they do not slip)\n");
        return 2;
      }
      if (!(o->rate_mm_per_min > 0) || !(o->to_strain > 0 && o->to_strain < 1) || o->samples < 1) {
        std::fprintf(stderr,
                     "conica-lab compress: need --rate-mm-per-min > 0, 0 < --to-strain < 1, "
                     "--samples >= 1\n");
        return 2;
      }
      BodySpec spec;
      if (std::string e = io::load_scene(o->scene, &spec); !e.empty()) {
        std::fprintf(stderr, "conica-lab compress: %s\n", e.c_str());
        return 2;
      }
      if (ensure_top_plate(&spec))
        std::fprintf(stderr, "conica-lab compress: the scene has no plate: added one on top\n");
      if (o->friction > 0) spec.planes[0].friction = o->friction;
      if (o->bonded) {
        if (std::string e = bond_compression_plates(&spec); !e.empty()) {
          std::fprintf(stderr, "conica-lab compress: %s: %s\n", o->scene.c_str(), e.c_str());
          return 2;
        }
      }
      Model m;
      if (std::string e = build_model(spec, &m); !e.empty()) {
        std::fprintf(stderr, "conica-lab compress: %s: %s\n", o->scene.c_str(), e.c_str());
        return 2;
      }
      // The measured curves, read before the run (units and reach against the body's height).
      const double height = plate_height(m);
      std::vector<Curve> measured;
      io::CurveRequest request;
      request.height = height;
      request.max_strain = o->to_strain;
      if (!read_measured_curves("conica-lab compress", o->data, request, &measured)) return 2;
      if (!o->bonded && m.planes[0].friction > 0)
        std::fprintf(stderr,
                     "conica-lab compress: frictional plates: the moving plate with Coulomb "
                     "friction %.4g\n",
                     m.planes[0].friction);
      const double onset =
          warn_material_stability("conica-lab compress", m, -m.planes[0].normal, o->to_strain);
      double structural = -1;  // strain where the body's equilibrium was found unstable
      if (o->check_stability) {
        const CompressionEquilibria e = compression_equilibria(m, o->to_strain, 25);
        structural = e.unstable_at;
        if (e.unstable_at < 0)
          std::fprintf(stderr,
                       "conica-lab compress: the body's equilibrium is stable to %.1f %% strain "
                       "(%d increments checked%s)\n",
                       100 * e.stable_to, e.checked,
                       e.factored ? "" : "; some factors failed and are not counted");
        else
          std::fprintf(stderr,
                       "conica-lab compress: WARNING: the body's equilibrium is stable to %.1f "
                       "%% strain and unstable at %.1f %% (%d mode(s) along which its energy "
                       "falls): the body buckles as a whole there (e.g. its faces slide "
                       "sideways on frictionless plates) though its material is stable; a "
                       "dynamic or served run leaves the homogeneous state there, and a "
                       "quasi-static curve past it follows a branch no real run takes\n",
                       100 * e.stable_to, 100 * e.unstable_at, e.modes);
      }
      CompressionStats st;
      Curve c;
      if (o->bonded || o->quasi_static) {
        // The plate as the rigid penalty compression_curve uses.
        m.planes[0].stiffness = std::max(m.planes[0].stiffness, rigid_plate_stiffness(m, false));
        QuasiStaticOptions qo;
        qo.samples = o->samples;
        qo.tolerance = o->tolerance;
        qo.stop_at_failure = true;  // the curve is cut there anyway
        qo.progress = quasi_static_progress("conica-lab compress", qo.samples);
        QuasiStaticStats qs;
        c = quasi_static_curve(m, plate_load(m), plate_reaction(), o->to_strain * height, qo, &qs);
        st.steps = qs.steps;
        st.dt = qo.dt;
        st.rollbacks = qs.rollbacks;
        st.failed_at = qs.failed_at;
        st.plate_stiffness = m.planes[0].stiffness;
        std::fprintf(
            stderr,
            "conica-lab compress: quasi-static, %s plates, %d increments, %ld implicit "
            "steps; %s: worst out-of-balance %.2g of the reaction (tolerance %.2g), %d "
            "increment(s) unconverged, rollbacks %llu, hard stops %llu\n",
            o->bonded ? "bonded" : (m.planes[0].friction > 0 ? "frictional" : "frictionless"),
            qs.increments, qs.steps, qs.unconverged == 0 ? "converged" : "NOT CONVERGED",
            qs.worst_residual, qo.tolerance, qs.unconverged,
            static_cast<unsigned long long>(qs.rollbacks),
            static_cast<unsigned long long>(qs.hard_stops));
      } else if (o->static_solve) {
        c = static_compression_curve(m, o->to_strain, o->samples, &st, o->static_tolerance);
      } else {
        if (o->served && !(m.options.body_rate_hz > 0))
          std::fprintf(stderr,
                       "conica-lab compress: --served: the scene is not multi-rate (no "
                       "body_rate_hz): stepped at its own time step\n");
        c = compression_curve(m, o->rate_mm_per_min * 1e-3 / 60, o->to_strain, o->samples, &st,
                              o->served);
      }
      // A run that blew up (a guard trip, a node through the rigid plate, or a quasi-static
      // increment left far out of balance) is no result past that point. The curve stops at the
      // last sample before it, and the run fails.
      const bool blew_up = st.failed_at >= 0;
      if (blew_up) {
        std::fprintf(stderr,
                     "conica-lab compress: %s: the body failed at %.4g mm of plate travel (strain "
                     "%.3g; %llu guard rollbacks, a node up to %.3g mm behind the plate, or no "
                     "equilibrium within %.3g of the reaction): the curve stops at the last "
                     "sample before it\n",
                     o->scene.c_str(), st.failed_at * 1e3, st.failed_at / height,
                     static_cast<unsigned long long>(st.rollbacks), st.max_penetration * 1e3,
                     kQuasiStaticFailure);
        if (onset >= 0 && st.failed_at / height >= onset - 0.02)
          std::fprintf(stderr,
                       "conica-lab compress: the failure is past the material's stability limit "
                       "(%.1f %% strain, above)\n",
                       100 * onset);
        if (structural >= 0 && st.failed_at / height >= structural - 0.02)
          std::fprintf(stderr,
                       "conica-lab compress: the failure is past the strain where the body's "
                       "equilibrium was found unstable (%.1f %% strain, above)\n",
                       100 * structural);
        cut_at_failure(&c, st.failed_at);
      }
      std::string csv = "displacement_mm,force_N\n";
      char line[96];
      for (const CurvePoint& p : c) {
        std::snprintf(line, sizeof line, "%.6f,%.9g\n", p.displacement * 1e3, p.force);
        csv += line;
      }
      FILE* out = o->out == "-" ? stdout : std::fopen(o->out.c_str(), "w");
      if (!out) {
        std::fprintf(stderr, "conica-lab compress: cannot write %s\n", o->out.c_str());
        return 1;
      }
      std::fputs(csv.c_str(), out);
      if (out != stdout) std::fclose(out);
      std::fprintf(stderr,
                   "conica-lab compress: %s, height %.4g mm, %ld %s steps of %.4g ms, plate "
                   "penalty %.4g N/m, max penetration %.3g mm, rollbacks %llu, force at %.4g mm: "
                   "%.6g N, step time %.4g us, layer spread %.3g %% of the half width\n",
                   o->scene.c_str(), height * 1e3, st.steps,
                   o->static_solve || o->quasi_static || o->bonded
                       ? "static (implicit)"
                       : integrator_name(m.options.integrator),
                   st.dt * 1e3, st.plate_stiffness, st.max_penetration * 1e3,
                   static_cast<unsigned long long>(st.rollbacks), c.back().displacement * 1e3,
                   c.back().force, st.step_seconds * 1e6,
                   st.half_width > 0 ? 100 * st.layer_spread / st.half_width : 0.0);
      if (!measured.empty()) {
        std::vector<double> grid, model, mean;
        for (const CurvePoint& p : c) {
          grid.push_back(p.displacement);
          model.push_back(p.force);
        }
        std::string why;
        if (!mean_curve(measured, grid, &mean, &why)) {
          std::fprintf(stderr, "conica-lab compress: --data: %s\n", why.c_str());
          return 2;
        }
        int first = 0;
        while (first + 1 < static_cast<int>(grid.size()) &&
               grid[first] < o->skip_strain * height - 1e-12)
          ++first;
        std::fprintf(stderr,
                     "conica-lab compress: mean relative error %.3f %% against the mean of %zu "
                     "measured curve(s), strain %.3g to %.3g (%zu points)\n",
                     100 * average_relative_error(model, mean, first), measured.size(),
                     grid[first] / height, grid.back() / height, grid.size() - first);
      }
      if (!o->plot.empty()) {
        std::string data = o->out;
        if (data == "-") {
          data = o->plot + ".csv";
          FILE* f = std::fopen(data.c_str(), "w");
          if (!f) {
            std::fprintf(stderr, "conica-lab compress: cannot write %s\n", data.c_str());
            return 1;
          }
          std::fputs(csv.c_str(), f);
          std::fclose(f);
        }
        const int plotted = run_plot_script(
            "plot_curves", "--out '" + o->plot + "' --title 'Compression of " + o->scene +
                               "' --xlabel 'plate travel (mm)' --ylabel 'force (N)' '" + data +
                               "'");
        if (plotted != 0) return plotted;
      }
      return blew_up ? 3 : 0;
    };
  });
}

}  // namespace conica::lab
