// The multi-rate body's cost (solver body_rate_hz, core/multirate.h) as the body thread runs it
// (loop/body_worker.cc): per body step, the step itself (implicit Euler at 1 / body_rate_hz), the
// factorisation of the body's system when the refactoring policy asks for one (refactor_due) and
// the local model the 1 kHz ticks answer from; and the body-step force against every step
// converged. Medians, p90 and maxima of wall and thread CPU time, measured in one run. With
// --per-tick instead: the per-tick force served at 1 kHz against the body solved every tick
// (PerTick below).
//   build/bin/bench_multirate [--depth M] [--up x|y|z] [--steps N] [--body-rate HZ]
//                             [--newton N] [--newton-tolerance M] [--cg-tolerance T]
//                             [--refactor-every N] [--refactor-iterations N]
//                             [--per-tick [--realtime] [--replies] [--lift] [--speed V]
//                             [--ref-sweeps N] [--warmup SECONDS] [--latency TICKS]]
//                             [--churn SECONDS]
//                             [--surface | --nodes] SCENE
// --surface, --nodes: the probe on surface contact or the node law whatever the scene says.
// --realtime: the per-tick run paced at 1 kHz instead of waiting for each body step (the body is as
// late as it is on this machine); --replies: a client's probe reply before each tick, as served;
// --speed V: the press's speed, m/s (10 mm/s unless given). With surface contact the reference
// tick is one step with the proxy in joint equilibrium with the nodes it leaves (converged,
// joint_proxy_step); --ref-sweeps N instead steps N times per tick with the probe where it is
// (the proxy moved against the nodes, then the body with the proxy held, N times: N = 1 is the
// single-rate step; a larger N approaches the quasi-static response, time running N times over);
// --warmup S: the served body ticks S seconds with the probe off the surface before the run (as a
// server does before its first press), so that its first steps and factorisations are not in it.
// --latency N: each body step handed over no sooner than N ticks after its kick-off (a waited run
// with the body as late as a body thread that slow: real time's lateness, deterministic).
// BENCH_DROPOUTS=1: where the probe stood at each tick whose force is less than half the last one.
// BENCH_REFERENCE=FILE: the per-tick reference's forces kept in FILE and read back by a later run
// of the same body and path (served settings compared without solving the reference again);
// BENCH_REFERENCE=none: no reference (the served run alone: its dropouts, times and counts).
// --lift: after the press and its hold the probe goes straight back out at the press's speed
// (instead of the slide), and the force at the same depths pressing and lifting is printed.
// --churn: the soak's churning client (tools/soak_main.cc) without the wire, paced at 1 kHz:
// sessions of 1-50 probe updates at a random point over the top of the body's box (down to 2 mm
// below it along a sine), each update a probe reply, three per tick (as one client's replies come
// back); the 1 kHz thread's tick and reply CPU time, p50 / p99 / max, and the tick's layer
// evaluations. The probe touches the node highest along `up` (the middle one of a flat top) and is
// pressed `depth` over the first half of the steps, then held.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <optional>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "bench_util.h"
#include "core/body.h"
#include "core/multirate.h"
#include "core/sparse_system.h"
#include "core/step.h"
#include "io/scene.h"
#include "loop/body_worker.h"

namespace {

using namespace conica;
using bench::Percentile;
using bench::ThreadCpuUs;

struct Timer {
  std::vector<double> wall_us, cpu_us;
  std::chrono::steady_clock::time_point t0;
  double c0 = 0;
  void start() {
    c0 = ThreadCpuUs();
    t0 = std::chrono::steady_clock::now();
  }
  void stop() {
    const auto t1 = std::chrono::steady_clock::now();
    cpu_us.push_back(ThreadCpuUs() - c0);
    wall_us.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
  }
};

void Row(const char* name, const Timer& t) {
  std::printf("| %s | %.2f | %.2f | %.2f | %.2f | %.2f |\n", name, 1e-3 * Percentile(t.cpu_us, 0.5),
              1e-3 * Percentile(t.cpu_us, 0.9), 1e-3 * Percentile(t.cpu_us, 1.0),
              1e-3 * Percentile(t.wall_us, 0.5), 1e-3 * Percentile(t.wall_us, 1.0));
}

// The tick CPU by the layer evaluations each tick made (BENCH_*_BY_EVALUATIONS).
void PrintByEvaluations(const std::vector<int>& evaluations, const std::vector<double>& cpu_us) {
  for (int e = 0; e <= 24; ++e) {
    std::vector<double> c;
    for (size_t t = 0; t < evaluations.size() && t < cpu_us.size(); ++t)
      if (evaluations[t] == e) c.push_back(cpu_us[t]);
    if (!c.empty())
      std::printf("%d evaluations: %zu ticks, CPU p50 / p90 / max %.0f / %.0f / %.0f us\n", e,
                  c.size(), Percentile(c, 0.5), Percentile(c, 0.9), Percentile(c, 1.0));
  }
  // Where the costliest ticks fall: those at 8 evaluations or more, by tenth of the run.
  const size_t n = evaluations.size(), tenth = std::max<size_t>(1, n / 10);
  std::printf("ticks at >= 8 evaluations by tenth of the run:");
  for (size_t b = 0; b < n; b += tenth) {
    int count = 0;
    for (size_t t = b; t < std::min(n, b + tenth); ++t) count += evaluations[t] >= 8;
    std::printf(" %d", count);
  }
  std::printf("\n");
}

// --per-tick: the served model at 1 kHz through the body thread (loop/body_worker.h, waited for
// after each hand-over so that the run is the same on any machine) along a press (from 1 mm
// above the top to `depth` at 10 mm/s), a 0.2 s hold, a 5 mm slide at 10 mm/s and a 0.2 s hold,
// against the same body stepped every tick with a converged Newton iteration (4 iterations, CG to
// 1e-10): the per-tick force's RMS and largest relative error (over the ticks above a fifth of
// the largest force).
int PerTick(const Model& served, const Vec3& top, int up, double depth, bool realtime, bool replies,
            bool lift, double speed, int sweeps, double warmup, int latency) {
  const int side = (up + 1) % 3;
  const double r = served.probes[0].radius;
  const double t_press = (depth + 1e-3) / speed, t_slide = t_press + 0.2;
  const int ticks = static_cast<int>(
      std::lround((lift ? t_slide + t_press : t_slide + 0.5 + 0.2) / served.options.dt));
  // The press; then the slide and a hold, or (lift) straight back out at the press's speed.
  auto travel = [&](double t) {
    if (!lift || t <= t_slide) return (depth + 1e-3) * std::min(1.0, t / t_press);
    return (depth + 1e-3) * std::max(0.0, 1 - (t - t_slide) / t_press);
  };
  auto path = [&](int tick) {
    const double t = (tick + 1) * served.options.dt;
    Vec3 c = top;
    c[up] += r + 1e-3 - travel(t);
    if (!lift) c[side] += 5e-3 * std::clamp((t - t_slide) / 0.5, 0.0, 1.0);
    return c;
  };
  Model ref = served;  // the node penalty stays the served one
  ref.options.body_rate_hz = 0;
  ref.options.newton_iterations = 4;
  ref.options.newton_tolerance = 0;
  ref.options.cg_iterations = 400;
  ref.options.cg_tolerance = 1e-10;
  ref.options.bdf2 = false;  // backward Euler at 1 kHz: the same reference for either scheme
  // Surface contact: each reference tick is the step with the proxy in joint equilibrium with
  // the nodes it leaves (joint_proxy_step, core/multirate.h), unless --ref-sweeps asks for N
  // alternating sweeps (the proxy moved against the nodes, then the body with it held).
  const bool joint = ref.probes[0].contact == ContactModel::kSurface && sweeps == 0;
  sweeps = std::max(1, sweeps);
  Model held = ref;
  held.probes[0].hold_proxy = true;
  double worst_gap = 0;  // m, the joint reference's largest |R_p| / k_c
  std::vector<Vec3> ref_force(ticks);
  Timer t_ref;
  // BENCH_REFERENCE=FILE keeps the reference's forces in FILE (read when it holds this run's:
  // the same body at rest, probe, contact model, path and reference kind; written otherwise), so
  // that served settings (body rate, Newton cap, factor policy) are compared against one
  // reference without solving it again.
  const char* cache = std::getenv("BENCH_REFERENCE");
  double key = ticks + 1e3 * r + 7 * depth + 11 * speed + 13 * lift + 17 * sweeps + 19 * up +
               23 * static_cast<int>(ref.probes[0].contact) + 29 * ref.options.mass_damping;
  for (size_t i = 0; i < served.rest.size(); ++i) key += (i % 97 + 1) * served.rest[i].sum();
  bool cached = false;
  const bool no_reference = cache && std::string(cache) == "none";
  if (no_reference) {
    std::fill(ref_force.begin(), ref_force.end(), Vec3::Zero());
    cached = true;
    std::printf("no reference: the served run alone\n");
  } else if (cache) {
    if (FILE* f = std::fopen(cache, "rb")) {
      double k = 0;
      cached = std::fread(&k, sizeof k, 1, f) == 1 && k == key &&
               std::fread(ref_force.data(), sizeof(Vec3), ticks, f) == static_cast<size_t>(ticks);
      std::fclose(f);
    }
    if (cached) std::printf("reference read from %s\n", cache);
  }
  if (!cached) {
    State s = make_state(ref);
    Workspace ws(ref), ws_held(held);
    for (int t = 0; t < ticks; ++t) {
      set_probe(s, 0, path(t));
      t_ref.start();
      if (joint) {
        const double gap = joint_proxy_step(held, ref, 0, &s, &ws_held);
        worst_gap = std::max(worst_gap, gap);
      } else {
        step(ref, s, ws);
      }
      t_ref.stop();
      for (int u = 1; u < sweeps; ++u) step(ref, s, ws);  // the same pose: toward equilibrium
      // The node law's force at the step's end; surface contact's is the proxy's of the step
      // (moved against the nodes the last step left), as the served tick's is.
      ProbeState p = s.probes[0];
      if (ref.probes[0].contact == ContactModel::kNodes) probe_contact(ref, s.x, 0, path(t), r, &p);
      ref_force[t] = p.force;
    }
    if (cache && !no_reference)
      if (FILE* f = std::fopen(cache, "wb")) {
        std::fwrite(&key, sizeof key, 1, f);
        std::fwrite(ref_force.data(), sizeof(Vec3), ticks, f);
        std::fclose(f);
      }
  }
  std::vector<Vec3> force(ticks);
  State s = make_state(served);
  // Waited: the body's factorisations too, so that the run is the same on any machine
  // (BENCH_FACTORING=inline: on the body thread after the step that asked, as before they had a
  // thread of their own).
  const char* factoring = std::getenv("BENCH_FACTORING");
  loop::BodyWorker worker(served, s,
                          factoring && std::string(factoring) == "inline" ? loop::Factoring::kInline
                          : realtime ? loop::Factoring::kBackground
                                     : loop::Factoring::kWaited);
  // --warmup: the served body ticked with the probe where the path starts (off the surface) before
  // the run, as a server is before its first client presses: the body's first steps (block-Jacobi
  // CG until the first factor, the first factorisations) are not in the run.
  const int warm = static_cast<int>(std::lround(warmup / served.options.dt));
  worker.set_latency(latency);
  const auto warm_start = std::chrono::steady_clock::now();
  for (int t = 0; t < warm; ++t) {
    set_probe(s, 0, path(0));
    worker.tick(served, s);
    if (realtime)
      std::this_thread::sleep_until(warm_start + std::chrono::microseconds(1000 * (t + 1)));
    else
      while (worker.stepping()) std::this_thread::sleep_for(std::chrono::microseconds(50));
  }
  const std::uint64_t steps0 = worker.body_steps(), factors0 = worker.factorizations(),
                      frozen0 = worker.frozen_answers(), fallbacks0 = worker.proxy_fallbacks(),
                      newton0 = worker.newton_iterations(), cg0 = worker.cg_iterations();
  Timer t_tick;                 // the 1 kHz thread's tick (its contact solve), not the body's step
  std::vector<double> body_ms;  // wall time of each body step handed over, with its models
  std::uint64_t last_steps = steps0;
  std::vector<int> evaluations(ticks, 0);
  const auto start = std::chrono::steady_clock::now();
  for (int t = 0; t < ticks; ++t) {
    set_probe(s, 0, path(t));
    if (replies) {  // a client's probe reply before each tick, as served
      ProbeState& p = s.probes[0];
      worker.contact(served, s, 0, path(t), p.radius, &p);
    }
    t_tick.start();
    worker.tick(served, s);
    t_tick.stop();
    evaluations[t] = worker.last_layer_evaluations();
    if (realtime)  // paced at 1 kHz: the body thread is late as it is
      std::this_thread::sleep_until(start + std::chrono::microseconds(1000 * (t + 1)));
    else
      while (worker.stepping()) std::this_thread::sleep_for(std::chrono::microseconds(50));
    force[t] = s.probes[0].force;
    if (std::getenv("BENCH_DROPOUTS") && t > 0 && force[t].norm() < 0.5 * force[t - 1].norm()) {
      const ProbeState& q = s.probes[0];  // a force that halves in one tick: where things stood
      std::printf(
          "drop at tick %d: %.4f -> %.4f N; body steps %llu (last hand-over %s); proxy - device "
          "%.3g m, contacts %d, depth %.3g m, proxy placed %d\n",
          t, force[t - 1].norm(), force[t].norm(),
          static_cast<unsigned long long>(worker.body_steps()),
          worker.body_steps() != last_steps ? "this tick" : "earlier", (q.proxy - q.center).norm(),
          q.contacts, q.depth, static_cast<int>(q.proxy_placed));
    }
    if (worker.body_steps() != last_steps) {  // a body step handed over: its step and models
      last_steps = worker.body_steps();
      body_ms.push_back(1e-6 * static_cast<double>(worker.last_body_ns()));
    }
  }
  double fmax = 0, e2 = 0, f2 = 0, worst = 0;
  for (const Vec3& f : ref_force) fmax = std::max(fmax, f.norm());
  for (int t = 0; t < ticks && fmax > 0; ++t) {
    if (ref_force[t].norm() < 0.2 * fmax) continue;
    const double e = (force[t] - ref_force[t]).norm();
    e2 += e * e;
    f2 += ref_force[t].squaredNorm();
    worst = std::max(worst, e / ref_force[t].norm());
  }
  if (lift) {  // the force at the same depths pressing and lifting, served and converged
    for (double at : {0.25, 0.5, 0.75}) {
      const double want = 1e-3 + at * depth;
      int tp = -1, tl = -1;
      for (int t = 0; t < ticks; ++t) {
        const double tt = (t + 1) * served.options.dt;
        if (tp < 0 && tt <= t_press && travel(tt) >= want) tp = t;
        if (tt > t_slide && travel(tt) >= want) tl = t;
      }
      if (tp >= 0 && tl >= 0)
        std::printf(
            "at %.2f mm: pressing %.4f N (converged %.4f N), lifting %.4f N (converged %.4f "
            "N)\n",
            1e3 * at * depth, force[tp].norm(), ref_force[tp].norm(), force[tl].norm(),
            ref_force[tl].norm());
    }
  }
  if (joint) std::printf("joint reference: largest |R_p| / k_c %.3g R\n", worst_gap / r);
  if (std::getenv("BENCH_TICK_BY_EVALUATIONS")) PrintByEvaluations(evaluations, t_tick.cpu_us);
  std::printf(
      "per tick, press %.1f mm / hold / %s (%d ticks): largest force %.4f N; "
      "served against converged every tick: RMS %.3f %%, largest %.3f %%; %llu body steps, "
      "%llu factorisations, %llu estimated answers, %llu proxy fallbacks; converged step p50 %.1f "
      "ms; tick CPU p50 / "
      "p99 / max %.0f / %.0f / %.0f us; body step wall p50 / p90 / max %.1f / %.1f / %.1f ms; "
      "Newton iterations per body step %.2f, CG iterations per Newton iteration %.1f\n",
      1e3 * depth, lift ? "lift" : "slide 5 mm / hold", ticks, fmax,
      100 * std::sqrt(e2 / std::max(f2, 1e-300)), 100 * worst,
      static_cast<unsigned long long>(worker.body_steps() - steps0),
      static_cast<unsigned long long>(worker.factorizations() - factors0),
      static_cast<unsigned long long>(worker.frozen_answers() - frozen0),
      static_cast<unsigned long long>(worker.proxy_fallbacks() - fallbacks0),
      1e-3 * Percentile(t_ref.wall_us, 0.5), Percentile(t_tick.cpu_us, 0.5),
      Percentile(t_tick.cpu_us, 0.99), Percentile(t_tick.cpu_us, 1.0), Percentile(body_ms, 0.5),
      Percentile(body_ms, 0.9), Percentile(body_ms, 1.0),
      static_cast<double>(worker.newton_iterations() - newton0) /
          std::max<double>(1, static_cast<double>(worker.body_steps() - steps0)),
      static_cast<double>(worker.cg_iterations() - cg0) /
          std::max<double>(1, static_cast<double>(worker.newton_iterations() - newton0)));
  // BENCH_FORCES=1: every 20th tick, ticks 1100-1134 and those more than 5 % off the converged
  // force; BENCH_FORCES=A-B: every tick from A to B - 1 too.
  if (const char* env = std::getenv("BENCH_FORCES")) {
    int from = 1100, to = 1135;
    if (std::strchr(env, '-')) std::sscanf(env, "%d-%d", &from, &to);
    for (int t = 0; t < ticks; ++t)
      if (t % 20 == 0 || (t >= from && t < to) ||
          (ref_force[t].norm() > 0.2 * fmax &&
           (force[t] - ref_force[t]).norm() > 0.05 * ref_force[t].norm()))
        std::printf("tick %d: %.4f N (converged %.4f N)\n", t, force[t].norm(),
                    ref_force[t].norm());
  }
  return 0;
}

// --churn (see the top).
int Churn(const Model& served, int up, double seconds) {
  Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
  for (const Vec3& p : served.rest) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  std::mt19937_64 rng(1234);
  std::uniform_real_distribution<double> u(0, 1);
  State s = make_state(served);
  loop::BodyWorker worker(served, s);
  Timer t_tick, t_reply;
  const int ticks = static_cast<int>(std::lround(seconds / served.options.dt));
  int left = 0, k = 0, idle = 0;
  Vec3 c0 = Vec3::Zero();
  std::vector<int> evaluations;
  evaluations.reserve(ticks);
  const auto start = std::chrono::steady_clock::now();
  for (int t = 0; t < ticks; ++t) {
    for (int r = 0; r < 3; ++r) {
      if (idle > 0) {
        --idle;
        continue;
      }
      if (left == 0) {  // a new session
        left = 1 + static_cast<int>(u(rng) * 50);
        k = 0;
        Vec3 f(u(rng), u(rng), u(rng));
        f[up] = 1;
        c0 = lo + (hi - lo).cwiseProduct(f);
      }
      Vec3 c = c0;
      c[up] += 5e-3 - 2e-3 * std::sin(0.3 * k++);
      ProbeState& p = s.probes[0];
      set_probe(s, 0, c);
      t_reply.start();
      worker.contact(served, s, 0, c, p.radius, &p);
      t_reply.stop();
      if (--left == 0) idle = static_cast<int>(u(rng) * 6);  // up to 2 ms between sessions
    }
    t_tick.start();
    worker.tick(served, s);
    t_tick.stop();
    evaluations.push_back(worker.last_layer_evaluations());
    std::this_thread::sleep_until(start + std::chrono::microseconds(1000 * (t + 1)));
  }
  std::vector<double> ev(evaluations.begin(), evaluations.end());
  if (std::getenv("BENCH_CHURN_BY_EVALUATIONS")) PrintByEvaluations(evaluations, t_tick.cpu_us);
  std::printf(
      "churn, %d ticks, %zu replies: tick CPU p50 / p99 / max %.0f / %.0f / %.0f us, reply CPU "
      "p50 / p99 / max %.0f / %.0f / %.0f us, layer evaluations per tick p50 / p99 / max %.0f / "
      "%.0f / %.0f; %llu body steps, %llu estimated answers\n",
      ticks, t_reply.cpu_us.size(), Percentile(t_tick.cpu_us, 0.5), Percentile(t_tick.cpu_us, 0.99),
      Percentile(t_tick.cpu_us, 1.0), Percentile(t_reply.cpu_us, 0.5),
      Percentile(t_reply.cpu_us, 0.99), Percentile(t_reply.cpu_us, 1.0), Percentile(ev, 0.5),
      Percentile(ev, 0.99), Percentile(ev, 1.0),
      static_cast<unsigned long long>(worker.body_steps()),
      static_cast<unsigned long long>(worker.frozen_answers()));
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  double depth = 0.004;
  double body_rate = 0, cg_tolerance = 0, newton_tolerance = -1;  // the scene's unless given
  int refactor_every = -1, refactor_iterations = -1, newton = 0;
  bool per_tick = false, realtime = false, replies = false, lift = false;
  double speed = 0.01;  // m/s, the press's (and the lift's)
  int sweeps = 0;       // reference steps per tick (0: surface contact's joint reference)
  double warmup = 0;    // s, ticks before the per-tick run (--warmup)
  int latency = 0;      // ticks, a body step's hand-over after its kick-off at the soonest
  double churn = 0;
  std::optional<ContactModel> contact;  // the scene's unless given
  int up = 2, steps = 40;
  std::string path;
  for (int a = 1; a < argc; ++a) {
    const std::string o = argv[a];
    if (o == "--depth" && a + 1 < argc)
      depth = std::atof(argv[++a]);
    else if (o == "--up" && a + 1 < argc)
      up = argv[++a][0] - 'x';
    else if (o == "--body-rate" && a + 1 < argc)
      body_rate = std::atof(argv[++a]);
    else if (o == "--per-tick")
      per_tick = true;
    else if (o == "--realtime")
      realtime = true;
    else if (o == "--latency" && a + 1 < argc)
      latency = std::atoi(argv[++a]);
    else if (o == "--churn" && a + 1 < argc)
      churn = std::atof(argv[++a]);
    else if (o == "--lift")
      lift = true;
    else if (o == "--speed" && a + 1 < argc)
      speed = std::atof(argv[++a]);
    else if (o == "--warmup" && a + 1 < argc)
      warmup = std::atof(argv[++a]);
    else if (o == "--ref-sweeps" && a + 1 < argc)
      sweeps = std::max(1, std::atoi(argv[++a]));
    else if (o == "--replies")
      replies = true;
    else if (o == "--surface")
      contact = ContactModel::kSurface;
    else if (o == "--nodes")
      contact = ContactModel::kNodes;
    else if (o == "--newton" && a + 1 < argc)
      newton = std::atoi(argv[++a]);
    else if (o == "--newton-tolerance" && a + 1 < argc)
      newton_tolerance = std::atof(argv[++a]);
    else if (o == "--cg-tolerance" && a + 1 < argc)
      cg_tolerance = std::atof(argv[++a]);
    else if (o == "--refactor-every" && a + 1 < argc)
      refactor_every = std::atoi(argv[++a]);
    else if (o == "--refactor-iterations" && a + 1 < argc)
      refactor_iterations = std::atoi(argv[++a]);
    else if (o == "--steps" && a + 1 < argc)
      steps = std::max(2, std::atoi(argv[++a]));
    else
      path = o;
  }
  Model served;
  if (!bench::LoadProbedScene(path, &served, contact)) return 2;
  if (body_rate > 0) served.options.body_rate_hz = body_rate;
  if (cg_tolerance > 0) served.options.cg_tolerance = cg_tolerance;
  if (newton > 0) served.options.newton_iterations = newton;
  if (newton_tolerance >= 0) served.options.newton_tolerance = newton_tolerance;
  if (refactor_every >= 0) served.options.refactor_every = refactor_every;
  if (refactor_iterations >= 0) served.options.refactor_iterations = refactor_iterations;
  if (!(served.options.body_rate_hz > 0)) {
    std::fprintf(stderr, "%s: not multi-rate (solver body_rate_hz)\n", path.c_str());
    return 2;
  }
  if (churn > 0) return Churn(served, up, churn);
  const Model body = body_model(served);
  // The highest node along `up`, nearest the middle of the nodes that high (a flat top's centre).
  double high = -1e300;
  for (int i = 0; i < body.num_nodes(); ++i) high = std::max(high, body.rest[i][up]);
  Vec3 mid = Vec3::Zero();
  int count = 0;
  for (int i = 0; i < body.num_nodes(); ++i)
    if (body.rest[i][up] > high - 1e-9) mid += body.rest[i], ++count;
  mid /= count;
  int top = -1;
  for (int i = 0; i < body.num_nodes(); ++i)
    if (body.rest[i][up] > high - 1e-9 &&
        (top < 0 || (body.rest[i] - mid).norm() < (body.rest[top] - mid).norm()))
      top = i;
  if (per_tick)
    return PerTick(served, body.rest[top], up, depth, realtime, replies, lift, speed, sweeps,
                   warmup, latency);
  // The body's cost below steps the body alone, the probe's pose given: surface contact's proxy
  // is moved by the 1 kHz tick (haptic_contact), which this path does not run, so a surface probe
  // would stay where it first touched and its coupling spring would read the tool's travel.
  if (body.probes[0].contact == ContactModel::kSurface) {
    std::fprintf(stderr,
                 "%s: the probe uses surface contact, whose proxy the 1 kHz tick moves: measure "
                 "its body cost with --per-tick (the body step's wall time is its last column), "
                 "or this path with --nodes\n",
                 path.c_str());
    return 2;
  }
  const double r = served.probes[0].radius;
  const double reach = served.options.body_reach > 0 ? served.options.body_reach : 0.5 * r;
  auto probe_at = [&](int k) {
    Vec3 c = body.rest[top];
    c[up] += r - depth * std::min(1.0, (k + 1.0) / (steps / 2));
    return c;
  };

  // The body worker's loop (loop/body_worker.cc) with its refactoring policy, timed part by part.
  struct Run {
    Timer step, build, total;
    std::vector<Vec3> force;
    double cg = 0, newton = 0;
    int factorizations = 0;
    long long factor_nonzeros = 0;
    bool supernodal = false;
  };
  auto simulate = [&](const SolverOptions& policy, const Model& b) {
    Run run;
    State s = make_state(b);
    Workspace ws(b);
    prime_workspace(ws);
    LocalModelBuilder builder(b);
    LocalModel lm;
    int since = 0;
    for (int k = 0; k < steps; ++k) {
      set_probe(s, 0, probe_at(k), true);
      const Counters c0 = s.counters;
      run.total.start();
      run.step.start();
      const bool factored = step_body(b, policy, s, ws, builder, &since);
      run.step.stop();
      const std::uint64_t newton =
          std::max<std::uint64_t>(1, s.counters.newton_iterations - c0.newton_iterations);
      run.cg += static_cast<double>(s.counters.cg_iterations - c0.cg_iterations) / newton;
      run.newton += static_cast<double>(newton);
      run.factorizations += factored;
      run.build.start();
      builder.build(b, s, ws, 0, reach, &lm);
      run.build.stop();
      run.total.stop();
      run.force.push_back(s.probes[0].force);
    }
    run.cg /= steps;
    run.newton /= steps;
    if (ws.factor) {
      run.factor_nonzeros = ws.factor->current->factor_nonzeros();
      run.supernodal = ws.factor->current->supernodal();
    }
    return run;
  };
  // The reference: every body step converged (4 Newton iterations, CG to 1e-12, a fresh factor).
  Model ref_body = body;
  ref_body.options.newton_iterations = 4;
  ref_body.options.cg_iterations = 400;
  ref_body.options.cg_tolerance = 1e-12;
  SolverOptions every_step = served.options;
  every_step.refactor_every = 1;
  const Run ref = simulate(every_step, ref_body);
  const Run run = simulate(served.options, body);

  double e2 = 0, f2 = 0, worst = 0, peak = 0;
  for (const Vec3& f : ref.force) peak = std::max(peak, f.norm());
  for (size_t k = 0; k < ref.force.size(); ++k) {
    if (ref.force[k].norm() < 0.05 * peak) continue;
    const double e = (run.force[k] - ref.force[k]).norm();
    e2 += e * e;
    f2 += ref.force[k].squaredNorm();
    worst = std::max(worst, e / ref.force[k].norm());
  }
  std::printf(
      "%s: %d nodes, %zu tetrahedra, %zu hexahedra; body step %.0f ms (%d ticks), %d x %d (Newton "
      "to %g m), CG "
      "to %g; refactor_every %d, refactor_iterations %d; L %lld nonzeros (%s); press %.1f mm over "
      "%d steps, then held\n",
      path.c_str(), body.num_nodes(), body.tetrahedra.size(), body.hexahedra.size(),
      1e3 * body.options.dt, ticks_per_body_step(served), body.options.newton_iterations,
      body.options.cg_iterations, body.options.newton_tolerance, body.options.cg_tolerance,
      served.options.refactor_every, served.options.refactor_iterations, run.factor_nonzeros,
      run.supernodal ? "supernodal" : "simplicial", 1e3 * depth, steps / 2);
  std::printf(
      "factorisations %d of %d steps; Newton iterations per step %.2f, CG iterations per Newton "
      "iteration %.1f; force at the end "
      "%.4f N (converged %.4f N); body-step force against converged steps: RMS %.3f %%, largest "
      "%.3f %%\n",
      run.factorizations, steps, run.newton, run.cg, run.force.back().norm(),
      ref.force.back().norm(), 100 * std::sqrt(e2 / std::max(f2, 1e-300)), 100 * worst);
  std::printf(
      "| part | CPU p50 (ms) | CPU p90 | CPU max | wall p50 | wall max |\n"
      "|---|---:|---:|---:|---:|---:|\n");
  Row("body step (with the factorisation when due)", run.step);
  Row("local model from the factor", run.build);
  Row("all, per body step", run.total);
  Row("converged reference, per body step", ref.total);
  if (std::getenv("BENCH_FORCES"))
    for (size_t k = 0; k < ref.force.size(); ++k)
      std::printf("step %zu: %.4f N (converged %.4f N)\n", k, run.force[k].norm(),
                  ref.force[k].norm());
  return 0;
}
