// One simulation step for the paper's 320-node cube and a 4,096-node (16^3) block, with conical
// and with linear (Hooke) springs, for each integrator; and the block with element terms.
//   build/bin/bench_step --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include "core/body.h"
#include "core/step.h"

namespace {

using namespace conica;

// Nodes per side: 320-node cube is {8, 8, 5}; the block is {16, 16, 16}.
// bulk, spread, shear: element terms (Pa), 0 for none.
Model MakeBody(std::array<int, 3> nodes, bool conical, Integrator integ, double bulk = 0,
               double spread = 0, double shear = 0) {
  BodySpec b;
  const double h = 0.01;  // 1 cm lattice
  b.mesh = make_box_lattice(Vec3(h * (nodes[0] - 1), h * (nodes[1] - 1), h * (nodes[2] - 1)),
                            {nodes[0] - 1, nodes[1] - 1, nodes[2] - 1});
  b.density = 1000;
  SpringCard c;
  if (conical) {
    c.conical = ConicalCard{2e8, 1e-3, 2e-3, 8e-3, 10e-3, 3};
    c.stiffness_cap = 20;
  } else {
    c.law = LawKind::kHooke;
    c.hooke_k = 49.0196;
    c.hooke_length = 10e-3;
  }
  b.groups.push_back({"tissue", c, kAllFamilies, {}, Vec3::Zero(), 10});
  FixedSelector base;
  base.kind = FixedSelector::Kind::kPlane;
  b.fixed.push_back(base);
  b.options.integrator = integ;
  b.options.mass_damping = 5;
  b.bulk_modulus = bulk;
  b.spread_modulus = spread;
  b.shear_modulus = shear;
  b.probes.push_back(ProbeSpec{0.008, 0, ContactModel::kNodes});
  Model m;
  if (!build_model(b, &m).empty()) std::abort();
  return m;
}

// Presses the probe into the top of m so that springs leave their linear phase, settles 300
// steps, then times one step per iteration. Returns the state at the end.
State PressAndTime(benchmark::State& state, const Model& m) {
  State s = make_state(m);
  Workspace ws(m);
  Vec3 top = Vec3::Zero();
  for (const Vec3& x : m.rest) top = top.cwiseMax(x);
  set_probe(s, 0, Vec3(top.x() / 2, top.y() / 2, top.z() + 0.008 - 0.006));
  for (int i = 0; i < 300; ++i) step(m, s, ws);
  for (auto _ : state) {
    step(m, s, ws);
    benchmark::DoNotOptimize(s.x.data());
  }
  return s;
}

void BM_Step(benchmark::State& state) {
  const bool big = state.range(0) == 1;
  const bool conical = state.range(1) == 1;
  const auto integ = static_cast<Integrator>(state.range(2));
  const Model m =
      MakeBody(big ? std::array<int, 3>{16, 16, 16} : std::array<int, 3>{8, 8, 5}, conical, integ);
  PressAndTime(state, m);
  state.counters["nodes"] = m.num_nodes();
  state.counters["springs"] = m.num_springs();
  state.counters["ns_per_spring"] =
      benchmark::Counter(static_cast<double>(state.iterations()) * m.num_springs(),
                         benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  state.SetLabel(std::string(big ? "block4096" : "cube320") + (conical ? "/conical/" : "/hooke/") +
                 integrator_name(integ));
}

// The 4,096-node conical block with element terms: range(0) 0 none, 1 bulk modulus, 2 bulk and
// spread moduli, 3 bulk, spread and shear moduli (each 1 kPa: the lattice's own bulk modulus is
// about 3 kPa, so the explicit step stays stable and the cost is that of the terms, not of
// rollbacks); range(1) integrator.
void BM_StepVolume(benchmark::State& state) {
  const int terms = static_cast<int>(state.range(0));
  const auto integ = static_cast<Integrator>(state.range(1));
  const Model m = MakeBody({16, 16, 16}, true, integ, terms > 0 ? 1e3 : 0, terms > 1 ? 1e3 : 0,
                           terms > 2 ? 1e3 : 0);
  const State s = PressAndTime(state, m);
  state.counters["rollbacks"] = static_cast<double>(s.counters.rollbacks);
  static const char* const kNames[] = {"springs", "bulk", "bulk+spread", "bulk+spread+shear"};
  state.SetLabel(std::string("block4096/") + kNames[terms] + "/" + integrator_name(integ));
}

void Args(benchmark::internal::Benchmark* b) {
  for (int big : {0, 1})
    for (int conical : {0, 1})
      for (int integ : {0, 1, 2}) b->Args({big, conical, integ});
}

}  // namespace

// Implicit Euler on the 4096-node conical block with small fixed budgets (Newton iterations x
// CG iterations), and the error after 200 pressed steps against a converged solve (10 x 1000,
// tolerance 1e-12): max node position difference over max node displacement.
void BM_ImplicitBudget(benchmark::State& state) {
  const int newton = static_cast<int>(state.range(0)), cg = static_cast<int>(state.range(1));
  auto run = [](int nw, int c, double tol, int steps, Model* out_m, State* out_s) {
    Model m = MakeBody({16, 16, 16}, true, Integrator::kImplicitEuler);
    m.options.newton_iterations = nw;
    m.options.cg_iterations = c;
    m.options.cg_tolerance = tol;
    State s = make_state(m);
    Workspace ws(m);
    Vec3 top = Vec3::Zero();
    for (const Vec3& x : m.rest) top = top.cwiseMax(x);
    for (int i = 0; i < steps; ++i) {
      const double depth = 0.006 * std::min(1.0, i / 100.0);  // ramp in 0.1 s, then hold
      set_probe(s, 0, Vec3(top.x() / 2, top.y() / 2, top.z() + 0.008 - depth));
      step(m, s, ws);
    }
    *out_m = m;
    *out_s = s;
  };
  Model mr, mc;
  State sr, sc;
  run(10, 1000, 1e-12, 200, &mr, &sr);
  run(newton, cg, 1e-12, 200, &mc, &sc);
  double err = 0, disp = 0;
  for (int i = 0; i < mr.num_nodes(); ++i) {
    err = std::max(err, (sc.x[i] - sr.x[i]).norm());
    disp = std::max(disp, (sr.x[i] - mr.rest[i]).norm());
  }
  // Both errors at step 200, before the timing loop moves the state on.
  const double force_err =
      (sc.probes[0].force - sr.probes[0].force).norm() / sr.probes[0].force.norm();
  Workspace ws(mc);
  for (auto _ : state) {
    step(mc, sc, ws);
    benchmark::DoNotOptimize(sc.x.data());
  }
  state.counters["rel_error"] = err / disp;
  state.counters["force_rel_error"] = force_err;
}

BENCHMARK(BM_Step)->Apply(Args)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_StepVolume)->ArgsProduct({{0, 1, 2, 3}, {0, 2}})->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_ImplicitBudget)
    ->Args({1, 2})
    ->Args({1, 3})
    ->Args({1, 5})
    ->Args({1, 10})
    ->Args({1, 20})
    ->Args({2, 10})
    ->Args({2, 40})
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_MAIN();
