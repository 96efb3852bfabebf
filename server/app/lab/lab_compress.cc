// conica-lab compress: the phantom compression test on a scene. The scene's first plate is the
// moving top plate (one is added above the body when the scene has none); it moves into the
// body at a constant rate with the scene's own integrator and time step. Writes
// displacement_mm,force_N (plate travel from first contact, force on the plate, compression
// positive).
#include <cstdio>
#include <memory>
#include <string>

#include "app/lab/lab.h"
#include "core/step.h"
#include "io/scene.h"
#include "lab/compression.h"

namespace conica::lab {

void register_compress(CLI::App& app, Runner* run) {
  struct Opts {
    std::string scene, out = "-", plot;
    double rate_mm_per_min = 500;
    double to_strain = 0.5;
    int samples = 50;
    bool quasi_static = false;
    double tolerance = 1e-5;
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
  cmd->add_flag("--static", o->quasi_static,
                "static equilibrium at each sample (continuation in strain, no rate terms) "
                "instead of moving the plate at --rate-mm-per-min");
  cmd->add_option("--static-tolerance", o->tolerance,
                  "--static: relative change of the plate force that ends a solve")
      ->capture_default_str();
  cmd->callback([o, run] {
    *run = [o]() -> int {
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
      Model m;
      if (std::string e = build_model(spec, &m); !e.empty()) {
        std::fprintf(stderr, "conica-lab compress: %s\n", e.c_str());
        return 2;
      }
      CompressionStats st;
      const Curve c =
          o->quasi_static
              ? static_compression_curve(m, o->to_strain, o->samples, &st, o->tolerance)
              : compression_curve(m, o->rate_mm_per_min * 1e-3 / 60, o->to_strain, o->samples, &st);
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
                   o->scene.c_str(), plate_height(m) * 1e3, st.steps,
                   o->quasi_static ? "static (implicit)" : integrator_name(m.options.integrator),
                   st.dt * 1e3, st.plate_stiffness, st.max_penetration * 1e3,
                   static_cast<unsigned long long>(st.rollbacks), c.back().displacement * 1e3,
                   c.back().force, st.step_seconds * 1e6,
                   st.half_width > 0 ? 100 * st.layer_spread / st.half_width : 0.0);
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
        return run_plot_script("plot_curves", "--out '" + o->plot + "' --title 'Compression of " +
                                                  o->scene +
                                                  "' --xlabel 'plate travel (mm)' "
                                                  "--ylabel 'force (N)' '" +
                                                  data + "'");
      }
      return 0;
    };
  });
}

}  // namespace conica::lab
