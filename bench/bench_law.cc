// Per-spring cost of the conical law over arrays of springs in each phase (docs/performance.md).
//   build/bin/bench_law --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
// Linear: deflections uniform in [0, delta_t]; nonlinear: uniform in [delta_t, delta_cap];
// mixed: uniform in [-delta_t, delta_cap], so tension, linear and nonlinear springs interleave
// (every chunk of evaluate_batch takes the full path).
#include <benchmark/benchmark.h>

#include <random>
#include <vector>

#include "core/conical.h"

namespace {

using conica::ConicalCard;
using conica::ConicalLaw;

const ConicalCard kCard{50, 1, 2, 8, 270, 3};  // paper Figure 6, n = 1 -> S = 270

std::vector<double> Deflections(const ConicalLaw&, double lo, double hi, int n) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(lo, hi);
  std::vector<double> x(n);
  for (auto& v : x) v = u(rng);
  return x;
}

// pre: pre-compression as a fraction of the transition deflection; the spring's own deflections
// (body deflection + delta0) cover the same ranges as without it.
void Run(benchmark::State& state, double lo_frac, double hi_frac, int mode, double pre = 0) {
  ConicalCard card = kCard;
  card.precompression = pre * ConicalLaw(kCard).transition_deflection();
  const ConicalLaw law(card, 1e4 * ConicalLaw(kCard).k0());
  const double d0 = law.transition_deflection(), d1 = law.cap_deflection();
  const int n = static_cast<int>(state.range(0));
  auto x = Deflections(law, lo_frac < 0 ? -d0 : lo_frac * d0 + (d1 - d0) * 0,
                       hi_frac <= 1 ? hi_frac * d0 : d0 + (hi_frac - 1) * (d1 - d0), n);
  for (double& v : x) v -= card.precompression;
  std::vector<double> f(n), k(n);
  for (auto _ : state) {
    if (mode == 2) {
      law.evaluate_batch(x.data(), f.data(), k.data(), n);
    } else {
      for (int i = 0; i < n; ++i) {
        const auto s = mode == 1 ? law.evaluate_exact(x[i]) : law.evaluate(x[i]);
        f[i] = s.force;
        k[i] = s.stiffness;
      }
    }
    benchmark::DoNotOptimize(f.data());
    benchmark::DoNotOptimize(k.data());
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * n);
  state.counters["ns_per_spring"] =
      benchmark::Counter(static_cast<double>(state.iterations() * n),
                         benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

// Phase ranges as fractions: [0,1] of the linear range, (1,2] across the nonlinear range.
// Scalar calls (evaluate), array calls (evaluate_batch) and the exact Newton inverse.
void BM_LawLinear(benchmark::State& s) { Run(s, 0.0, 1.0, 0); }
void BM_LawNonlinear(benchmark::State& s) { Run(s, 1.0, 2.0, 0); }
void BM_LawMixed(benchmark::State& s) { Run(s, -1.0, 2.0, 0); }
void BM_LawBatchLinear(benchmark::State& s) { Run(s, 0.0, 1.0, 2); }
void BM_LawBatchNonlinear(benchmark::State& s) { Run(s, 1.0, 2.0, 2); }
void BM_LawBatchMixed(benchmark::State& s) { Run(s, -1.0, 2.0, 2); }
void BM_LawNonlinearExactNewton(benchmark::State& s) { Run(s, 1.0, 2.0, 1); }
// Pre-compressed by half the transition deflection (the shifted instance of evaluate_batch).
void BM_LawBatchLinearPrecompressed(benchmark::State& s) { Run(s, 0.0, 1.0, 2, 0.5); }
void BM_LawBatchNonlinearPrecompressed(benchmark::State& s) { Run(s, 1.0, 2.0, 2, 0.5); }
void BM_LawBatchMixedPrecompressed(benchmark::State& s) { Run(s, -1.0, 2.0, 2, 0.5); }

void BM_Hooke(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  const auto x = Deflections(ConicalLaw(kCard), -1, 1, n);
  std::vector<double> f(n), k(n);
  const double k0 = 2.5;
  for (auto _ : state) {
    for (int i = 0; i < n; ++i) {
      f[i] = k0 * x[i];
      k[i] = k0;
    }
    benchmark::DoNotOptimize(f.data());
    benchmark::DoNotOptimize(k.data());
    benchmark::ClobberMemory();
  }
  state.counters["ns_per_spring"] =
      benchmark::Counter(static_cast<double>(state.iterations() * n),
                         benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

}  // namespace

// 4096 springs: three 32 KiB arrays, L1/L2-resident; 46620 springs: 1.1 MB of arrays, beyond L2.
BENCHMARK(BM_Hooke)->Arg(4096)->Arg(46620);
BENCHMARK(BM_LawLinear)->Arg(4096)->Arg(46620);
BENCHMARK(BM_LawNonlinear)->Arg(4096)->Arg(46620);
BENCHMARK(BM_LawMixed)->Arg(4096)->Arg(46620);
BENCHMARK(BM_LawBatchLinear)->Arg(4096)->Arg(46620);
BENCHMARK(BM_LawBatchNonlinear)->Arg(4096)->Arg(46620);
BENCHMARK(BM_LawBatchMixed)->Arg(4096)->Arg(46620);
BENCHMARK(BM_LawNonlinearExactNewton)->Arg(4096);
BENCHMARK(BM_LawBatchLinearPrecompressed)->Arg(4096)->Arg(46620);
BENCHMARK(BM_LawBatchNonlinearPrecompressed)->Arg(4096)->Arg(46620);
BENCHMARK(BM_LawBatchMixedPrecompressed)->Arg(4096)->Arg(46620);
BENCHMARK_MAIN();
