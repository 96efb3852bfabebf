// The surface contact stage (core/contact.h) on the 4,096-node (16^3, 1 cm lattice) block: one
// tick's proxy update (a settled press, the device still) plus the layer's forces and blocks on
// the nodes, for spheres touching a few to about fifty surface triangles.
//   build/bin/bench_contact --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include "core/body.h"
#include "core/contact.h"
#include "core/step.h"

namespace {

using namespace conica;

void BM_SurfaceContactStage(benchmark::State& state) {
  const double R = state.range(0) * 1e-4;  // m
  BodySpec b;
  b.mesh = make_box_lattice(Vec3(0.15, 0.15, 0.15), {15, 15, 15});
  b.density = 1000;
  SpringCard c;
  c.conical = ConicalCard{2e8, 1e-3, 2e-3, 8e-3, 10e-3, 3};
  c.stiffness_cap = 20;
  b.groups.push_back({"tissue", c, kAllFamilies, {}, Vec3::Zero(), 10});
  FixedSelector base;
  base.kind = FixedSelector::Kind::kPlane;
  b.fixed.push_back(base);
  b.options.integrator = Integrator::kImplicitEuler;
  b.options.mass_damping = 5;
  ProbeSpec p;
  p.radius = R;
  p.contact = ContactModel::kSurface;
  b.probes.push_back(p);
  Model m;
  if (!build_model(b, &m).empty()) std::abort();
  State s = make_state(m);
  Workspace ws(m);
  // Press 0.2 R into the top face off the lattice's symmetry lines and let it settle.
  const Vec3 target(0.0713, 0.0687, 0.15 + R - 0.2 * R);
  for (int t = 0; t < 400; ++t) {
    set_probe(s, 0, target);
    step(m, s, ws);
  }
  std::vector<int> cand;
  cand.reserve(m.surface.size());
  std::vector<Vec3> force(m.num_nodes(), Vec3::Zero());
  std::vector<Mat3> block(m.num_nodes(), Mat3::Zero());
  ToolContact tc;
  for (auto _ : state) {
    ProbeState probe = s.probes[0];
    update_proxy(m, 0, s.x, &cand, &probe);
    tool_contact(m, 0, R, probe.proxy, s.x, cand.data(), static_cast<int>(cand.size()), &tc,
                 force.data(), block.data());
    benchmark::DoNotOptimize(force.data());
    benchmark::DoNotOptimize(block.data());
  }
  state.counters["faces"] = tc.faces;
  state.counters["candidates"] = static_cast<double>(cand.size());
  state.counters["force_N"] = s.probes[0].force.norm();
}
// Radii in 0.1 mm: 2.5 mm (a quarter of the spacing), 10 mm, 20 mm and 40 mm (about 50 faces).
BENCHMARK(BM_SurfaceContactStage)
    ->Arg(25)
    ->Arg(100)
    ->Arg(200)
    ->Arg(400)
    ->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
