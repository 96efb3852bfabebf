// The surface contact stage (core/contact.h) on the 4,096-node (16^3, 1 cm lattice) block: one
// tick's proxy update plus the layer's forces and blocks on the nodes (what the contact stage
// adds at a force evaluation), for spheres touching one to about fifty surface triangles.
//   Settled: a press at 0.2 R, the device still (the candidate list kept between ticks, as in
//   the step).
//   Drag: the same press dragged at 10 mm/s, replaying 400 recorded ticks of the body stepping
//   (the list's passes over the whole surface included).
//   build/bin/bench_contact --benchmark_repetitions=9 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <algorithm>
#include <vector>

#include "core/body.h"
#include "core/contact.h"
#include "core/step.h"

namespace {

using namespace conica;

Model Block(double R) {
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
  return m;
}

// Press 0.2 R into the top face off the lattice's symmetry lines.
Vec3 PressTarget(double R) { return Vec3(0.0713, 0.0687, 0.15 + R - 0.2 * R); }

// One tick of the stage: the proxy update and the layer's node forces and blocks.
void Tick(const Model& m, const std::vector<Vec3>& x, ProbeState* probe, ContactCandidates* cand,
          std::vector<Vec3>* force, std::vector<Mat3>* block, ToolContact* tc) {
  update_proxy(m, 0, x, cand, probe);
  tool_contact(m, 0, probe_radius(m, 0, *probe), probe->proxy, x, cand->triangles.data(),
               static_cast<int>(cand->triangles.size()), tc, force->data(), block->data(),
               kToolForceOnly);
}

void BM_SurfaceContactStage(benchmark::State& state) {
  const double R = state.range(0) * 1e-4;  // m
  const Model m = Block(R);
  State s = make_state(m);
  Workspace ws(m);
  for (int t = 0; t < 400; ++t) {  // settle the press
    set_probe(s, 0, PressTarget(R));
    step(m, s, ws);
  }
  ContactCandidates cand = ws.contact.candidates[0];
  std::vector<Vec3> force(m.num_nodes(), Vec3::Zero());
  std::vector<Mat3> block(m.num_nodes(), Mat3::Zero());
  ToolContact tc;
  for (auto _ : state) {
    ProbeState probe = s.probes[0];
    Tick(m, s.x, &probe, &cand, &force, &block, &tc);
    benchmark::DoNotOptimize(force.data());
    benchmark::DoNotOptimize(block.data());
  }
  state.counters["faces"] = tc.faces;
  state.counters["candidates"] = static_cast<double>(cand.triangles.size());
  state.counters["force_N"] = s.probes[0].force.norm();
}

void BM_SurfaceContactDrag(benchmark::State& state) {
  const double R = state.range(0) * 1e-4;  // m
  const Model m = Block(R);
  State s = make_state(m);
  Workspace ws(m);
  for (int t = 0; t < 400; ++t) {
    set_probe(s, 0, PressTarget(R));
    step(m, s, ws);
  }
  // Record the drag: positions and the probe's state before each tick.
  const int ticks = 400;
  std::vector<std::vector<Vec3>> xs;
  std::vector<ProbeState> probes;
  for (int t = 0; t < ticks; ++t) {
    set_probe(s, 0, PressTarget(R) + Vec3(1e-5 * t, 0, 0));
    xs.push_back(s.x);
    probes.push_back(s.probes[0]);
    step(m, s, ws);
  }
  ContactCandidates cand(m);
  std::vector<Vec3> force(m.num_nodes(), Vec3::Zero());
  std::vector<Mat3> block(m.num_nodes(), Mat3::Zero());
  ToolContact tc;
  int t = 0, faces = 0;
  for (auto _ : state) {
    ProbeState probe = probes[t];
    Tick(m, xs[t], &probe, &cand, &force, &block, &tc);
    faces = std::max(faces, tc.faces);
    benchmark::DoNotOptimize(force.data());
    t = (t + 1) % ticks;
  }
  state.counters["max_faces"] = faces;
  state.counters["passes_per_tick"] =
      static_cast<double>(cand.passes) / static_cast<double>(state.iterations());
}

// Radii in 0.1 mm: 2.5 mm (a quarter of the spacing), 10, 20, 40 mm, 55 and 60 mm (about fifty
// and sixty-five faces).
BENCHMARK(BM_SurfaceContactStage)
    ->Arg(25)
    ->Arg(100)
    ->Arg(200)
    ->Arg(400)
    ->Arg(550)
    ->Arg(600)
    ->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_SurfaceContactDrag)->Arg(25)->Arg(100)->Arg(550)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
