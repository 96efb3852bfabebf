// conica-lab library: a material library from a database of compression tests. Every folder of
// --data-dir holding CSV files is a recipe (its tests averaged); each recipe's card is fitted
// with calibrate() and written to OUT/<recipe>.card, a scene fragment a scene uses by name
// (`material: "EF30_0T"`), with its provenance in comment lines: data files and their content
// hashes, strain range, error, program version, options, and a key over all of them.
//
// Sweeps: --shard i/N fits the recipes k with k % N == i (sorted by name), so N processes (a
// Slurm job array: scripts/slurm/) share a database; --merge checks that every recipe has its
// card, fitted with the current key, and writes OUT/index.csv. A card is written to a temporary
// file and renamed, so an interrupted sweep leaves no half card, and a rerun skips every recipe
// whose card has the current key (resume). Cards hold no wall time and no machine paths (data
// files relative to --data-dir), so a sharded sweep writes the same bytes as one process; wall
// times go to OUT/logs/<recipe>.log with the fit's progress.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "app/lab/lab.h"
#include "app/lab/lab_sweep.h"
#include "io/curve_reader.h"
#include "io/scene.h"
#include "io/scene_writer.h"
#include "lab/calibration.h"

#ifndef CONICA_VERSION
#define CONICA_VERSION "unknown"
#endif

namespace conica::lab {
namespace {

namespace fs = std::filesystem;

std::uint64_t fnv1a(const std::string& bytes, std::uint64_t h = 1469598103934665603ull) {
  for (unsigned char c : bytes) {
    h ^= c;
    h *= 1099511628211ull;
  }
  return h;
}

std::string hex(std::uint64_t v) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(v));
  return buf;
}

std::string read_all(const fs::path& p, bool* ok) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  *ok = static_cast<bool>(in) || in.eof();
  return s.str();
}

std::string g(double v, int precision = 6) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*g", precision, v);
  return buf;
}

std::string duration(double s) {
  char buf[32];
  const long t = std::lround(s);
  if (t >= 3600)
    std::snprintf(buf, sizeof buf, "%ldh%02ldm%02lds", t / 3600, t / 60 % 60, t % 60);
  else if (t >= 60)
    std::snprintf(buf, sizeof buf, "%ldm%02lds", t / 60, t % 60);
  else
    std::snprintf(buf, sizeof buf, "%lds", t);
  return buf;
}

struct Recipe {
  std::string name;
  std::vector<fs::path> files;  // sorted
};

// Recipes of a database: folders with *.csv files, sorted by name.
std::vector<Recipe> recipes_in(const fs::path& dir, std::string* error) {
  std::vector<Recipe> out;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) {
    *error = dir.string() + ": not a folder of recipes";
    return out;
  }
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    if (!e.is_directory()) continue;
    Recipe r{e.path().filename().string(), {}};
    for (const auto& f : fs::directory_iterator(e.path(), ec))
      if (f.is_regular_file() && f.path().extension() == ".csv") r.files.push_back(f.path());
    if (r.files.empty()) continue;
    std::sort(r.files.begin(), r.files.end());
    out.push_back(std::move(r));
  }
  std::sort(out.begin(), out.end(),
            [](const Recipe& a, const Recipe& b) { return a.name < b.name; });
  if (out.empty()) *error = dir.string() + ": no recipe folder with .csv files";
  return out;
}

// The "# key: " line of a card, empty when none.
std::string key_of(const fs::path& card) {
  std::ifstream in(card);
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("# key: ", 0) == 0) return line.substr(7);
  return {};
}

// "# error: " value of a card.
std::string field_of(const fs::path& card, const std::string& field) {
  std::ifstream in(card);
  std::string line;
  const std::string head = "# " + field + ": ";
  while (std::getline(in, line))
    if (line.rfind(head, 0) == 0) return line.substr(head.size());
  return {};
}

}  // namespace

void register_library(CLI::App& app, Runner* run) {
  struct Opts {
    std::string scene, data_dir, out, shard = "0/1", method = "static";
    std::vector<std::string> only;
    bool merge = false, force = false;
    FitOptions fit;
  };
  auto o = std::make_shared<Opts>();
  o->fit.space_mapping = 2;
  o->fit.verify_candidates = 2;
  o->fit.escalate_above = 0.02;
  CLI::App* cmd = app.add_subcommand(
      "library",
      "Calibrate every recipe of a database of compression tests into a material "
      "library (OUT/<recipe>.card), sharded and resumable");
  cmd->add_option("--scene", o->scene, "calibration scene (.pbtxt)")->required();
  cmd->add_option("--data-dir", o->data_dir, "database: one folder of CSV tests per recipe")
      ->required();
  cmd->add_option("--out", o->out, "library folder (created)")->required();
  cmd->add_option("--recipes", o->only, "only these recipes (folder names)")->delimiter(',');
  cmd->add_option("--shard", o->shard, "i/N: this process fits recipes k with k % N == i")
      ->capture_default_str();
  cmd->add_flag("--merge", o->merge,
                "fit nothing: check that every recipe has its card with the current key and "
                "write OUT/index.csv");
  cmd->add_flag("--force", o->force, "refit recipes whose card is already there");
  cmd->add_option("--method", o->method, "calibration method (conica-lab calibrate --method)")
      ->check(CLI::IsMember({"static", "grid"}))
      ->capture_default_str();
  cmd->add_option("--max-strain", o->fit.max_strain, "fit up to this strain")
      ->capture_default_str();
  cmd->add_option("--skip-strain", o->fit.skip_strain, "error from this strain")
      ->capture_default_str();
  cmd->add_option("--points", o->fit.points, "displacement grid points")->capture_default_str();
  cmd->add_option("--poisson-grid", o->fit.poisson_grid, "static: Poisson ratios searched")
      ->capture_default_str();
  cmd->add_option("--poisson-min", o->fit.poisson_min, "lowest Poisson ratio searched")
      ->capture_default_str();
  cmd->add_option("--space-mapping", o->fit.space_mapping, "static: space-mapping steps")
      ->capture_default_str();
  cmd->add_option("--full-iterations", o->fit.full_iterations,
                  "-1: surrogate only (no full body, no escalation; fast, for tests of the sweep "
                  "itself)")
      ->capture_default_str();
  add_full_body_check_options(cmd, &o->fit);
  cmd->add_option("--threads", o->fit.threads, "threads per recipe (0: one per hardware thread)")
      ->capture_default_str();
  cmd->callback([o, run] {
    *run = [o]() -> int {
      auto fail = [](const std::string& e, int rc = 2) {
        std::fprintf(stderr, "conica-lab library: %s\n", e.c_str());
        return rc;
      };
      int shard = 0, shards = 1;
      if (!parse_shard(o->shard, &shard, &shards))
        return fail("--shard " + o->shard + ": expected i/N with 0 <= i < N");
      std::string e;
      std::vector<Recipe> all = recipes_in(o->data_dir, &e);
      if (all.empty()) return fail(e);
      if (!o->only.empty()) {
        std::vector<Recipe> kept;
        for (const std::string& name : o->only) {
          auto it =
              std::find_if(all.begin(), all.end(), [&](const Recipe& r) { return r.name == name; });
          if (it == all.end()) return fail("--recipes: no recipe " + name + " in " + o->data_dir);
          kept.push_back(*it);
        }
        std::sort(kept.begin(), kept.end(),
                  [](const Recipe& a, const Recipe& b) { return a.name < b.name; });
        all = kept;
      }
      auto scene = io::read_scene(o->scene);
      if (!scene) return fail(scene.error());
      bool ok = true;
      const std::string scene_text = read_all(o->scene, &ok);
      FitOptions fo = o->fit;
      fo.method = o->method == "static" ? FitMethod::kStatic : FitMethod::kGrid;
      // The key: program, scene, options and every data file's bytes.
      const std::string options =
          "method=" + o->method + " max_strain=" + g(fo.max_strain, 17) +
          " skip_strain=" + g(fo.skip_strain, 17) + " points=" + std::to_string(fo.points) +
          " poisson_grid=" + std::to_string(fo.poisson_grid) +
          " poisson_min=" + g(fo.poisson_min, 17) +
          " space_mapping=" + std::to_string(fo.space_mapping) +
          " full_iterations=" + std::to_string(fo.full_iterations) +
          " stability_margin=" + g(fo.stability_margin, 17) +
          (fo.escalate_above > 0 && fo.full_iterations >= 0
               ? " escalate_above=" + g(fo.escalate_above, 17) +
                     " escalate_cards=" + std::to_string(fo.escalate_cards) +
                     " escalate_mapping=" + std::to_string(fo.escalate_mapping) +
                     " body_samples=" + std::to_string(fo.body_samples)
               : std::string());
      struct Unit {
        Recipe recipe;
        std::string key, provenance;
        std::vector<std::string> texts;
      };
      std::vector<Unit> units;
      for (const Recipe& r : all) {
        Unit u{r, {}, {}, {}};
        std::uint64_t h = fnv1a(std::string("conica ") + CONICA_VERSION + "\n" + scene_text + "\n" +
                                options + "\n");
        for (const fs::path& f : r.files) {
          u.texts.push_back(read_all(f, &ok));
          if (!ok) return fail(f.string() + ": cannot read");
          const std::string rel = fs::path(f).lexically_relative(o->data_dir).generic_string();
          h = fnv1a(rel + "\n" + u.texts.back(), h);
          u.provenance += "# data: " + rel + " (" + std::to_string(u.texts.back().size()) +
                          " bytes, fnv1a-64 " + hex(fnv1a(u.texts.back())) + ")\n";
        }
        u.key = hex(h);
        units.push_back(std::move(u));
      }
      const fs::path out = o->out;
      std::error_code ec;
      fs::create_directories(out / "logs", ec);
      if (ec) return fail(out.string() + ": cannot create (" + ec.message() + ")", 1);

      if (o->merge) {
        std::string missing;
        std::string index =
            "recipe,error_percent,poisson,card_modulus_Pa,taper,stroke,"
            "precompression,bulk_modulus_Pa,shear_modulus_Pa,tests\n";
        for (const Unit& u : units) {
          const fs::path card = out / (u.recipe.name + ".card");
          if (key_of(card) != u.key) {
            missing += (missing.empty() ? "" : ", ") + u.recipe.name;
            continue;
          }
          index += u.recipe.name + "," + field_of(card, "index") + "," +
                   std::to_string(u.recipe.files.size()) + "\n";
        }
        if (!missing.empty())
          return fail(
              "merge: no card with the current key for " + missing + " (run their shards first)",
              3);
        if (std::string w = write_atomic(out / "index.csv", index); !w.empty()) return fail(w, 1);
        std::printf("merged %zu recipes into %s\n", units.size(),
                    (out / "index.csv").string().c_str());
        return 0;
      }

      std::vector<const Unit*> mine;
      for (size_t k = 0; k < units.size(); ++k)
        if (static_cast<int>(k % shards) == shard) mine.push_back(&units[k]);
      const auto t0 = std::chrono::steady_clock::now();
      int done = 0, fitted = 0;
      double fit_seconds = 0;
      std::printf("shard %d/%d: %zu of %zu recipes\n", shard, shards, mine.size(), units.size());
      std::fflush(stdout);
      for (const Unit* u : mine) {
        const std::string name = u->recipe.name;
        const fs::path card = out / (name + ".card");
        ++done;
        if (!o->force && key_of(card) == u->key) {
          std::printf("[%d/%zu] %s: card up to date, skipped\n", done, mine.size(), name.c_str());
          std::fflush(stdout);
          continue;
        }
        const auto t1 = std::chrono::steady_clock::now();
        // Read every test against the body's height: bad files stop the recipe, naming file
        // and line, before anything is written.
        BodySpec spec = scene.value().spec;
        ensure_top_plate(&spec);
        io::CurveRequest request;
        request.max_strain = fo.max_strain;
        if (Model body; build_model(spec, &body).empty() && !body.planes.empty())
          request.height = plate_height(body);
        std::vector<Curve> curves;
        for (size_t f = 0; f < u->recipe.files.size(); ++f) {
          auto c = io::parse_curve(u->texts[f], u->recipe.files[f].string(), request);
          if (!c) return fail(c.error());
          for (const std::string& w : c.value().warnings)
            std::fprintf(stderr, "conica-lab library: warning: %s\n", w.c_str());
          Curve curve;
          for (const io::CurveSample& s : c.value().samples)
            curve.push_back({s.displacement, s.force});
          curves.push_back(std::move(curve));
        }
        std::string log;
        FitOptions run_options = fo;
        run_options.progress = [&log](const std::string& line) { log += line + "\n"; };
        const FitResult r = calibrate(spec, curves, run_options);
        if (!r.error.empty()) return fail(name + ": " + r.error);
        const double error = r.full_error >= 0 ? r.full_error : r.surrogate_error;
        if (!std::isfinite(error))
          return fail(name + ": no card written: the fit's error is not defined (" +
                          (r.full_error >= 0 ? std::string("no full-body run kept its "
                                                           "homogeneous state")
                                             : std::string("the surrogate failed")) +
                          "; the fit's log: rerun conica-lab calibrate on its files)",
                      4);
        const std::string which = r.full_error >= 0 ? "full body" : "cell surrogate";
        std::string head = "# conica material " + name + "\n";
        head +=
            "# program: conica " CONICA_VERSION ", conica-lab library --method " + o->method + "\n";
        head += "# options: " + options + "\n";
        head += "# scene: " + scene.value().name + " (fnv1a-64 " + hex(fnv1a(scene_text)) + ")\n";
        head += "# database: " + std::to_string(u->recipe.files.size()) +
                " tests, their mean fitted\n" + u->provenance;
        head += "# strain range: error over " + g(fo.skip_strain) + " to " + g(fo.max_strain) +
                " engineering strain\n";
        head += "# error: " + g(100 * error, 4) + " % mean relative (" + which + ")\n";
        for (size_t c = 0; c < r.shapes.size(); ++c) {
          const CardShape& sh = r.shapes[c];
          head += "# card" +
                  (r.shapes.size() > 1 ? " " + std::to_string(c + 1) + " (" +
                                             families_name(card_families(r.shapes.size())[c]) + ")"
                                       : std::string()) +
                  ": E_c " + g(sh.modulus) + " Pa, taper " + g(sh.taper) + ", stroke " +
                  g(sh.stroke) + ", pre-compression " + g(sh.precompression) + " S";
          head += c + 1 < r.shapes.size() ? "\n" : "; body Poisson " + g(r.poisson, 4) + "\n";
        }
        head += "# index: " + g(100 * error, 4) + "," + g(r.poisson, 4) + "," + g(r.shape.modulus) +
                "," + g(r.shape.taper) + "," + g(r.shape.stroke) + "," + g(r.shape.precompression) +
                "," + g(r.bulk_modulus) + "," + g(r.shear_modulus) + "\n";
        head += "# key: " + u->key + "\n";
        BodySpec material;
        material.bulk_modulus = r.bulk_modulus;
        material.spread_modulus = r.spread_modulus;
        material.shear_modulus = r.shear_modulus;
        material.shear_stiffening = r.shear_stiffening;
        for (const auto& grp : r.groups)
          if (grp.card.law == LawKind::kConical) material.groups.push_back(grp);
        const std::string text = head + io::material_text(material);
        // The card must load as a scene's material before it is written.
        if (auto back = io::parse_scene("cylinder { radius: 0.025 height: 0.03 cells_across: 2 "
                                        "cells_high: 2 }\ndensity: 1000\n" +
                                            text,
                                        name + ".card", ".");
            !back)
          return fail(name + ": the fitted card does not load: " + back.error(), 1);
        const double seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
        log += "wall time: " + g(seconds, 4) + " s\n";
        if (std::string w = write_atomic(out / "logs" / (name + ".log"), log); !w.empty())
          return fail(w, 1);
        if (std::string w = write_atomic(card, text); !w.empty()) return fail(w, 1);
        ++fitted;
        fit_seconds += seconds;
        const double elapsed =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        const int left = static_cast<int>(mine.size()) - done;
        std::printf("[%d/%zu] %s: %s %% (%s) in %s; elapsed %s, ETA %s\n", done, mine.size(),
                    name.c_str(), g(100 * error, 4).c_str(), which.c_str(),
                    duration(seconds).c_str(), duration(elapsed).c_str(),
                    duration(left * fit_seconds / fitted).c_str());
        std::fflush(stdout);
      }
      return 0;
    };
  });
}

}  // namespace conica::lab
