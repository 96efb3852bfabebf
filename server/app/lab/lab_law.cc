// conica-lab law: the load-deflection curve of one conical spring card as CSV.
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>

#include "app/lab/lab.h"
#include "core/conical.h"

namespace conica::lab {

void register_law(CLI::App& app, Runner* run) {
  struct Opts {
    ConicalCard card{50, 0.5, 2, 8, 90, 3};
    double from = 0, to = 89;
    int steps = 90;
    double cap = 0;
    int precision = std::numeric_limits<double>::max_digits10;
    std::string plot;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* cmd = app.add_subcommand(
      "law", "Print deflection,force,stiffness,phase of a conical spring card (card units)");
  cmd->add_option("--G", o->card.G, "shear modulus")->capture_default_str();
  cmd->add_option("--d", o->card.d, "wire diameter")->capture_default_str();
  cmd->add_option("--D1", o->card.D1, "smallest coil mean diameter")->capture_default_str();
  cmd->add_option("--D2", o->card.D2, "largest coil mean diameter")->capture_default_str();
  cmd->add_option("--L0", o->card.L0, "free length")->capture_default_str();
  cmd->add_option("--na", o->card.n_a, "active coils")->capture_default_str();
  cmd->add_option("--from", o->from, "first deflection")->capture_default_str();
  cmd->add_option("--to", o->to, "last deflection")->capture_default_str();
  cmd->add_option("--steps", o->steps, "number of samples (>= 2)")->capture_default_str();
  cmd->add_option("--cap", o->cap, "stiffness cap (0: exact law)")->capture_default_str();
  cmd->add_option("--precision", o->precision,
                  "significant digits of every number (default: 17, enough to read back the "
                  "exact double)")
      ->capture_default_str()
      ->check(CLI::Range(1, std::numeric_limits<double>::max_digits10));
  cmd->add_option("--plot", o->plot, "also draw the curve to this PNG file");
  cmd->callback([o, run] {
    *run = [o]() -> int {
      const std::string err = validate(o->card);
      if (!err.empty()) {
        std::fprintf(stderr, "conica-lab law: invalid card: %s\n", err.c_str());
        return 2;
      }
      if (o->steps < 2 || !std::isfinite(o->from) || !std::isfinite(o->to)) {
        std::fprintf(stderr, "conica-lab law: --steps must be >= 2 and --from/--to finite\n");
        return 2;
      }
      const ConicalLaw law(o->card, o->cap > 0 ? o->cap : INFINITY);
      std::string csv = "deflection,force,stiffness,phase\n";
      const int p = o->precision;
      char line[160];
      for (int i = 0; i < o->steps; ++i) {
        const double x = o->from + (o->to - o->from) * i / (o->steps - 1);
        const LawSample s = law.evaluate(x);
        std::snprintf(line, sizeof line, "%.*g,%.*g,%.*g,%s\n", p, x, p, s.force, p, s.stiffness,
                      phase_name(s.phase));
        csv += line;
      }
      std::fputs(csv.c_str(), stdout);
      if (!o->plot.empty()) {
        const std::string tmp = o->plot + ".csv";
        if (FILE* f = std::fopen(tmp.c_str(), "w")) {
          std::fputs(csv.c_str(), f);
          std::fclose(f);
        } else {
          std::fprintf(stderr, "conica-lab law: cannot write %s\n", tmp.c_str());
          return 1;
        }
        return run_plot_script("plot_law", "--out '" + o->plot + "' '" + tmp + "'");
      }
      return 0;
    };
  });
}

}  // namespace conica::lab
