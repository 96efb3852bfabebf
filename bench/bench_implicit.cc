// The implicit step of a scene with each linear solver, over a press-hold-slide of its probe:
// per-step time (p50 / p90 / p99 / max), CG iterations per Newton iteration, factorisations, and
// the probe force per tick against a converged solve of the same body (RMS and largest relative
// error over the ticks in contact).
//   build/bin/bench_implicit [--depth M] [--up x|y|z] [--jacobi-newton N --jacobi-cg N]
//                            [--surface | --nodes] [--newton-tolerance M] SCENE
// --surface, --nodes: the probe on surface contact or the node law whatever the scene says.
// --newton-tolerance: the stepped variants' Newton cap (m of node motion; 0: every iteration);
// the reference always takes every iteration.
// Variants: "block-Jacobi CG" (the scene with LinearSolver::kBlockJacobiCG and the given budgets),
// "factor CG, inline" (the scene as written, factorisations inside the step that asks),
// "factor CG, worker" (factorisations on a FactorWorker thread, as conica-server runs it), and the
// reference: factor CG with 4 Newton iterations (none skipped by the scene's newton_tolerance)
// to a 1e-12 relative residual.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <optional>
#include <string>
#include <vector>

#include "bench_util.h"
#include "core/body.h"
#include "core/sparse_system.h"
#include "core/step.h"
#include "io/scene.h"
#include "loop/factor_worker.h"

namespace {

using namespace conica;
using bench::Percentile;
using bench::ThreadCpuUs;

struct Run {
  std::vector<double> step_us;  // wall clock
  std::vector<double> cpu_us;   // the thread's CPU time: what the step costs without preemption
  std::vector<Vec3> force;
  Counters counters;
  int newton = 0;
};

// The probe's path: touching the top (the node highest along `up`), pressed `depth` in 0.3 s,
// held 0.2 s, slid 10 mm along the next axis in 0.3 s, held 0.2 s (1,000 ticks at 1 kHz).
Vec3 ProbeAt(const Model& m, int up, double depth, double t) {
  int top = 0;
  for (int i = 0; i < m.num_nodes(); ++i)
    if (m.rest[i][up] > m.rest[top][up]) top = i;
  const int side = (up + 1) % 3;
  Vec3 c = m.rest[top];
  const double r = m.probes[0].radius;
  const double press = depth * std::min(1.0, t / 0.3);
  const double slide = 0.01 * std::clamp((t - 0.5) / 0.3, 0.0, 1.0);
  c[up] += r - press;
  c[side] += slide;
  return c;
}

Run Simulate(const Model& m, int up, double depth, bool worker) {
  Run run;
  State s = make_state(m);
  Workspace ws(m);
  std::unique_ptr<loop::FactorWorker> w;
  if (worker && ws.factor) w = std::make_unique<loop::FactorWorker>(ws.factor.get());
  const int ticks = static_cast<int>(std::lround(1.0 / m.options.dt));
  for (int k = 0; k < ticks; ++k) {
    set_probe(s, 0, ProbeAt(m, up, depth, (k + 1) * m.options.dt));
    const double c0 = ThreadCpuUs();
    const auto t0 = std::chrono::steady_clock::now();
    step(m, s, ws);
    const auto t1 = std::chrono::steady_clock::now();
    run.cpu_us.push_back(ThreadCpuUs() - c0);
    run.step_us.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
    run.force.push_back(s.probes[0].force);
  }
  w.reset();
  run.counters = s.counters;
  run.newton = m.options.newton_iterations;
  return run;
}

void Report(const char* name, const Run& r, const Run& ref) {
  double num = 0, den = 0, worst = 0, peak = 0;
  for (const Vec3& f : ref.force) peak = std::max(peak, f.norm());
  int n = 0;
  for (size_t k = 0; k < ref.force.size(); ++k) {
    if (ref.force[k].norm() < 0.05 * peak) continue;  // ticks in contact
    const double e = (r.force[k] - ref.force[k]).norm();
    num += e * e;
    den += ref.force[k].squaredNorm();
    worst = std::max(worst, e / ref.force[k].norm());
    ++n;
  }
  const double solves = static_cast<double>(r.step_us.size()) * r.newton;
  std::printf(
      "| %s | %.0f | %.0f | %.0f | %.0f | %.0f | %.0f | %.1f | %llu | %.2g %% | %.2g %% |\n", name,
      Percentile(r.cpu_us, 0.5), Percentile(r.cpu_us, 0.99), Percentile(r.cpu_us, 1.0),
      Percentile(r.step_us, 0.5), Percentile(r.step_us, 0.99), Percentile(r.step_us, 1.0),
      r.counters.cg_iterations / solves, static_cast<unsigned long long>(r.counters.factorizations),
      100 * std::sqrt(num / std::max(den, 1e-300)), 100 * worst);
  if (std::getenv("BENCH_PHASES")) {
    std::printf("  per 100 ticks (mean us):");
    for (size_t k = 0; k < r.step_us.size(); k += 100) {
      double a = 0;
      for (size_t j = k; j < std::min(k + 100, r.step_us.size()); ++j) a += r.step_us[j];
      std::printf(" %.0f", a / 100);
    }
    std::printf("\n");
  }
  std::printf("  stages (us per step):");
  for (int k = 0; k < kNumStages; ++k)
    if (r.counters.stage_ns[k] > 0)
      std::printf(" %s %.0f", stage_name(static_cast<Stage>(k)),
                  1e-3 * r.counters.stage_ns[k] / r.step_us.size());
  std::printf("\n");
  if (r.counters.rollbacks || r.counters.factor_failures)
    std::printf("  (rollbacks %llu, factor failures %llu)\n",
                static_cast<unsigned long long>(r.counters.rollbacks),
                static_cast<unsigned long long>(r.counters.factor_failures));
}

}  // namespace

int main(int argc, char** argv) {
  double depth = 0.005;
  int up = 2, jn = -1, jc = -1;
  std::optional<ContactModel> contact;  // the scene's unless given
  double newton_tolerance = -1;         // the scene's unless given
  std::string path;
  for (int a = 1; a < argc; ++a) {
    const std::string o = argv[a];
    if (o == "--depth" && a + 1 < argc)
      depth = std::atof(argv[++a]);
    else if (o == "--up" && a + 1 < argc)
      up = argv[++a][0] - 'x';
    else if (o == "--jacobi-newton" && a + 1 < argc)
      jn = std::atoi(argv[++a]);
    else if (o == "--jacobi-cg" && a + 1 < argc)
      jc = std::atoi(argv[++a]);
    else if (o == "--newton-tolerance" && a + 1 < argc)
      newton_tolerance = std::atof(argv[++a]);
    else if (o == "--surface")
      contact = ContactModel::kSurface;
    else if (o == "--nodes")
      contact = ContactModel::kNodes;
    else
      path = o;
  }
  Model m;
  if (!bench::LoadProbedScene(path, &m, contact)) return 2;
  m.options.linear_solver = LinearSolver::kFactorCG;
  if (newton_tolerance >= 0) m.options.newton_tolerance = newton_tolerance;
  Model ref = m;
  ref.options.newton_iterations = 4;
  ref.options.cg_iterations = 200;
  ref.options.cg_tolerance = 1e-12;
  ref.options.newton_tolerance = 0;  // every Newton iteration, not stopped by a scene's cap
  Model jac = m;
  jac.options.linear_solver = LinearSolver::kBlockJacobiCG;
  if (jn > 0) jac.options.newton_iterations = jn;
  if (jc > 0) jac.options.cg_iterations = jc;
  {
    Workspace ws(m);
    std::printf(
        "%s: %d nodes, %d springs, %zu tetrahedra, %zu hexahedra; %d unknowns, %lld "
        "nonzeros in A (upper), %lld in L (%s); press %.1f mm\n",
        path.c_str(), m.num_nodes(), m.num_springs(), m.tetrahedra.size(), m.hexahedra.size(),
        ws.factor->current->num_unknowns(), static_cast<long long>(ws.factor->current->nonzeros()),
        static_cast<long long>(ws.factor->current->factor_nonzeros()),
        ws.factor->current->supernodal() ? "supernodal" : "simplicial", 1e3 * depth);
  }
  const Run r_ref = Simulate(ref, up, depth, false);
  const Run r_jac = Simulate(jac, up, depth, false);
  const Run r_inl = Simulate(m, up, depth, false);
  const Run r_wrk = Simulate(m, up, depth, true);
  std::printf(
      "| solver | CPU p50 (us) | CPU p99 | CPU max | wall p50 | wall p99 | wall max | CG it. per "
      "solve | factorisations | force RMS error | largest |\n"
      "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  char name[128];
  std::snprintf(name, sizeof name, "block-Jacobi CG, %d x %d", jac.options.newton_iterations,
                jac.options.cg_iterations);
  Report(name, r_jac, r_ref);
  std::snprintf(name, sizeof name, "factor CG, %d x %d, inline", m.options.newton_iterations,
                m.options.cg_iterations);
  Report(name, r_inl, r_ref);
  std::snprintf(name, sizeof name, "factor CG, %d x %d, worker", m.options.newton_iterations,
                m.options.cg_iterations);
  Report(name, r_wrk, r_ref);
  Report("reference: factor CG, 4 x 200, 1e-12", r_ref, r_ref);
  return 0;
}
