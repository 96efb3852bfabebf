// conica-lab plan: choose resolution, integrator and substeps for a scene from the speed/accuracy
// data of conica-lab tradeoff. The scene is matched to one experiment of the data (a lattice or
// cylinder: the compression; a mesh: the liver indentation) and to the resolution of that
// experiment with the nearest node count. Costs: the data's tick times scaled by the scene's own
// measured tick time over the data's at the matched resolution (symplectic Euler, 1 substep);
// errors: the data's, for the scene's spring law. Prints the cheapest setting meeting the
// tolerance within the budget, why, and the runners-up, or that no setting can and the closest;
// --out writes the chosen solver block as a scene fragment.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "app/lab/lab.h"
#include "core/step.h"
#include "io/scene.h"
#include "lab/tradeoff.h"

#ifndef CONICA_SOURCE_DIR
#define CONICA_SOURCE_DIR "."
#endif

namespace conica::lab {
namespace {

// Median wall time (us) of one tick of `model` released from a 1 % stretch about its centroid
// (so that every stage, the implicit solver's included, has work to do).
double measure_tick_us(const Model& model, long ticks) {
  State s = make_state(model);
  Workspace ws(model);
  Vec3 c = Vec3::Zero();
  for (const Vec3& x : model.rest) c += x;
  c /= std::max(1, model.num_nodes());
  for (int i = 0; i < model.num_nodes(); ++i)
    s.x[i] += (0.01 * (model.rest[i] - c)).cwiseProduct(model.free_axes[i]);
  std::vector<double> us;
  for (long k = 0; k < ticks; ++k) {
    const auto t0 = std::chrono::steady_clock::now();
    step(model, s, ws);
    us.push_back(1e6 *
                 std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  std::nth_element(us.begin(), us.begin() + static_cast<long>(us.size() / 2), us.end());
  return us[us.size() / 2];
}

const char* proto_integrator(const std::string& name) {
  if (name == "explicit") return "EXPLICIT_EULER";
  if (name == "implicit") return "IMPLICIT_EULER";
  return "SYMPLECTIC_EULER";
}

std::string describe(const TradeoffRow& r) {
  char buf[160];
  if (r.integrator == "implicit")
    std::snprintf(buf, sizeof buf, "implicit Euler (%d Newton x %d CG), %d substep%s", r.newton,
                  r.cg, r.substeps, r.substeps == 1 ? "" : "s");
  else
    std::snprintf(buf, sizeof buf, "%s Euler, %d substep%s", r.integrator.c_str(), r.substeps,
                  r.substeps == 1 ? "" : "s");
  return buf;
}

}  // namespace

void register_plan(CLI::App& app, Runner* run) {
  struct Opts {
    std::string scene, data = "docs/figures/tradeoff.csv", out, experiment;
    double tolerance = NAN, budget_us = 1000;
    long calibration_ticks = 500;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* cmd = app.add_subcommand(
      "plan", "Choose resolution, integrator and substeps that meet a force tolerance in a budget");
  cmd->add_option("--scene", o->scene, "scene file (.pbtxt)")->required();
  cmd->add_option("--tolerance", o->tolerance,
                  "largest relative force error against a converged run (0.05: 5 %)")
      ->required();
  cmd->add_option("--budget-us", o->budget_us, "time per 1 ms tick the step may take, us")
      ->capture_default_str();
  cmd->add_option("--data", o->data,
                  "speed/accuracy CSV from conica-lab tradeoff (when the default is absent, a "
                  "quick sweep is run)")
      ->capture_default_str();
  cmd->add_option("--experiment", o->experiment,
                  "compression or indentation (default: lattices compression, meshes indentation)");
  cmd->add_option("--out", o->out, "write the chosen solver { ... } block to this file");
  cmd->add_option("--calibration-ticks", o->calibration_ticks,
                  "ticks timed on the scene to scale the data's costs")
      ->capture_default_str();
  cmd->callback([o, run, cmd] {
    *run = [o, cmd]() -> int {
      const char* me = "conica-lab plan";
      if (!(o->tolerance > 0) || !std::isfinite(o->tolerance)) {
        std::fprintf(stderr,
                     "%s: --tolerance must be a relative error > 0 (0.05 for 5 %%), got %g\n", me,
                     o->tolerance);
        return 2;
      }
      if (!(o->budget_us > 0) || !std::isfinite(o->budget_us)) {
        std::fprintf(stderr, "%s: --budget-us must be > 0 us, got %g\n", me, o->budget_us);
        return 2;
      }
      if (o->calibration_ticks < 1) {
        std::fprintf(stderr, "%s: --calibration-ticks must be >= 1\n", me);
        return 2;
      }
      if (!o->experiment.empty() && o->experiment != "compression" &&
          o->experiment != "indentation") {
        std::fprintf(stderr, "%s: --experiment must be compression or indentation, got '%s'\n", me,
                     o->experiment.c_str());
        return 2;
      }
      auto scene = io::read_scene(o->scene);
      if (!scene) {
        std::fprintf(stderr, "%s: %s\n", me, scene.error().c_str());
        return 2;
      }
      Model model;
      if (std::string e = build_model(scene.value().spec, &model); !e.empty()) {
        std::fprintf(stderr, "%s: %s: %s\n", me, o->scene.c_str(), e.c_str());
        return 2;
      }

      // The data: the file, or a quick sweep when the default file is absent.
      std::vector<TradeoffRow> rows;
      std::string data_path = o->data;
      const bool given = cmd->count("--data") > 0;
      if (!given && !std::filesystem::exists(data_path)) {
        const std::string alt = std::string(CONICA_SOURCE_DIR) + "/" + data_path;
        if (std::filesystem::exists(alt)) data_path = alt;
      }
      if (std::filesystem::exists(data_path)) {
        std::ifstream in(data_path);
        std::stringstream ss;
        ss << in.rdbuf();
        std::string error;
        if (!in || !parse_tradeoff_csv(ss.str(), &rows, &error)) {
          std::fprintf(stderr, "%s: %s: %s\n", me, data_path.c_str(),
                       in ? error.c_str() : "cannot read");
          return 2;
        }
      } else if (given) {
        std::fprintf(stderr, "%s: --data %s: no such file (run conica-lab tradeoff --out PREFIX)\n",
                     me, o->data.c_str());
        return 2;
      } else {
        std::printf("no %s: running the quick sweep (conica-lab tradeoff --quick)\n",
                    o->data.c_str());
        std::string error;
        if (!tradeoff_sweep(true, false, &rows, &error)) {
          std::fprintf(stderr, "%s: quick sweep: %s\n", me, error.c_str());
          return 2;
        }
        data_path = "quick sweep";
      }

      // Which experiment and law the scene is like.
      const std::string experiment =
          !o->experiment.empty()
              ? o->experiment
              : (scene.value().mesh_path.empty() ? "compression" : "indentation");
      int conical = 0;
      for (const SpringGroup& g : model.groups) conical += g.card.law == LawKind::kConical;
      const std::string law = conical > 0 ? "conical" : "hooke";
      // The resolution of the data nearest the scene in node count.
      const TradeoffRow* match = nullptr;
      for (const TradeoffRow& r : rows) {
        if (r.scene != experiment || r.law != law || r.integrator != "symplectic" ||
            r.substeps != 1)
          continue;
        if (!match || std::abs(std::log(double(r.nodes) / model.num_nodes())) <
                          std::abs(std::log(double(match->nodes) / model.num_nodes())))
          match = &r;
      }
      if (!match) {
        std::fprintf(stderr,
                     "%s: %s has no %s rows with %s springs and symplectic Euler at 1 "
                     "substep to calibrate against\n",
                     me, data_path.c_str(), experiment.c_str(), law.c_str());
        return 2;
      }
      if (std::abs(model.options.dt - 1e-3) > 1e-12)
        std::printf("note: the scene ticks every %.4g ms; the data were measured at 1 ms ticks\n",
                    model.options.dt * 1e3);

      // Calibrate: the scene's own tick with symplectic Euler, 1 substep.
      Model probe_model = model;
      probe_model.options.integrator = Integrator::kSymplecticEuler;
      probe_model.options.substeps = 1;
      probe_model.options.active_region = false;
      const double measured = measure_tick_us(probe_model, o->calibration_ticks);
      PlanRequest q;
      q.scene = experiment;
      q.law = law;
      q.tolerance = o->tolerance;
      q.budget_us = o->budget_us;
      q.cost_scale = measured / std::max(match->step_us, 1e-3);
      std::printf("scene %s: %d nodes, %d springs, %s springs; like the %s data (%s)\n",
                  o->scene.c_str(), model.num_nodes(), model.num_springs(), law.c_str(),
                  experiment.c_str(), data_path.c_str());
      std::printf(
          "calibration: symplectic Euler x1 here %.1f us per tick (median of %ld); data "
          "at %s (%d nodes) %.1f us: costs x %.3g\n",
          measured, o->calibration_ticks, match->resolution.c_str(), match->nodes, match->step_us,
          q.cost_scale);
      const Plan p = plan(rows, q);
      auto resolution_note = [&](const TradeoffRow& r) {
        char buf[200];
        if (r.resolution == match->resolution)
          std::snprintf(buf, sizeof buf, "the scene's own resolution (data: %s, %d nodes)",
                        r.resolution.c_str(), r.nodes);
        else
          std::snprintf(buf, sizeof buf, "%s to about %.0f springs (data: %s, %d nodes)",
                        r.springs > match->springs ? "refine" : "coarsen",
                        double(model.num_springs()) * r.springs / match->springs,
                        r.resolution.c_str(), r.nodes);
        return std::string(buf);
      };
      auto line = [&](const PlanCandidate& c) {
        const TradeoffRow& r = rows[c.row];
        std::printf("  %s; %s: %.1f us per tick, error %.3g %%\n", describe(r).c_str(),
                    resolution_note(r).c_str(), c.cost_us, 100 * c.error);
      };
      if (!p.found) {
        std::printf(
            "no setting meets %.3g %% within %.0f us per tick (%d settings of the data "
            "considered). Closest:\n",
            100 * o->tolerance, o->budget_us, p.candidates);
        for (const PlanCandidate& c : p.closest) line(c);
        return 3;
      }
      const TradeoffRow& r = rows[p.chosen.row];
      std::printf("chosen: %s; %s\n", describe(r).c_str(), resolution_note(r).c_str());
      std::printf(
          "why: predicted %.1f us per tick (budget %.0f us) and force error %.3g %% "
          "(tolerance %.3g %%): the cheapest of the settings meeting both, among %d "
          "stable %s settings measured on the %s\n",
          p.chosen.cost_us, o->budget_us, 100 * p.chosen.error, 100 * o->tolerance, p.candidates,
          law.c_str(), experiment.c_str());
      if (!p.runners_up.empty()) {
        std::printf("runners-up:\n");
        for (const PlanCandidate& c : p.runners_up) line(c);
      }
      if (!o->out.empty()) {
        std::ofstream f(o->out);
        const SolverOptions& so = model.options;
        f << "# conica-lab plan --scene " << o->scene << " --tolerance " << o->tolerance
          << " --budget-us " << o->budget_us << "\n";
        f << "# " << describe(r) << "; " << resolution_note(r) << "\n";
        f << "# predicted " << p.chosen.cost_us << " us per tick, force error "
          << 100 * p.chosen.error << " %\n";
        f << "solver {\n  integrator: " << proto_integrator(r.integrator) << "\n";
        f << "  rate_hz: " << 1.0 / so.dt << "\n  substeps: " << r.substeps << "\n";
        if (r.integrator == "implicit")
          f << "  newton_iterations: " << r.newton << "\n  cg_iterations: " << r.cg << "\n";
        if (so.mass_damping != 0) f << "  mass_damping: " << so.mass_damping << "\n";
        if (so.gravity.norm() > 0)
          f << "  gravity { x: " << so.gravity.x() << " y: " << so.gravity.y()
            << " z: " << so.gravity.z() << " }\n";
        f << "}\n";
        if (!f) {
          std::fprintf(stderr, "%s: cannot write %s\n", me, o->out.c_str());
          return 1;
        }
        std::printf("wrote %s\n", o->out.c_str());
      }
      return 0;
    };
  });
}

}  // namespace conica::lab
