// conica-lab active-region: the same probe path with and without the active region; ends with
// "force error: X %, speedup: Y x" (force error: largest difference of probe force over the
// largest full-simulation probe force; speedup: total step time without / with). --far-every
// chooses how the far field moves (see core/step.h).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>

#include "app/lab/lab.h"
#include "core/step.h"
#include "io/probe_script.h"
#include "io/scene.h"

namespace conica::lab {

void register_active_region(CLI::App& app, Runner* run) {
  struct Opts {
    std::string scene, script;
    long ticks = 2000;
    bool relative = false;
    double tolerance = 1e-5;
    int far_every = 0;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* cmd = app.add_subcommand("active-region",
                                     "Compare a probe path with and without the active region");
  cmd->add_option("--scene", o->scene, "scene file (.pbtxt)")->required();
  cmd->add_option("--probe-script", o->script, "CSV t,probe,x,y,z (s, index, m)")->required();
  cmd->add_option("--ticks", o->ticks, "number of ticks")->capture_default_str();
  CLI::Option* tol = cmd->add_option("--tolerance", o->tolerance,
                                     "displacement tolerance sizing the region, m (default: the "
                                     "scene's active_region, else 1e-5)");
  CLI::Option* far = cmd->add_option(
      "--far-every", o->far_every,
      "far field: one step every N ticks (0: the longest its stability bound allows, -1: frozen; "
      "default: the scene's, else 0)");
  cmd->add_flag("--relative", o->relative, "x, y, z are fractions of the bounding box");
  cmd->callback([o, run, tol, far] {
    const bool tol_given = tol->count() > 0, far_given = far->count() > 0;
    *run = [o, tol_given, far_given]() -> int {
      auto loaded = io::load_model(o->scene);
      if (!loaded) {
        std::fprintf(stderr, "conica-lab active-region: %s\n", loaded.error().c_str());
        return 2;
      }
      auto script = io::read_probe_script(o->script);
      if (!script) {
        std::fprintf(stderr, "conica-lab active-region: %s\n", script.error().c_str());
        return 2;
      }
      Model full = loaded.value();
      if (full.options.integrator == Integrator::kImplicitEuler) {
        std::fprintf(stderr,
                     "conica-lab active-region: the active region applies to symplectic "
                     "and explicit Euler; %s uses implicit Euler\n",
                     o->scene.c_str());
        return 2;
      }
      io::ProbeScript& ps = script.value();
      if (ps.probes.size() > full.probes.size()) {
        std::fprintf(stderr,
                     "conica-lab active-region: the script drives more probes than the "
                     "scene has\n");
        return 2;
      }
      if (o->relative) {
        Vec3 lo = full.rest[0], hi = full.rest[0];
        for (const Vec3& x : full.rest) {
          lo = lo.cwiseMin(x);
          hi = hi.cwiseMax(x);
        }
        io::make_absolute(ps, lo, hi);
      }
      // The scene's own active region gives the defaults; the reference integrates every node.
      if (full.options.active_region) {
        if (!tol_given) o->tolerance = full.options.active_tolerance;
        if (!far_given) o->far_every = full.options.active_far_every;
      }
      full.options.active_region = false;
      Model active = full;
      active.options.active_region = true;
      active.options.active_tolerance = o->tolerance;
      active.options.active_far_every = o->far_every;
      if (o->far_every < -1) {
        std::fprintf(stderr, "conica-lab active-region: --far-every must be >= -1, got %d\n",
                     o->far_every);
        return 2;
      }
      struct Run {
        std::vector<Vec3> force;      // (ticks x probes)
        std::vector<double> tick_us;  // (ticks) step time of each tick, us
        double seconds = 0;
        std::uint64_t awake_sum = 0, rollbacks = 0, whole_body_ticks = 0;
        double cost_sum = 0;  // region cost estimates, summed over ticks
        int far_every = 0, far_max_every = 0, measured_every = 0;
        double far_lambda = 0, damping_ratio = 0, far_raise = 1;
      };
      auto drive = [&](const Model& m) {
        Run r;
        State s = make_state(m);
        Workspace ws(m);
        for (long k = 0; k < o->ticks; ++k) {
          for (size_t p = 0; p < ps.probes.size(); ++p) {
            Vec3 x;
            const bool present = ps.position(static_cast<int>(p), s.time, &x);
            set_probe(s, static_cast<int>(p), present ? x : s.probes[p].center, present);
          }
          const auto t0 = std::chrono::steady_clock::now();
          step(m, s, ws);
          const double dt_s =
              std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
          r.seconds += dt_s;
          r.tick_us.push_back(1e6 * dt_s);
          for (const ProbeState& p : s.probes) r.force.push_back(p.force);
          r.awake_sum += m.options.active_region ? s.counters.awake_nodes : m.num_nodes();
          r.whole_body_ticks += s.region.whole_body;
          r.cost_sum += s.region.cost;
        }
        r.rollbacks = s.counters.rollbacks;
        r.far_every = ws.bounds.far_every;
        r.far_max_every = ws.bounds.far_max_every;
        r.measured_every = ws.bounds.measured_every;
        r.far_lambda = ws.bounds.far_lambda;
        r.damping_ratio = ws.bounds.far_gamma;
        r.far_raise = ws.bounds.far_raise;
        return r;
      };
      const Run a = drive(full), b = drive(active);
      double fmax = 0, err = 0, err_at_peak = 0;
      size_t worst = 0;
      for (size_t k = 0; k < a.force.size(); ++k) {
        if (a.force[k].norm() > fmax) {
          fmax = a.force[k].norm();
          err_at_peak = (a.force[k] - b.force[k]).norm();
        }
        if ((a.force[k] - b.force[k]).norm() > err) worst = k;
        err = std::max(err, (a.force[k] - b.force[k]).norm());
      }
      std::printf("scene %s: %d nodes, %d springs, %ld ticks\n", o->scene.c_str(), full.num_nodes(),
                  full.num_springs(), o->ticks);
      std::printf("full:   %.1f us per step, peak probe force %.4g N, rollbacks %lu\n",
                  1e6 * a.seconds / o->ticks, fmax, (unsigned long)a.rollbacks);
      std::printf("active: %.1f us per step, mean awake nodes %.0f (%.1f %%), rollbacks %lu\n",
                  1e6 * b.seconds / o->ticks, double(b.awake_sum) / o->ticks,
                  100.0 * b.awake_sum / (double(o->ticks) * full.num_nodes()),
                  (unsigned long)b.rollbacks);
      if (b.far_every > 0)
        std::printf(
            "region: estimated cost %.2f of a whole step (mean); whole body stepped on %lu "
            "of %ld ticks (above %.2f, back below %.2f)\n",
            b.cost_sum / o->ticks, (unsigned long)b.whole_body_ticks, o->ticks,
            active.options.active_whole_body_cost,
            kRegionResumeFraction * active.options.active_whole_body_cost);
      if (b.far_every > 0)
        std::printf(
            "far field: one step every %d ticks (bound from the measured spectrum %d: "
            "omega_max %.0f rad/s, damping bound %.0f 1/s, far inertia x %.3f; Gershgorin at the "
            "lightest node %d)\n",
            b.far_every, b.measured_every, std::sqrt(b.far_lambda), b.damping_ratio, b.far_raise,
            b.far_max_every);
      else
        std::printf("far field: frozen\n");
      auto quantile = [](std::vector<double> v, double q) {
        std::sort(v.begin(), v.end());
        return v.empty() ? 0.0 : v[std::min(v.size() - 1, static_cast<size_t>(q * v.size()))];
      };
      std::printf(
          "step time median / 99th percentile / max: full %.0f / %.0f / %.0f us, "
          "active %.0f / %.0f / %.0f us\n",
          quantile(a.tick_us, 0.5), quantile(a.tick_us, 0.99), quantile(a.tick_us, 1.0),
          quantile(b.tick_us, 0.5), quantile(b.tick_us, 0.99), quantile(b.tick_us, 1.0));
      {
        const size_t np = std::max<size_t>(1, ps.probes.size());
        std::printf("worst tick: t = %.3f s, full %.4g N, active %.4g N\n",
                    (worst / np + 1) * full.options.dt, a.force[worst].norm(),
                    b.force[worst].norm());
      }
      std::printf("at the peak force: error %.3g %%\n", fmax > 0 ? 100 * err_at_peak / fmax : 0.0);
      std::printf("force error: %.3g %%, speedup: %.2f x\n", fmax > 0 ? 100 * err / fmax : 0.0,
                  a.seconds / b.seconds);
      return 0;
    };
  });
}

}  // namespace conica::lab
