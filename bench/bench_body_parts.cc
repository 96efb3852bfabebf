// The parts of a calibrated body's implicit step, one at a time, on a scene pressed by its probe
// and settled: the force pass (springs and element terms, with what the system keeps), the
// element terms' forces alone, the system's preparation, the preparation and one product with
// A, and one application of the factor's preconditioner (docs/performance.md, "The element
// terms' forces in one pass, in vector lanes").
//   BENCH_SCENE=configs/phantom-ef30.pbtxt build/bin/bench_body_parts
//       --benchmark_repetitions=5 --benchmark_report_aggregates_only=true   (one line)
// (scenes naming a material need CONICA_MATERIAL_PATH; BENCH_UP=x|y|z the axis pressed along,
// z by default.)
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "bench_util.h"
#include "core/element_terms.h"
#include "core/sparse_system.h"
#include "core/step.h"
#include "core/step_detail.h"

namespace {

using namespace conica;

// The scene, pressed 3 mm by its probe from above along `up` over 200 steps and settled 100.
struct Pressed {
  Model m;
  State s;
  std::unique_ptr<Workspace> ws;
  bool ok = false;
  Pressed() {
    const char* path = std::getenv("BENCH_SCENE");
    const char* up_name = std::getenv("BENCH_UP");
    if (!bench::LoadProbedScene(path ? path : "configs/phantom-ef30.pbtxt", &m)) return;
    const int up = up_name ? up_name[0] - 'x' : 2;
    m.options.body_rate_hz = 0;  // the body steps itself here
    s = make_state(m);
    ws = std::make_unique<Workspace>(m);
    int top = 0;
    for (int i = 0; i < m.num_nodes(); ++i)
      if (m.rest[i][up] > m.rest[top][up]) top = i;
    for (int t = 0; t < 300; ++t) {
      Vec3 c = m.rest[top];
      c[up] += m.probes[0].radius - 0.003 * std::min(1.0, t / 200.0);
      set_probe(s, 0, c);
      step(m, s, *ws);
    }
    ok = s.probes[0].force.norm() > 0;
  }
};

Pressed& Scene() {
  static Pressed p;
  return p;
}

void BM_Forces(benchmark::State& state) {
  Pressed& p = Scene();
  if (!p.ok) return state.SkipWithError("the scene did not load or its probe felt nothing");
  for (auto _ : state) {
    detail::evaluate_forces(p.m, p.s, *p.ws, true);
    benchmark::DoNotOptimize(p.ws->force.data());
  }
}

void BM_ElementForces(benchmark::State& state) {
  Pressed& p = Scene();
  if (!p.ok) return state.SkipWithError("the scene did not load or its probe felt nothing");
  for (auto _ : state) {
    element_forces(p.m, p.s, *p.ws);
    benchmark::DoNotOptimize(p.ws->force.data());
  }
}

void BM_Prepare(benchmark::State& state) {
  Pressed& p = Scene();
  if (!p.ok) return state.SkipWithError("the scene did not load or its probe felt nothing");
  for (auto _ : state) detail::prepare_system_at(p.m, p.s, *p.ws, p.m.options.dt);
}

void BM_PrepareAndProduct(benchmark::State& state) {
  Pressed& p = Scene();
  if (!p.ok) return state.SkipWithError("the scene did not load or its probe felt nothing");
  const size_t n3 = 3 * static_cast<size_t>(p.m.num_nodes());
  std::vector<double> x(n3, 1e-6), y(n3);
  for (auto _ : state) {
    detail::system_product(p.m, p.s, *p.ws, p.m.options.dt, x.data(), y.data());
    benchmark::DoNotOptimize(y.data());
  }
}

// kind 0: simplicial (the body's own factor when it steps alone), 1: supernodal (the multi-rate
// body's, its sweeps in single precision).
void BM_Precondition(benchmark::State& state) {
  Pressed& p = Scene();
  if (!p.ok) return state.SkipWithError("the scene did not load or its probe felt nothing");
  SystemFactor f(
      p.m, state.range(0) ? SystemFactor::Kind::kSupernodal : SystemFactor::Kind::kSimplicial);
  detail::prepare_system_at(p.m, p.s, *p.ws, p.m.options.dt);
  f.assemble(p.m, *p.ws);
  if (!f.factorize()) return state.SkipWithError("the system's factorisation failed");
  const size_t n3 = 3 * static_cast<size_t>(p.m.num_nodes());
  std::vector<double> r(n3, 1e-6), z(n3);
  for (auto _ : state) {
    f.precondition(r.data(), z.data());
    benchmark::DoNotOptimize(z.data());
  }
  state.SetLabel(f.supernodal() ? "supernodal" : "simplicial");
}

}  // namespace

BENCHMARK(BM_Forces)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_ElementForces)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Prepare)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_PrepareAndProduct)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Precondition)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);
BENCHMARK_MAIN();
