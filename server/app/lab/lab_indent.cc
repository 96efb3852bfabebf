// conica-lab indent: a flat rigid punch pressed into the top face of a scene's body,
// quasi-statically (lab/quasi_static.h). The nodes of every top element face whose centre lies
// within --punch-radius of the punch axis (the top face's centre) move down together; the base
// (lowest face) is clamped with --bonded, else held in z only (plus two nodes against rigid
// motion). Writes displacement_mm,force_N (punch travel, force on the punch, pressing positive) and
// prints the step count and whether every increment converged.
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>

#include "app/lab/lab.h"
#include "core/step.h"
#include "io/scene.h"
#include "lab/quasi_static.h"

namespace conica::lab {

void register_indent(CLI::App& app, Runner* run) {
  struct Opts {
    std::string scene, out = "-";
    double radius_mm = 5, depth_mm = 1;
    bool bonded = false, punch_bonded = false;
    int samples = 20;
    double tolerance = 1e-4;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* cmd = app.add_subcommand(
      "indent", "Press a flat rigid punch into a body quasi-statically and write its force curve");
  cmd->add_option("--scene", o->scene, "scene file (.pbtxt)")->required();
  cmd->add_option("--punch-radius", o->radius_mm, "punch radius, mm")->required();
  cmd->add_option("--depth", o->depth_mm, "final punch travel, mm")->required();
  cmd->add_flag("--bonded", o->bonded, "clamp the base (bonded to a rigid support)");
  cmd->add_flag("--punch-bonded", o->punch_bonded,
                "the punch face holds its nodes in x and y too (no slip); default frictionless");
  cmd->add_option("--samples", o->samples, "load increments (curve points after the origin)")
      ->capture_default_str();
  cmd->add_option("--tolerance", o->tolerance,
                  "out-of-balance force over the reaction for an increment to converge")
      ->capture_default_str();
  cmd->add_option("--out", o->out, "CSV displacement_mm,force_N ('-': stdout)")
      ->capture_default_str();
  cmd->callback([o, run] {
    *run = [o]() -> int {
      if (!(o->radius_mm > 0) || !(o->depth_mm > 0) || o->samples < 1 || !(o->tolerance > 0)) {
        std::fprintf(stderr,
                     "conica-lab indent: need --punch-radius > 0, --depth > 0, --samples >= 1, "
                     "--tolerance > 0\n");
        return 2;
      }
      BodySpec spec;
      if (std::string e = io::load_scene(o->scene, &spec); !e.empty()) {
        std::fprintf(stderr, "conica-lab indent: %s\n", e.c_str());
        return 2;
      }
      std::vector<int> punch;
      double area = 0;
      if (std::string e =
              add_flat_punch(&spec, o->radius_mm * 1e-3, o->punch_bonded, o->bonded, &punch, &area);
          !e.empty()) {
        std::fprintf(stderr, "conica-lab indent: %s: %s\n", o->scene.c_str(), e.c_str());
        return 2;
      }
      Model m;
      if (std::string e = build_model(spec, &m); !e.empty()) {
        std::fprintf(stderr, "conica-lab indent: %s: %s\n", o->scene.c_str(), e.c_str());
        return 2;
      }
      QuasiStaticOptions qo;
      qo.samples = o->samples;
      qo.tolerance = o->tolerance;
      qo.stop_at_failure = true;  // the curve is cut there anyway
      qo.progress = quasi_static_progress("conica-lab indent", qo.samples);
      QuasiStaticStats qs;
      Curve c = quasi_static_curve(m, punch_load(punch), punch_reaction(punch), o->depth_mm * 1e-3,
                                   qo, &qs);
      // No equilibrium (an increment left far out of balance): no result from there on.
      if (qs.failed_at >= 0) {
        std::fprintf(stderr,
                     "conica-lab indent: %s: no equilibrium within %.3g of the reaction at %.4g "
                     "mm: the curve stops at the last sample before it\n",
                     o->scene.c_str(), kQuasiStaticFailure, qs.failed_at * 1e3);
        cut_at_failure(&c, qs.failed_at);
      }
      FILE* out = o->out == "-" ? stdout : std::fopen(o->out.c_str(), "w");
      if (!out) {
        std::fprintf(stderr, "conica-lab indent: cannot write %s\n", o->out.c_str());
        return 1;
      }
      std::fputs("displacement_mm,force_N\n", out);
      for (const CurvePoint& p : c) std::fprintf(out, "%.6f,%.9g\n", p.displacement * 1e3, p.force);
      if (out != stdout) std::fclose(out);
      std::fprintf(stderr,
                   "conica-lab indent: %s, %d nodes under a %.4g mm punch (%s; the faces it "
                   "drives cover %.4g mm^2, a disc of radius %.4g mm), base %s; %d "
                   "increments, %ld implicit steps; %s: worst out-of-balance %.2g of the reaction "
                   "(tolerance %.2g), %d increment(s) unconverged, rollbacks %llu, hard stops "
                   "%llu; force at %.4g mm: %.6g N\n",
                   o->scene.c_str(), static_cast<int>(punch.size()), o->radius_mm,
                   o->punch_bonded ? "bonded" : "frictionless", area * 1e6,
                   std::sqrt(area / M_PI) * 1e3, o->bonded ? "bonded" : "sliding", qs.increments,
                   qs.steps, qs.unconverged == 0 ? "converged" : "NOT CONVERGED", qs.worst_residual,
                   qo.tolerance, qs.unconverged, static_cast<unsigned long long>(qs.rollbacks),
                   static_cast<unsigned long long>(qs.hard_stops), c.back().displacement * 1e3,
                   c.back().force);
      return qs.unconverged == 0 ? 0 : 3;
    };
  });
}

}  // namespace conica::lab
