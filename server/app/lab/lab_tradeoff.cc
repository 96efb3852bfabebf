// conica-lab tradeoff: speed against accuracy. Two experiments, each run with every integrator x
// substeps x spring law x resolution:
//  - compression: a 60 x 60 x 40 mm box of the paper cube's material (configs/paper-cube.pbtxt),
//    clamped base, frictionless top plate driven to 30 % strain in 0.15 s, held to 0.2 s;
//    lattices of 20, 10, 6.7 and 5 mm cubic cells (48 to 1,521 nodes).
//  - indentation: the liver (configs/liver-nodes.pbtxt, liver2.msh, 507 nodes, the node penalty
//    whose per-node stiffness the sweep holds fixed) pressed 10 mm along -y
//    at (-0.0485, 0.0716, -0.0093) m by its 10 mm probe (penalty 100 N/m per node, see
//    --probe-stiffness) in 0.2 s, held to 0.3 s. --coarse-liver adds a coarser mesh (SOFA's
//    liver.msh, 181 nodes) mapped onto it by principal axes; it is not in the default sweep
//    because that mesh is not the same organ shape (mean node distance 13.7 mm after mapping, first
//    contact 68 mm deeper along the press line), so its error would measure shape, not resolution.
// Reference per experiment and law: the finest resolution, symplectic Euler, 64 substeps per 1 ms
// tick. Error: max over the run of |F - F_ref| / max |F_ref| (see lab/tradeoff.h). Step time:
// median wall time of one tick over the run, one thread. Writes PREFIX.csv (one row per setting)
// and PREFIX.png (scripts/plot_tradeoff.py) and prints the Pareto front.
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "app/lab/lab.h"
#include "app/lab/lab_sweep.h"
#include "core/step.h"
#include "io/mesh_reader.h"
#include "io/mesh_repair.h"
#include "io/scene.h"
#include "lab/tradeoff.h"

#ifndef CONICA_VERSION
#define CONICA_VERSION "unknown"
#endif
#ifndef CONICA_SOURCE_DIR
#define CONICA_SOURCE_DIR "."
#endif

namespace conica::lab {
namespace {

// A path as given, or under the source tree when it does not exist as given (so the defaults
// work from any directory).
std::string find_file(const std::string& path) {
  if (std::filesystem::exists(path)) return path;
  const std::string alt = std::string(CONICA_SOURCE_DIR) + "/" + path;
  if (std::filesystem::exists(alt)) return alt;
  return path;
}

struct Setting {
  Integrator integrator = Integrator::kSymplecticEuler;
  int newton = 0, cg = 0, substeps = 1;
};

struct Resolution {
  std::string name;
  BodySpec spec;                 // conical law as loaded
  Vec3 press_at = Vec3::Zero();  // indentation: probe centre at first contact, m
};

struct Experiment {
  std::string name;                     // "compression", "indentation"
  std::vector<Resolution> resolutions;  // coarse to fine; the last is the reference's
  long ticks = 0;
  double strain = 0;  // compression
};

struct SweepConfig {
  std::string cube_scene = "configs/paper-cube.pbtxt";
  std::string liver_scene = "configs/liver-nodes.pbtxt";
  std::string coarse_liver;  // a coarser liver mesh as a second resolution (empty: none)
  bool quick = false;
  bool verbose = true;
  int reference_substeps = 64;
  double probe_stiffness = 0;  // N/m per node for the indentation; 0: the liver scene's own
  double strain = 0.3;         // compression, engineering strain
};

// Indentation path of the liver press (the viewer figure's press).
const Vec3 kPressAt(-0.0485, 0.0716, -0.0093);
const Vec3 kPressAxis(0, -1, 0);
constexpr double kPressDepth = 0.01;    // m
constexpr double kPressRamp = 0.2;      // s
constexpr double kCompressRamp = 0.15;  // s

Model build(const BodySpec& spec, const Setting& s, std::string* error) {
  BodySpec b = spec;
  b.options.integrator = s.integrator;
  b.options.substeps = s.substeps;
  if (s.integrator == Integrator::kImplicitEuler) {
    b.options.newton_iterations = s.newton;
    b.options.cg_iterations = s.cg;
  }
  Model m;
  *error = build_model(b, &m);
  return m;
}

// Fixes contact penalties at the values the scene gets at 1 substep, so that every setting
// simulates the same contact law (the default penalty depends on the substep length).
bool freeze_penalties(BodySpec* spec, std::string* error) {
  BodySpec b = *spec;
  b.options.substeps = 1;
  Model m;
  *error = build_model(b, &m);
  if (!error->empty()) return false;
  for (size_t k = 0; k < spec->probes.size(); ++k)
    spec->probes[k].stiffness = m.probes[k].stiffness;
  for (size_t k = 0; k < spec->planes.size(); ++k)
    spec->planes[k].stiffness = m.planes[k].stiffness;
  return true;
}

// Where a sphere of radius R moving from `from` along the unit `axis` first touches a node: the
// smallest s with |x - (from + s axis)| = R over the nodes within R of the line.
Vec3 first_touch(const std::vector<Vec3>& nodes, const Vec3& from, const Vec3& axis, double R) {
  double best = std::numeric_limits<double>::infinity();
  for (const Vec3& x : nodes) {
    const Vec3 u = x - from;
    const double along = u.dot(axis), lat2 = (u - along * axis).squaredNorm();
    if (lat2 < R * R) best = std::min(best, along - std::sqrt(R * R - lat2));
  }
  return std::isfinite(best) ? from + best * axis : from;
}

Trace run_experiment(const Experiment& e, const Resolution& r, const Model& m) {
  if (e.name == "compression")
    return run_compression(m, e.strain, kCompressRamp * static_cast<double>(e.ticks) / 200.0,
                           e.ticks);
  return run_indentation(m, r.press_at, kPressAxis, kPressDepth,
                         kPressRamp * static_cast<double>(e.ticks) / 300.0, e.ticks);
}

bool make_experiments(const SweepConfig& c, std::vector<Experiment>* out, std::string* error) {
  // Compression: the paper cube's material in a 60 x 60 x 40 mm box.
  BodySpec material;
  if (std::string e = io::load_scene(find_file(c.cube_scene), &material); !e.empty()) {
    *error = e;
    return false;
  }
  Experiment comp;
  comp.name = "compression";
  comp.ticks = c.quick ? 100 : 200;
  comp.strain = c.strain;
  const Vec3 size(0.06, 0.06, 0.04);
  struct Lattice {
    const char* name;
    std::array<int, 3> cells;
  };
  std::vector<Lattice> lattices = {
      {"20mm", {3, 3, 2}}, {"10mm", {6, 6, 4}}, {"6.7mm", {9, 9, 6}}, {"5mm", {12, 12, 8}}};
  if (c.quick) lattices = {{"20mm", {3, 3, 2}}, {"10mm", {6, 6, 4}}};
  for (const Lattice& l : lattices)
    comp.resolutions.push_back({l.name, compression_body(material, size, l.cells)});
  out->push_back(std::move(comp));

  // Indentation: the liver, and the coarser SOFA liver mapped onto it.
  auto liver = io::read_scene(find_file(c.liver_scene));
  if (!liver) {
    *error = liver.error();
    return false;
  }
  Experiment ind;
  ind.name = "indentation";
  ind.ticks = c.quick ? 100 : 300;
  BodySpec fine = liver.value().spec;
  if (fine.probes.empty()) {
    *error = c.liver_scene + ": the indentation needs a probe";
    return false;
  }
  if (c.probe_stiffness > 0) fine.probes[0].stiffness = c.probe_stiffness;
  if (!c.coarse_liver.empty()) {
    const std::string coarse_path = c.coarse_liver;
    auto mesh = io::read_mesh(coarse_path);
    if (!mesh) {
      std::fprintf(stderr, "conica-lab tradeoff: coarse liver skipped: %s\n", mesh.error().c_str());
    } else {
      BodySpec coarse = fine;
      coarse.mesh = mesh.value().mesh;
      io::repair(coarse.mesh);
      const double d = register_principal_axes(&coarse.mesh.nodes, fine.mesh.nodes);
      const double v_fine = io::total_volume(fine.mesh), v_coarse = io::total_volume(coarse.mesh);
      // Equal volumes: the same organ, so the same amount of tissue under the probe.
      const double s = std::cbrt(v_fine / v_coarse);
      Vec3 c0 = Vec3::Zero();
      for (const Vec3& x : coarse.mesh.nodes) c0 += x;
      c0 /= static_cast<double>(coarse.mesh.nodes.size());
      for (Vec3& x : coarse.mesh.nodes) x = c0 + s * (x - c0);
      if (c.verbose)
        std::printf(
            "coarse liver %s: %zu nodes mapped onto %zu by principal axes, mean node "
            "distance %.2f mm, volume scaled by %.3f to %.3g l\n",
            coarse_path.c_str(), coarse.mesh.nodes.size(), fine.mesh.nodes.size(), 1e3 * d,
            s * s * s, 1e3 * v_fine);
      ind.resolutions.push_back({std::filesystem::path(coarse_path).stem().string(), coarse});
    }
  }
  ind.resolutions.push_back({std::filesystem::path(liver.value().mesh_path).stem().string(), fine});
  // Each mesh is pressed from where the probe first touches it on the press line.
  for (Resolution& r : ind.resolutions) {
    r.press_at = first_touch(r.spec.mesh.nodes, kPressAt, kPressAxis, r.spec.probes[0].radius);
    if (c.verbose)
      std::printf(
          "indentation %s: first contact %.2f mm along the press line from the nominal "
          "start\n",
          r.name.c_str(), 1e3 * (r.press_at - kPressAt).dot(kPressAxis));
  }
  out->push_back(std::move(ind));
  return true;
}

}  // namespace

bool tradeoff_sweep(bool quick, bool verbose, std::vector<TradeoffRow>* rows, std::string* error,
                    double probe_stiffness, double strain, const std::string& coarse_liver,
                    const TradeoffUnits& units) {
  SweepConfig c;
  c.coarse_liver = coarse_liver;
  c.probe_stiffness = probe_stiffness;
  c.strain = strain;
  c.quick = quick;
  c.verbose = verbose;
  if (quick) c.reference_substeps = 16;
  std::vector<Experiment> experiments;
  if (!make_experiments(c, &experiments, error)) return false;
  std::vector<Setting> settings;
  const std::vector<int> explicit_substeps =
      quick ? std::vector<int>{1, 2} : std::vector<int>{1, 2, 4, 8};
  const std::vector<int> implicit_substeps =
      quick ? std::vector<int>{1} : std::vector<int>{1, 2, 4};
  for (int n : explicit_substeps) settings.push_back({Integrator::kSymplecticEuler, 0, 0, n});
  for (int n : explicit_substeps) settings.push_back({Integrator::kExplicitEuler, 0, 0, n});
  for (int n : implicit_substeps) settings.push_back({Integrator::kImplicitEuler, 1, 20, n});
  if (!quick)
    for (int n : implicit_substeps) settings.push_back({Integrator::kImplicitEuler, 2, 40, n});

  int unit = -1;
  for (const Experiment& e : experiments) {
    for (const char* law : {"conical", "hooke"}) {
      ++unit;
      if (units.runs && !units.runs(unit)) continue;
      const size_t first_row = rows->size();
      const bool hooke = std::string(law) == "hooke";
      // The reference: finest resolution, symplectic Euler at the smallest step.
      BodySpec ref_spec = e.resolutions.back().spec;
      if (hooke) ref_spec = hooke_twin(ref_spec);
      if (!freeze_penalties(&ref_spec, error)) return false;
      const Setting ref_set{Integrator::kSymplecticEuler, 0, 0, c.reference_substeps};
      Model ref_model = build(ref_spec, ref_set, error);
      if (!error->empty()) return false;
      const Trace ref = run_experiment(e, e.resolutions.back(), ref_model);
      if (ref.rollbacks > 0 || !ref.finite) {
        *error = e.name + " " + law + ": the reference run is not stable (" +
                 std::to_string(ref.rollbacks) + " rollbacks)";
        return false;
      }
      double peak = 0;
      for (const Vec3& f : ref.force) peak = std::max(peak, f.norm());
      if (verbose) {
        // How converged the reference is: the same run at half its substeps.
        const Setting half{Integrator::kSymplecticEuler, 0, 0, c.reference_substeps / 2};
        const Trace h = run_experiment(e, e.resolutions.back(), build(ref_spec, half, error));
        std::printf(
            "%s, %s: reference %s symplectic x%d, peak force %.4g N; x%d differs by "
            "%.3g %%",
            e.name.c_str(), law, e.resolutions.back().name.c_str(), c.reference_substeps, peak,
            c.reference_substeps / 2, 100 * force_error(h.force, ref.force));
        if (!ref_model.probes.empty())
          std::printf("; probe penalty %.4g N/m per node", ref_model.probes[0].stiffness);
        std::printf("\n");
      }
      for (const Resolution& res : e.resolutions) {
        BodySpec spec = hooke ? hooke_twin(res.spec) : res.spec;
        if (!freeze_penalties(&spec, error)) return false;
        for (const Setting& s : settings) {
          const Model m = build(spec, s, error);
          if (!error->empty()) return false;
          const Trace t = run_experiment(e, res, m);
          TradeoffRow r;
          r.scene = e.name;
          r.resolution = res.name;
          r.nodes = m.num_nodes();
          r.springs = m.num_springs();
          r.integrator = integrator_name(s.integrator);
          r.newton = s.newton;
          r.cg = s.cg;
          r.substeps = s.substeps;
          r.law = law;
          r.step_us = t.tick_us_median;
          r.cpu_us = t.cpu_us_mean;
          r.error = force_error(t.force, ref.force);
          r.rms_error = force_rms_error(t.force, ref.force);
          r.rollbacks = t.rollbacks;
          double p = 0;
          for (const Vec3& f : t.force) p = std::max(p, f.norm());
          r.stable = t.rollbacks == 0 && t.finite && p <= 2 * peak;
          if (verbose)
            std::printf(
                "  %-11s %-7s %5d nodes %-10s %dx%-3d x%d %-7s %9.1f us  error %9.3g %%"
                "  rms %9.3g %%%s\n",
                r.scene.c_str(), r.resolution.c_str(), r.nodes, r.integrator.c_str(), r.newton,
                r.cg, r.substeps, law, r.step_us, 100 * r.error, 100 * r.rms_error,
                r.stable ? "" : "  UNSTABLE");
          std::fflush(stdout);
          rows->push_back(r);
        }
      }
      if (units.done) {
        *error = units.done(unit, std::vector<TradeoffRow>(rows->begin() + first_row, rows->end()));
        if (!error->empty()) return false;
      }
    }
  }
  return true;
}

void register_tradeoff(CLI::App& app, Runner* run) {
  struct Opts {
    std::string out = "tradeoff";
    bool quick = false, plot = true;
    // The liver scene's own penalty (1.9 N/m per node: a fifth of the explicit limit of its
    // lightest surface node) lets the probe sink in (0.015 N at 10 mm); at 100 N/m the press
    // meets the tissue (0.24 N) and the step matters.
    double probe_stiffness = 100;
    double strain = 0.3;
    std::string coarse_liver;
    Sweep sweep;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* cmd = app.add_subcommand(
      "tradeoff", "Speed against accuracy: integrator x substeps x law x resolution, Pareto chart");
  cmd->add_option("--out", o->out, "output prefix: PREFIX.csv and PREFIX.png")
      ->capture_default_str();
  cmd->add_flag("--quick", o->quick, "a small sweep (2 lattices, the liver, fewer settings)");
  cmd->add_flag("!--no-plot", o->plot, "skip the PNG");
  cmd->add_option("--probe-stiffness", o->probe_stiffness,
                  "indentation probe penalty, N/m per node (0: the liver scene's own)")
      ->capture_default_str();
  cmd->add_option("--strain", o->strain, "compression: final engineering strain")
      ->capture_default_str();
  cmd->add_option("--coarse-liver", o->coarse_liver,
                  "indentation: a coarser liver mesh, mapped onto the scene's by principal axes");
  o->sweep.add_options(cmd);
  cmd->callback([o, run] {
    *run = [o]() -> int {
      std::vector<TradeoffRow> rows;
      std::string error;
      if (!(o->strain > 0 && o->strain < 1)) {
        std::fprintf(stderr, "conica-lab tradeoff: --strain must be in (0, 1)\n");
        return 2;
      }
      if (!(o->probe_stiffness >= 0)) {
        std::fprintf(stderr, "conica-lab tradeoff: --probe-stiffness must be >= 0 N/m\n");
        return 2;
      }
      // Units: the experiment x law pairs; the key: every option that changes a row.
      Sweep& sw = o->sweep;
      char key[512];
      std::snprintf(key, sizeof key,
                    "conica-lab tradeoff%s --probe-stiffness %.17g --strain %.17g "
                    "--coarse-liver '%s' (conica %s)",
                    o->quick ? " --quick" : "", o->probe_stiffness, o->strain,
                    o->coarse_liver.c_str(), CONICA_VERSION);
      if (std::string e = sw.begin(o->out, key, kTradeoffUnits); !e.empty()) {
        std::fprintf(stderr, "conica-lab tradeoff: %s\n", e.c_str());
        return 2;
      }
      std::string text;
      if (sw.merging()) {
        if (std::string e = sw.merged(&text);
            !e.empty() || !parse_tradeoff_csv(tradeoff_csv_header() + text, &rows, &error)) {
          std::fprintf(stderr, "conica-lab tradeoff: %s\n", e.empty() ? error.c_str() : e.c_str());
          return 2;
        }
      } else {
        if (sw.sharded()) std::printf("%s\n", sw.summary().c_str());
        TradeoffUnits units;
        units.runs = [&sw](int u) { return sw.runs(u); };
        units.done = [&sw](int u, const std::vector<TradeoffRow>& unit_rows) {
          std::string t;
          for (const TradeoffRow& r : unit_rows) t += to_csv(r);
          return sw.put(u, t);
        };
        if (!tradeoff_sweep(o->quick, true, &rows, &error, o->probe_stiffness, o->strain,
                            o->coarse_liver, units)) {
          std::fprintf(stderr, "conica-lab tradeoff: %s\n", error.c_str());
          return 2;
        }
        if (sw.sharded()) return 0;  // --merge writes the CSV and the chart
        for (const TradeoffRow& r : rows) text += to_csv(r);
      }
      const std::string csv_path = o->out + ".csv";
      if (std::string e = write_atomic(csv_path, tradeoff_csv_header() + text); !e.empty()) {
        std::fprintf(stderr, "conica-lab tradeoff: %s\n", e.c_str());
        return 1;
      }
      // The Pareto front of each experiment and law.
      for (const char* scene : {"compression", "indentation"})
        for (const char* law : {"conical", "hooke"}) {
          std::vector<TradeoffRow> sub;
          for (const TradeoffRow& r : rows)
            if (r.scene == scene && r.law == law) sub.push_back(r);
          if (sub.empty()) continue;
          std::printf("Pareto front (rms error; max error beside it), %s, %s:\n", scene, law);
          for (int i : pareto_front(sub)) {
            const TradeoffRow& r = sub[i];
            std::printf("  %-7s %5d nodes  %-10s", r.resolution.c_str(), r.nodes,
                        r.integrator.c_str());
            if (r.newton > 0)
              std::printf(" %dx%-3d", r.newton, r.cg);
            else
              std::printf("       ");
            std::printf(" x%d  %9.1f us  %8.3g %% (max %.3g %%)\n", r.substeps, r.step_us,
                        100 * front_error(r), 100 * r.error);
          }
        }
      std::printf("wrote %s\n", csv_path.c_str());
      if (!o->plot) return 0;
      return run_plot_script("plot_tradeoff", "'" + csv_path + "' --out '" + o->out + ".png'");
    };
  });
}

}  // namespace conica::lab
