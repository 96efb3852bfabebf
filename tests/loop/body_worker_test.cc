// Multi-rate serving (loop/body_worker.h): a calibrated block stepped at 50 Hz on the body thread
// and answered at 1 kHz from its local compliance, pressed, held and slid, against the same body
// stepped every tick at 1 kHz with a converged Newton iteration (the independent value: the body
// solved at the tick rate). The body thread is waited for after each hand-over, so the run is
// the same on any machine (the thread keeps pace exactly).
#include "loop/body_worker.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <thread>
#include <vector>

#include "../core/lattice_meshes.h"
#include "core/body.h"
#include "core/step.h"

namespace conica::loop {
namespace {

using testing_meshes::Tetrahedralised;

constexpr double kRadius = 0.004;  // m
const Vec3 kTop(0.01, 0.01, 0.015);

// A 20 x 20 x 15 mm block of the EF30 card (volume and shear terms), tetrahedra, fixed base,
// served at 1 kHz with the body at 50 Hz; the node stiffness is the multi-rate default.
Model Block() {
  BodySpec b;
  b.mesh = Tetrahedralised(make_box_lattice(Vec3(0.02, 0.02, 0.015), {4, 4, 3}));
  b.density = 1070;
  SpringCard c;
  c.conical = ConicalCard{
      2.0638952894602549e9, 1.6662609498394193e-3, 4.8853058085019819e-3, 8e-3, 10e-3, 3};
  c.stiffness_cap = 1000;
  b.groups.push_back({"silicone", c, kAllFamilies, {}, Vec3::Zero(), 10});
  b.bulk_modulus = 137052.6;
  b.shear_modulus = 15613.6;
  FixedSelector base;
  base.kind = FixedSelector::Kind::kPlane;
  b.fixed.push_back(base);
  b.probes.push_back(ProbeSpec{kRadius, 0});
  b.options.integrator = Integrator::kImplicitEuler;
  b.options.mass_damping = 20;
  b.options.newton_iterations = 4;
  b.options.cg_iterations = 200;
  b.options.cg_tolerance = 1e-10;
  b.options.body_rate_hz = 50;
  Model m;
  EXPECT_EQ(build_model(b, &m), "");
  return m;
}

// Press from 1 mm above to 2.5 mm deep (0.3 s), hold (0.1 s), slide 2 mm (0.2 s), hold (0.05 s).
Vec3 Path(int tick) {
  const double t = 1e-3 * tick;
  const double depth = -1e-3 + 3.5e-3 * std::min(1.0, t / 0.3);
  const double slide = 2e-3 * std::clamp((t - 0.4) / 0.2, 0.0, 1.0);
  return kTop + Vec3(slide, 0, kRadius - depth);
}

TEST(BodyWorkerTest, PerTickForceFollowsTheBodySolvedEveryTick) {
  const Model m = Block();
  ASSERT_GT(m.probes[0].stiffness, 0);
  constexpr int kTicks = 650;

  // Reference: the body stepped every tick.
  Model ref_model = m;
  ref_model.options.body_rate_hz = 0;
  State ref = make_state(ref_model);
  Workspace ws(ref_model);
  std::vector<Vec3> ref_force(kTicks);
  for (int t = 0; t < kTicks; ++t) {
    set_probe(ref, 0, Path(t));
    step(ref_model, ref, ws);
    ProbeState p = ref.probes[0];
    probe_contact(ref_model, ref.x, 0, Path(t), kRadius, &p);
    ref_force[t] = p.force;
  }

  State s = make_state(m);
  BodyWorker worker(m, s);
  ASSERT_EQ(worker.every(), 20);
  double err2 = 0, ref2 = 0, worst = 0, fmax = 0;
  for (const Vec3& f : ref_force) fmax = std::max(fmax, f.norm());
  for (int t = 0; t < kTicks; ++t) {
    set_probe(s, 0, Path(t));
    worker.tick(m, s);
    while (worker.stepping()) std::this_thread::sleep_for(std::chrono::microseconds(50));
    const Vec3 d = s.probes[0].force - ref_force[t];
    err2 += d.squaredNorm();
    ref2 += ref_force[t].squaredNorm();
    if (ref_force[t].norm() > 0.2 * fmax) worst = std::max(worst, d.norm() / ref_force[t].norm());
  }
  const double rms = std::sqrt(err2 / ref2);
  std::printf(
      "largest force %.4f N; per-tick RMS error %.2f %%, worst %.2f %% (above 20 %% of "
      "the largest); %llu body steps, %llu frozen answers, %llu late ticks\n",
      fmax, 100 * rms, 100 * worst, static_cast<unsigned long long>(worker.body_steps()),
      static_cast<unsigned long long>(worker.frozen_answers()),
      static_cast<unsigned long long>(worker.late_ticks()));
  EXPECT_GT(fmax, 0.05);
  EXPECT_LT(rms, 0.02);
  EXPECT_GE(worker.body_steps(), static_cast<std::uint64_t>(kTicks / 20 - 1));
}

}  // namespace
}  // namespace conica::loop
