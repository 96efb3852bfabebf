#include <cstdio>
#include <cstdlib>

#include "app/lab/lab.h"
#include "core/stability.h"

#ifndef CONICA_SOURCE_DIR
#define CONICA_SOURCE_DIR "."
#endif

namespace conica::lab {

bool read_measured_curves(const char* me, const std::vector<std::string>& paths,
                          const io::CurveRequest& request, std::vector<Curve>* out) {
  for (const std::string& path : paths) {
    auto r = io::read_curve(path, request);
    if (!r) {
      std::fprintf(stderr, "%s: %s\n", me, r.error().c_str());
      return false;
    }
    for (const std::string& w : r.value().warnings)
      std::fprintf(stderr, "%s: warning: %s\n", me, w.c_str());
    Curve curve;
    for (const io::CurveSample& s : r.value().samples) curve.push_back({s.displacement, s.force});
    out->push_back(std::move(curve));
  }
  return true;
}

double warn_material_stability(const char* me, const Model& model, const Vec3& axis,
                               double to_strain) {
  if (model.tetrahedra.empty() && model.hexahedra.empty()) return -1;
  const CompressionStability c = uniaxial_compression_stability(model, axis, to_strain);
  if (c.onset_strain >= 0)
    std::fprintf(stderr,
                 "%s: warning: the material loses strong ellipticity under uniaxial compression "
                 "at %.1f %% strain (its compressed springs' sideways softening outgrows its "
                 "shear stiffness; softest wave along (%.2f, %.2f, %.2f)): a compression past it "
                 "buckles in layers instead of shortening evenly, and a curve past it is no "
                 "result. A card fitted with `conica-lab library` (stability margin) keeps it.\n",
                 me, 100 * c.onset_strain, c.wave.normal.x(), c.wave.normal.y(), c.wave.normal.z());
  return c.onset_strain;
}

int run_plot_script(const std::string& name, const std::string& args) {
  const std::string cmd =
      std::string("/usr/bin/python3 '") + CONICA_SOURCE_DIR + "/scripts/" + name + ".py' " + args;
  const int rc = std::system(cmd.c_str());
  if (rc != 0) std::fprintf(stderr, "conica-lab: plotting failed (%s)\n", cmd.c_str());
  return rc == 0 ? 0 : 1;
}

}  // namespace conica::lab

int main(int argc, char** argv) {
  CLI::App app{"conica-lab: conical mass-spring experiments, offline"};
  app.require_subcommand(1);
  conica::lab::Runner run;
  conica::lab::register_law(app, &run);
  conica::lab::register_mesh(app, &run);
  conica::lab::register_run(app, &run);
  conica::lab::register_stability(app, &run);
  conica::lab::register_active_region(app, &run);
  conica::lab::register_compress(app, &run);
  conica::lab::register_calibrate(app, &run);
  conica::lab::register_viscoelastic(app, &run);
  conica::lab::register_tradeoff(app, &run);
  conica::lab::register_plan(app, &run);
  conica::lab::register_contact(app, &run);
  conica::lab::register_indent(app, &run);
  conica::lab::register_fem_reference(app, &run);
  conica::lab::register_validate(app, &run);
  conica::lab::register_library(app, &run);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  return run ? run() : 0;
}
