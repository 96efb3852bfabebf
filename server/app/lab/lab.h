// conica-lab: offline commands (law curves, meshes, headless runs, experiments).
// Each command registers itself on the CLI11 app; main() dispatches.
#pragma once

#include <CLI/CLI.hpp>
#include <functional>
#include <string>
#include <vector>

#include "io/curve_reader.h"
#include "lab/compression.h"

namespace conica::lab {

// A command sets *run to the function that executes it after parsing; it returns the process
// exit status (0 success, non-zero with a message on stderr).
using Runner = std::function<int()>;

void register_law(CLI::App& app, Runner* run);
void register_mesh(CLI::App& app, Runner* run);
void register_run(CLI::App& app, Runner* run);
void register_stability(CLI::App& app, Runner* run);
void register_active_region(CLI::App& app, Runner* run);
void register_compress(CLI::App& app, Runner* run);
void register_calibrate(CLI::App& app, Runner* run);
void register_viscoelastic(CLI::App& app, Runner* run);
void register_tradeoff(CLI::App& app, Runner* run);
void register_plan(CLI::App& app, Runner* run);
void register_contact(CLI::App& app, Runner* run);
void register_indent(CLI::App& app, Runner* run);
void register_fem_reference(CLI::App& app, Runner* run);
void register_validate(CLI::App& app, Runner* run);
void register_library(CLI::App& app, Runner* run);

struct FitOptions;
// The static fit's full-body check and escalation, and the stability margin, as calibrate and
// library both take them (--escalate-above, --escalate-cards, --escalate-mapping,
// --body-samples, --stability-margin).
void add_full_body_check_options(CLI::App* cmd, FitOptions* fit);

struct TradeoffRow;
// The speed/accuracy sweep of conica-lab tradeoff (quick: the small one). Scenes are found from
// the working directory or the source tree. Returns false with the reason in *error.
// probe_stiffness: indentation probe penalty in N/m per node, 0 for the liver scene's own;
// strain: the compression's final engineering strain; coarse_liver: a second liver mesh or "".
// The sweep's units are its experiment x law pairs (kTradeoffUnits, each with its own reference
// run): `units`, when given, says which to run and hears each one's rows when it is done (its
// error stops the sweep).
constexpr int kTradeoffUnits = 4;  // {compression, indentation} x {conical, hooke}
struct TradeoffUnits {
  std::function<bool(int unit)> runs;
  std::function<std::string(int unit, const std::vector<TradeoffRow>& rows)> done;
};
bool tradeoff_sweep(bool quick, bool verbose, std::vector<TradeoffRow>* rows, std::string* error,
                    double probe_stiffness = 100, double strain = 0.3,
                    const std::string& coarse_liver = "", const TradeoffUnits& units = {});

// Reads measured compression curves (io::read_curve against `request`) into `out`, printing each
// warning, and the first error, as "ME: ...". False on an error.
bool read_measured_curves(const char* me, const std::vector<std::string>& paths,
                          const io::CurveRequest& request, std::vector<Curve>* out);

// The strain (engineering, along `axis`) at which the model's material loses strong
// ellipticity under uniaxial compression (core/stability.h), up to `to_strain`; -1: it does not.
// When it does, says so as "ME: warning: ...": a compression past it buckles instead of
// shortening evenly.
double warn_material_stability(const char* me, const Model& model, const Vec3& axis,
                               double to_strain);

// QuasiStaticOptions::progress for a command ME of `samples` increments: past 10 s, a line per
// increment on stderr (travel, settled or not, steps so far, time and time left).
std::function<void(int, double, double, bool, long)> quasi_static_progress(const char* me,
                                                                           int samples);

// Runs `/usr/bin/python3 scripts/NAME.py ARGS...` from the source tree to draw a figure.
// Returns the exit status; prints why on failure.
int run_plot_script(const std::string& name, const std::string& args);

}  // namespace conica::lab
