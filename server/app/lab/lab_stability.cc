// conica-lab stability: where each integrator fails. Sweeps integrator x time step x material
// stiffness on a standard body released from a stretched state (no damping), plus the cases that
// break methods in practice: conical bottoming with and without the stiffness cap, a step load
// (a probe appearing at depth), and a probe teleporting through the body. For every cell it
// records whether the run stayed bounded, its energy drift, and its error against a converged
// reference (the same run with symplectic Euler at a 64x smaller step). Writes CSV and a PNG map.
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "app/lab/lab.h"
#include "app/lab/lab_sweep.h"
#include "core/body.h"
#include "core/step.h"

#ifndef CONICA_VERSION
#define CONICA_VERSION "unknown"
#endif

namespace conica::lab {
namespace {

// The standard body: a 4 x 4 x 2-cell block of 1 cm cells, clamped base, all spring families.
Model standard_body(const SpringCard& card, Integrator integ, double dt, bool top_driven = false) {
  BodySpec b;
  b.mesh = make_box_lattice(Vec3(0.04, 0.04, 0.02), {4, 4, 2});
  b.density = 1000;
  b.groups.push_back({"body", card, kAllFamilies, {}, Vec3::Zero(), 10});
  FixedSelector base;
  base.kind = FixedSelector::Kind::kPlane;
  b.fixed.push_back(base);
  if (top_driven) {  // top face moved in z by the caller, free to slide
    FixedSelector top;
    top.kind = FixedSelector::Kind::kPlane;
    top.offset = 0.02;
    top.axes = 4;
    b.fixed.push_back(top);
  }
  b.options.integrator = integ;
  b.options.dt = dt;
  b.options.newton_iterations = 3;
  b.options.cg_iterations = 200;
  b.options.cg_tolerance = 1e-10;
  b.options.max_speed = 1e3;
  ProbeSpec probe{0.006, 0};
  probe.contact = ContactModel::kNodes;  // the map of docs/stability.md: the node penalty
  b.probes.push_back(probe);
  Model m;
  const std::string e = build_model(b, &m);
  if (!e.empty()) std::fprintf(stderr, "conica-lab stability: %s\n", e.c_str());
  return m;
}

SpringCard hooke(double k) {
  SpringCard c;
  c.law = LawKind::kHooke;
  c.hooke_k = k;
  c.hooke_length = 0.01;
  return c;
}

// Largest natural frequency (rad/s) at rest: power iteration on M^-1 K, with K v from a finite
// difference of the forces (exact for linear springs).
double omega_max(const Model& m) {
  State s = make_state(m);
  Workspace ws(m);
  compute_forces(m, s, ws);
  const std::vector<Vec3> f0 = ws.force;
  std::vector<Vec3> v(m.num_nodes());
  for (int i = 0; i < m.num_nodes(); ++i)
    v[i] = Vec3(std::sin(1.0 + i), std::cos(2.0 + 3 * i), std::sin(5.0 * i))
               .cwiseProduct(m.free_axes[i]);
  double lambda = 0;
  for (int it = 0; it < 300; ++it) {
    double norm = 0;
    for (const Vec3& x : v) norm = std::max(norm, x.cwiseAbs().maxCoeff());
    for (Vec3& x : v) x /= norm;
    const double eps = 1e-7;
    State p = s;
    for (int i = 0; i < m.num_nodes(); ++i) p.x[i] += eps * v[i];
    compute_forces(m, p, ws);
    double num = 0, den = 0;
    for (int i = 0; i < m.num_nodes(); ++i) {
      const Vec3 kv = -(ws.force[i] - f0[i]) / eps;
      const Vec3 w = (kv * m.inv_mass[i]).cwiseProduct(m.free_axes[i]);
      num += v[i].dot(m.mass[i] * w);
      den += v[i].dot(m.mass[i] * v[i]);
      v[i] = w;
    }
    lambda = num / den;
  }
  return std::sqrt(std::max(lambda, 0.0));
}

struct Outcome {
  bool bounded = true;
  std::uint64_t rollbacks = 0;
  double drift = 0;      // max (E - E0) / E0 over the run: energy gained (dissipation is not drift)
  double error = 0;      // max node position error against the reference / max displacement
  double max_force = 0;  // N, probe cases
};

// Releases the block from a 2 % vertical stretch and runs for `seconds`.
Outcome release(const Model& m, double seconds, std::vector<Vec3>* final_x) {
  State s = make_state(m);
  Workspace ws(m);
  for (int i = 0; i < m.num_nodes(); ++i)
    if (m.fixed[i] != 7) s.x[i].z() *= 1.02;
  const double e0 = potential_energy(m, s);
  Outcome o;
  const long steps = std::lround(seconds / m.options.dt);
  for (long k = 0; k < steps; ++k) {
    step(m, s, ws);
    const double e = potential_energy(m, s) + kinetic_energy(m, s);
    o.drift = std::max(o.drift, (e - e0) / e0);
  }
  o.rollbacks = s.counters.rollbacks;
  o.bounded = o.rollbacks == 0 && o.drift < 1.0;
  if (final_x) *final_x = s.x;
  return o;
}

double error_against(const Model& m, const std::vector<Vec3>& x, const std::vector<Vec3>& ref) {
  double err = 0, disp = 0;
  for (int i = 0; i < m.num_nodes(); ++i) {
    err = std::max(err, (x[i] - ref[i]).norm());
    disp = std::max(disp, (ref[i] - m.rest[i]).norm());
  }
  return disp > 0 ? err / std::max(disp, 1e-6) : 0;
}

// A probe at `depth` below the top centre: `ramp` s to get there (0: a step load), then held.
// With `teleport`, it jumps from above the body to below the top after `ramp` seconds.
Outcome press(const Model& m, double depth, double ramp, bool teleport, double seconds) {
  State s = make_state(m);
  Workspace ws(m);
  const Vec3 top(0.02, 0.02, 0.02);
  const double R = m.probes[0].radius;
  Outcome o;
  const long steps = std::lround(seconds / m.options.dt);
  for (long k = 0; k < steps; ++k) {
    const double t = k * m.options.dt;
    double d = ramp > 0 ? depth * std::min(1.0, t / ramp) : depth;
    if (teleport) d = t < ramp ? -0.01 : depth;
    set_probe(s, 0, top + Vec3(0, 0, R - d));
    step(m, s, ws);
    o.max_force = std::max(o.max_force, s.probes[0].force.norm());
    for (const Vec3& x : s.x) o.bounded &= x.allFinite();
  }
  o.rollbacks = s.counters.rollbacks;
  o.bounded &= o.rollbacks == 0;
  return o;
}

// One mass on one conical spring (raw mapping, L0 = 10 mm) under a step load of `load_ratio`
// times the solid load Ps: the spring is driven into solid height, where the exact law's stiffness
// is infinite. Records the smallest spring length as a fraction of the hard-stop length.
Outcome one_spring_bottoming(double cap, Integrator integ, double load_ratio, double ramp,
                             double mass, bool hard_stop, double* min_frac) {
  SpringCard c;
  c.conical = ConicalCard{2e8, 1e-3, 2e-3, 8e-3, 10e-3, 3};
  c.stiffness_cap = cap;
  const ConicalLaw law(c.conical);
  const double l0 = c.conical.L0;
  SolverOptions opts;
  opts.integrator = integ;
  opts.dt = 1e-3;
  opts.newton_iterations = 3;
  opts.mass_damping = 2;
  Model m = make_spring_pair(c, l0, mass, opts);
  m.options.hard_stop = hard_stop;
  State s = make_state(m);
  Workspace ws(m);
  Outcome o;
  double lmin = l0;
  const double stop = std::max(ws.layout.min_length[0], m.options.min_length_fraction * l0);
  for (int k = 0; k < 800; ++k) {
    const double w = ramp > 0 ? std::min(1.0, k * m.options.dt / ramp) : 1.0;
    m.options.gravity = Vec3(0, 0, -w * load_ratio * law.solid_load() / mass);
    step(m, s, ws);
    lmin = std::min(lmin, s.x[1].z());
    o.bounded &= s.x[1].allFinite();
  }
  o.rollbacks = s.counters.rollbacks;
  o.bounded &= o.rollbacks == 0;
  o.max_force = law.solid_load() * load_ratio;
  *min_frac = lmin / stop;
  o.bounded &= lmin > 0;  // the mass never passed through its anchor
  return o;
}

}  // namespace

namespace {

const Integrator kIntegrators[] = {Integrator::kSymplecticEuler, Integrator::kExplicitEuler,
                                   Integrator::kImplicitEuler};
const double kDts[] = {0.125e-3, 0.25e-3, 0.5e-3, 1e-3, 2e-3, 4e-3};
const double kStiffnesses[] = {50, 200, 800, 3200, 12800, 51200};
constexpr int kReleaseUnits = 36;  // stiffness x time step
constexpr int kUnits = kReleaseUnits + 2 + 3;

std::string format(const char* fmt, auto... args) {
  char buf[512];
  std::snprintf(buf, sizeof buf, fmt, args...);
  return buf;
}

// The CSV rows of unit u: 0..35 a release (stiffness u / 6, time step u % 6) with every
// integrator, 36..37 the two bottoming loads, 38..40 the step load, ramp and teleport per
// integrator. Units are independent: a sharded sweep writes the rows one process writes.
std::string stability_unit(int u, double seconds) {
  std::string rows;
  if (u < kReleaseUnits) {
    // 1. Release: time step x stiffness.
    const double k = kStiffnesses[u / 6], dt = kDts[u % 6];
    const double w = omega_max(standard_body(hooke(k), Integrator::kSymplecticEuler, 1e-3));
    // Converged reference: symplectic Euler at dt / 64 (h omega <= 0.2 everywhere here).
    std::vector<Vec3> ref, x;
    const Model mr = standard_body(hooke(k), Integrator::kSymplecticEuler, dt / 64);
    release(mr, seconds, &ref);
    for (Integrator integ : kIntegrators) {
      const Model m = standard_body(hooke(k), integ, dt);
      Outcome r = release(m, seconds, &x);
      r.error = r.bounded ? error_against(m, x, ref) : NAN;
      rows += format("release,%s,%g,%g,%.4f,%d,%lu,%.4g,%.4g,\n", integrator_name(integ), dt * 1e3,
                     k, dt * w, r.bounded, (unsigned long)r.rollbacks, r.drift, r.error);
    }
    if (u % 6 == 5)
      std::printf(
          "stiffness %6g N/m: omega_max %.1f rad/s, symplectic limit dt = 2/omega = %.3f ms\n", k,
          w, 2e3 / w);
    return rows;
  }
  if (u < kReleaseUnits + 2) {
    // 2. Bottoming, one mass on one conical spring (K0 = 49 N/m, telescopic, L0 = 10 mm).
    //    (a) 0.1 g ramped to 0.2 Ps: the equilibrium lies in the nonlinear phase where the exact
    //        law's k_t = 34 K0 = 1650 N/m, past the explicit limit 2 m / dt^2 = 200 N/m; a cap of
    //        3 K0 = 147 N/m respects it.
    //    (b) 1 g under a step load of 1.5 Ps, more than the spring can carry: only the hard stop
    //        keeps the mass from passing through its anchor.
    //    With and without the hard stop. energy_drift holds the smallest length reached over
    //    the hard-stop length (< 0: the spring inverted).
    struct Load {
      const char* name;
      double ratio, ramp, mass, cap;
    };
    const Load loads[] = {Load{"ramp0.2Ps", 0.2, 0.5, 1e-4, 3.0},
                          Load{"step1.5Ps", 1.5, 0.0, 1e-3, 20.0}};
    const Load& load = loads[u - kReleaseUnits];
    for (bool stop : {true, false})
      for (double cap : {1e12, load.cap})
        for (Integrator integ : kIntegrators) {
          double min_frac = 0;
          const Outcome r =
              one_spring_bottoming(cap, integ, load.ratio, load.ramp, load.mass, stop, &min_frac);
          rows += format("bottoming_%s_cap_%s%s,%s,1,,,%d,%lu,%.4g,,%.4g\n", load.name,
                         cap > 1e11 ? "none" : (cap < 10 ? "3" : "20"), stop ? "" : "_nostop",
                         integrator_name(integ), r.bounded, (unsigned long)r.rollbacks, min_frac,
                         r.max_force);
        }
    return rows;
  }
  // 3. Step load vs ramp, 4. probe teleport, on a linear block at the 1 kHz rate.
  const Integrator integ = kIntegrators[u - kReleaseUnits - 2];
  const Model m = standard_body(hooke(200), integ, 1e-3);
  const Outcome ramp = press(m, 0.006, 0.2, false, 0.4);
  const Outcome stepl = press(m, 0.006, 0.0, false, 0.4);
  const Outcome tele = press(m, 0.018, 0.1, true, 0.4);
  rows += format("ramp_load,%s,1,200,,%d,%lu,,,%.4g\n", integrator_name(integ), ramp.bounded,
                 (unsigned long)ramp.rollbacks, ramp.max_force);
  rows += format("step_load,%s,1,200,,%d,%lu,,,%.4g\n", integrator_name(integ), stepl.bounded,
                 (unsigned long)stepl.rollbacks, stepl.max_force);
  rows += format("teleport,%s,1,200,,%d,%lu,,,%.4g\n", integrator_name(integ), tele.bounded,
                 (unsigned long)tele.rollbacks, tele.max_force);
  return rows;
}

}  // namespace

void register_stability(CLI::App& app, Runner* run) {
  struct Opts {
    std::string out = "stability";
    double seconds = 0.2;
    bool plot = true;
    Sweep sweep;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* cmd = app.add_subcommand(
      "stability", "Map where each integrator fails: time step x stiffness, bottoming, step loads");
  cmd->add_option("--out", o->out, "output prefix: PREFIX.csv and PREFIX.png")
      ->capture_default_str();
  cmd->add_option("--seconds", o->seconds, "simulated time per cell, s")->capture_default_str();
  cmd->add_flag("!--no-plot", o->plot, "skip the PNG");
  o->sweep.add_options(cmd);
  cmd->callback([o, run] {
    *run = [o]() -> int {
      auto fail = [](const std::string& e, int rc) {
        std::fprintf(stderr, "conica-lab stability: %s\n", e.c_str());
        return rc;
      };
      if (!(o->seconds > 0) || !std::isfinite(o->seconds))
        return fail("--seconds must be > 0 s", 2);
      const std::string key =
          format("conica-lab stability --seconds %.17g (conica %s)", o->seconds, CONICA_VERSION);
      Sweep& sw = o->sweep;
      if (std::string e = sw.begin(o->out, key, kUnits); !e.empty()) return fail(e, 2);
      std::string rows;
      if (sw.sharded() && !sw.merging()) std::printf("%s\n", sw.summary().c_str());
      for (int u = 0; u < kUnits; ++u) {
        if (!sw.runs(u)) continue;
        const std::string r = stability_unit(u, o->seconds);
        if (std::string e = sw.put(u, r); !e.empty()) return fail(e, 1);
        rows += r;
        std::fflush(stdout);
      }
      if (sw.sharded() && !sw.merging()) return 0;  // --merge writes the CSV
      if (sw.merging())
        if (std::string e = sw.merged(&rows); !e.empty()) return fail(e, 2);
      const std::string csv_path = o->out + ".csv";
      const std::string header =
          "case,integrator,dt_ms,stiffness_n_per_m,h_omega,bounded,rollbacks,energy_drift,"
          "error,max_force_n\n";
      if (std::string e = write_atomic(csv_path, header + rows); !e.empty()) return fail(e, 1);
      std::printf("wrote %s\n", csv_path.c_str());
      if (o->plot)
        return run_plot_script("plot_stability", "'" + csv_path + "' --out '" + o->out + ".png'");
      return 0;
    };
  });
}

}  // namespace conica::lab
