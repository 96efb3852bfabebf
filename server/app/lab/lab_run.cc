// conica-lab run: a scene driven by a probe script, offline and deterministic (same inputs, same
// bytes). Writes tick,t,probe,fx,fy,fz,contact per tick and probe (force on the probe, N) and
// ends with "max |force|: F N, nan: K, rollbacks: R".
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <memory>

#include "app/lab/lab.h"
#include "core/step.h"
#include "io/probe_script.h"
#include "io/scene.h"

namespace conica::lab {

void register_run(CLI::App& app, Runner* run) {
  struct Opts {
    std::string scene, script, out;
    long ticks = 1000;
    bool relative = false;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* cmd =
      app.add_subcommand("run", "Run a scene headless, driving probes from a CSV script");
  cmd->add_option("--scene", o->scene, "scene file (.pbtxt)")->required();
  cmd->add_option("--probe-script", o->script, "CSV t,probe,x,y,z (s, index, m)")->required();
  cmd->add_option("--ticks", o->ticks, "number of ticks")->capture_default_str();
  cmd->add_option("--out", o->out, "CSV of probe forces per tick ('-': stdout)")->required();
  cmd->add_flag("--relative", o->relative,
                "x, y, z are fractions of the body's bounding box, not metres");
  cmd->callback([o, run] {
    *run = [o]() -> int {
      auto model = io::load_model(o->scene);
      if (!model) {
        std::fprintf(stderr, "conica-lab run: %s\n", model.error().c_str());
        return 2;
      }
      const Model& m = model.value();
      auto script = io::read_probe_script(o->script);
      if (!script) {
        std::fprintf(stderr, "conica-lab run: %s\n", script.error().c_str());
        return 2;
      }
      io::ProbeScript& ps = script.value();
      if (ps.probes.size() > m.probes.size()) {
        std::fprintf(stderr, "conica-lab run: %s drives probe %zu but scene %s has %zu probe(s)\n",
                     o->script.c_str(), ps.probes.size() - 1, o->scene.c_str(), m.probes.size());
        return 2;
      }
      if (o->ticks < 0) {
        std::fprintf(stderr, "conica-lab run: --ticks must be >= 0\n");
        return 2;
      }
      if (o->relative) {
        Vec3 lo = m.rest[0], hi = m.rest[0];
        for (const Vec3& x : m.rest) {
          lo = lo.cwiseMin(x);
          hi = hi.cwiseMax(x);
        }
        io::make_absolute(ps, lo, hi);
      }
      FILE* out = o->out == "-" ? stdout : std::fopen(o->out.c_str(), "w");
      if (!out) {
        std::fprintf(stderr, "conica-lab run: cannot write %s\n", o->out.c_str());
        return 1;
      }
      std::fputs("tick,t,probe,fx,fy,fz,contact\n", out);
      State s = make_state(m);
      Workspace ws(m);
      double max_force = 0;
      for (long k = 0; k < o->ticks; ++k) {
        for (size_t p = 0; p < ps.probes.size(); ++p) {
          Vec3 x;
          const bool present = ps.position(static_cast<int>(p), s.time, &x);
          set_probe(s, static_cast<int>(p), present ? x : s.probes[p].center, present);
        }
        step(m, s, ws);
        for (size_t p = 0; p < m.probes.size(); ++p) {
          const Vec3& f = s.probes[p].force;
          max_force = std::max(max_force, f.norm());
          std::fprintf(out, "%" PRIu64 ",%.6f,%zu,%.9g,%.9g,%.9g,%d\n", s.tick, s.time, p, f.x(),
                       f.y(), f.z(), s.probes[p].contacts > 0 ? 1 : 0);
        }
      }
      if (out != stdout) std::fclose(out);
      std::printf("max |force|: %.6g N, nan: %" PRIu64 ", rollbacks: %" PRIu64 "\n", max_force,
                  s.counters.nan_events, s.counters.rollbacks);
      return 0;
    };
  });
}

}  // namespace conica::lab
