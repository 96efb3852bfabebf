// Speed/accuracy experiments: the error norm, the compression driver against the lattice's
// analytic modulus, first-order convergence of Euler integrators in the step, the Hooke twin,
// the Pareto front, principal-axis registration and the CSV round trip.
#include "lab/tradeoff.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "core/conical.h"

namespace conica::lab {
namespace {

// The paper cube's material (configs/paper-cube.pbtxt): conical card, cap 20, damping.
BodySpec PaperMaterial() {
  BodySpec m;
  m.density = 1000;
  SpringCard c;
  c.law = LawKind::kConical;
  c.conical = ConicalCard{2e8, 1e-3, 2e-3, 8e-3, 10e-3, 3};
  c.stiffness_cap = 20;
  c.damping = 0.02;
  m.groups.push_back({"tissue", c, kAllFamilies, {}, Vec3::Zero(), 10});
  m.options.mass_damping = 5;
  return m;
}

Model Build(const BodySpec& spec, Integrator integ, int substeps, int newton = 2, int cg = 40) {
  BodySpec b = spec;
  b.options.integrator = integ;
  b.options.substeps = substeps;
  b.options.newton_iterations = newton;
  b.options.cg_iterations = cg;
  Model m;
  EXPECT_EQ(build_model(b, &m), "");
  return m;
}

const Vec3 kBox(0.06, 0.06, 0.04);

TEST(TradeoffTest, ErrorNormIsRelativeMaxOverTheCurve) {
  const std::vector<Vec3> ref = {Vec3(0, 0, 1), Vec3(0, 0, 4), Vec3(0, 0, 2)};
  EXPECT_EQ(force_error(ref, ref), 0.0);
  // Largest difference 0.5 N (third point) over the peak 4 N.
  const std::vector<Vec3> f = {Vec3(0, 0, 1.2), Vec3(0, 0, 4.1), Vec3(0, 0, 2.5)};
  EXPECT_DOUBLE_EQ(force_error(f, ref), 0.5 / 4);
  // 3-vector norm: a sideways 3 N at the peak.
  const std::vector<Vec3> g = {Vec3(0, 0, 1), Vec3(3, 0, 4), Vec3(0, 0, 2)};
  EXPECT_DOUBLE_EQ(force_error(g, ref), 3.0 / 4);
  const std::vector<Vec3> bad = {Vec3(0, 0, 1), Vec3(0, 0, NAN), Vec3(0, 0, 2)};
  EXPECT_TRUE(std::isnan(force_error(bad, ref)));
}

// The spike-robust error: a 3-tick contact spike of twice the held force in a 300-tick hold is
// the whole max error (200 %) but sqrt(3 x 2^2 / 300) = 20 % of the RMS; a steady 1 % offset is
// 1 % in both.
TEST(TradeoffTest, RmsErrorIsRobustToShortSpikes) {
  const std::vector<Vec3> ref(300, Vec3(0, 0, 1));
  std::vector<Vec3> spike = ref;
  for (int k = 100; k < 103; ++k) spike[k] = Vec3(0, 0, 3);
  EXPECT_DOUBLE_EQ(force_error(spike, ref), 2.0);
  EXPECT_NEAR(force_rms_error(spike, ref), std::sqrt(3 * 4.0 / 300), 1e-12);
  std::vector<Vec3> offset = ref;
  for (Vec3& f : offset) f.z() = 1.01;
  EXPECT_NEAR(force_rms_error(offset, ref), 0.01, 1e-12);
  EXPECT_NEAR(force_error(offset, ref), 0.01, 1e-12);
  EXPECT_EQ(force_rms_error(ref, ref), 0.0);
  std::vector<Vec3> bad = ref;
  bad[5].x() = NAN;
  EXPECT_TRUE(std::isnan(force_rms_error(bad, ref)));
}

TEST(TradeoffTest, ReferenceSettingHasZeroErrorAndRunsAreDeterministic) {
  const Model m =
      Build(compression_body(PaperMaterial(), kBox, {3, 3, 2}), Integrator::kSymplecticEuler, 16);
  const Trace a = run_compression(m, 0.2, 0.15, 200);
  const Trace b = run_compression(m, 0.2, 0.15, 200);
  ASSERT_EQ(a.force.size(), 200u);
  EXPECT_EQ(a.rollbacks, 0u);
  EXPECT_TRUE(a.finite);
  EXPECT_EQ(force_error(b.force, a.force), 0.0);
  EXPECT_GT(a.force.back().z(), 0) << "compression is positive";
  EXPECT_GT(a.tick_us_median, 0);
}

// Quasi-static compression of a linear lattice: the plate force lies between the uniaxial
// (E A strain) and the confined (M A strain) bounds of the lattice's analytic moduli, because the
// clamped base restrains the lateral expansion near it. E = 3780/639/28 K/L for the hex lattice
// with all 28 springs (tests/lab/compression_test.cc), nu = 1/4, M = E (1 - nu) / ((1 + nu)(1 - 2
// nu)).
TEST(TradeoffTest, CompressionForceBetweenUniaxialAndConfinedModulus) {
  const double K = 49.0196, L = 0.01, strain = 0.01;
  const BodySpec spec = hooke_twin(compression_body(PaperMaterial(), kBox, {3, 3, 2}));
  ASSERT_EQ(spec.groups[0].card.law, LawKind::kHooke);
  const Model m = Build(spec, Integrator::kSymplecticEuler, 1);
  const Trace t = run_compression(m, strain, 1.0, 1500);  // 1 s ramp, 0.5 s hold
  const double E = 3780.0 / 639 / 28 * K / L, nu = 0.25;
  const double M = E * (1 - nu) / ((1 + nu) * (1 - 2 * nu));
  const double A = kBox.x() * kBox.y();
  const double F = t.force.back().z();
  EXPECT_GT(F, E * A * strain);
  EXPECT_LT(F, M * A * strain);
}

TEST(TradeoffTest, HookeTwinHasTheConicalInitialStiffness) {
  const BodySpec conical = compression_body(PaperMaterial(), kBox, {3, 3, 2});
  const BodySpec hooke = hooke_twin(conical);
  const ConicalLaw law(conical.groups[0].card.conical);
  EXPECT_DOUBLE_EQ(hooke.groups[0].card.hooke_k, law.k0());
  EXPECT_NEAR(law.k0(), 49.0196, 1e-4);  // the card of configs/paper-cube-hooke.pbtxt
  EXPECT_EQ(hooke.groups[0].card.hooke_length, 10e-3);
  EXPECT_EQ(hooke.groups[0].card.damping, 0.02);
  // In the linear phase (1 % strain) both laws give the same force.
  const Trace a = run_compression(Build(conical, Integrator::kSymplecticEuler, 2), 0.01, 0.1, 150);
  const Trace b = run_compression(Build(hooke, Integrator::kSymplecticEuler, 2), 0.01, 0.1, 150);
  EXPECT_LT(force_error(b.force, a.force), 0.01);
}

// Euler integrators are first order: halving the step halves the error against a converged run.
// Observed order log2(e(h) / e(h/2)) within 0.75..1.25 on the dynamic compression (the plate
// reaches 20 % strain in 0.15 s, about two periods of the body's first mode).
void ExpectFirstOrder(Integrator integ, int newton, int cg) {
  const BodySpec spec = compression_body(PaperMaterial(), kBox, {3, 3, 2});
  const Trace ref = run_compression(Build(spec, Integrator::kSymplecticEuler, 128), 0.2, 0.15, 200);
  std::vector<double> e;
  for (int n : {1, 2, 4}) {
    const Trace t = run_compression(Build(spec, integ, n, newton, cg), 0.2, 0.15, 200);
    ASSERT_EQ(t.rollbacks, 0u);
    e.push_back(force_error(t.force, ref.force));
  }
  EXPECT_GT(e[0], 1e-3) << "the step must matter for the test to mean anything";
  for (int k = 0; k + 1 < 3; ++k) {
    const double order = std::log2(e[k] / e[k + 1]);
    EXPECT_NEAR(order, 1.0, 0.25) << integrator_name(integ) << ": errors " << e[0] << " " << e[1]
                                  << " " << e[2];
  }
}

TEST(TradeoffTest, SymplecticEulerConvergesFirstOrder) {
  ExpectFirstOrder(Integrator::kSymplecticEuler, 0, 0);
}

TEST(TradeoffTest, ImplicitEulerConvergesFirstOrder) {
  ExpectFirstOrder(Integrator::kImplicitEuler, 4, 200);
}

TEST(TradeoffTest, ParetoFrontOfAHandMadeTable) {
  auto row = [](double us, double err, bool stable = true) {
    TradeoffRow r;
    r.step_us = us;
    r.error = err;
    r.stable = stable;
    return r;
  };
  const std::vector<TradeoffRow> rows = {
      row(10, 0.5),         // 0: front (fastest)
      row(20, 0.6),         // 1: dominated by 0
      row(30, 0.1),         // 2: front
      row(5, 0.01, false),  // 3: unstable: never on the front
      row(30, 0.2),         // 4: dominated by 2 (same time, larger error)
      row(100, 0.01),       // 5: front (most accurate)
      row(50, NAN),         // 6: no error: excluded
  };
  EXPECT_EQ(pareto_front(rows), (std::vector<int>{0, 2, 5}));
  // With the RMS error known the front uses it: row 1's spikes (max 0.6) hide an RMS of 0.05.
  std::vector<TradeoffRow> robust = rows;
  for (TradeoffRow& r : robust) r.rms_error = r.error;
  robust[1].rms_error = 0.05;
  EXPECT_EQ(pareto_front(robust), (std::vector<int>{0, 1, 5}));
}

TEST(TradeoffTest, PrincipalAxisRegistrationRecoversARigidMapAndScale) {
  // An irregular cloud: a skewed lattice with distinct principal extents.
  std::vector<Vec3> target;
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 4; ++j)
      for (int k = 0; k < 3; ++k)
        target.emplace_back(0.03 * i + 0.002 * j * j, 0.02 * j + 0.001 * i,
                            0.01 * k + 0.003 * i * i * 0.1);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()).toRotationMatrix();
  std::vector<Vec3> moved;
  for (const Vec3& x : target) moved.push_back(Vec3(5, -2, 1) + 2.5 * R * x);  // other units
  const double d = register_principal_axes(&moved, target);
  EXPECT_LT(d, 1e-9);
  for (size_t i = 0; i < target.size(); ++i) EXPECT_LT((moved[i] - target[i]).norm(), 1e-9);
}

TEST(TradeoffTest, CsvRoundTripAndErrors) {
  TradeoffRow r;
  r.scene = "compression";
  r.resolution = "10mm";
  r.nodes = 245;
  r.springs = 2000;
  r.integrator = "implicit";
  r.newton = 2;
  r.cg = 40;
  r.substeps = 4;
  r.law = "hooke";
  r.step_us = 123.4;
  r.error = 0.0123;
  r.stable = false;
  r.rollbacks = 3;
  std::vector<TradeoffRow> rows;
  std::string error;
  ASSERT_TRUE(parse_tradeoff_csv(tradeoff_csv_header() + to_csv(r), &rows, &error)) << error;
  ASSERT_EQ(rows.size(), 1u);
  EXPECT_EQ(rows[0].resolution, "10mm");
  EXPECT_EQ(rows[0].newton, 2);
  EXPECT_EQ(rows[0].substeps, 4);
  EXPECT_DOUBLE_EQ(rows[0].step_us, 123.4);
  EXPECT_DOUBLE_EQ(rows[0].error, 0.0123);
  EXPECT_FALSE(rows[0].stable);
  EXPECT_EQ(rows[0].rollbacks, 3u);
  EXPECT_TRUE(std::isnan(rows[0].rms_error));  // not set: written and read back as NaN
  r.rms_error = 0.00456;
  ASSERT_TRUE(parse_tradeoff_csv(tradeoff_csv_header() + to_csv(r), &rows, &error)) << error;
  EXPECT_DOUBLE_EQ(rows[0].rms_error, 0.00456);
  // A CSV from before the column: no RMS error, the front falls back to the max error.
  const std::string old_csv =
      "scene,resolution,nodes,springs,integrator,newton,cg,substeps,law,step_us,error,stable\n"
      "compression,10mm,245,2000,implicit,2,40,4,hooke,123.4,0.0123,1\n";
  ASSERT_TRUE(parse_tradeoff_csv(old_csv, &rows, &error)) << error;
  EXPECT_TRUE(std::isnan(rows[0].rms_error));
  EXPECT_DOUBLE_EQ(front_error(rows[0]), 0.0123);
  EXPECT_FALSE(parse_tradeoff_csv("scene,resolution\n", &rows, &error));
  EXPECT_NE(error.find("no column 'nodes'"), std::string::npos) << error;
  std::string bad = tradeoff_csv_header() + to_csv(r);
  bad.replace(bad.find("123.4"), 5, "fast!");
  EXPECT_FALSE(parse_tradeoff_csv(bad, &rows, &error));
  EXPECT_NE(error.find("line 2: column 'step_us'"), std::string::npos) << error;
}

}  // namespace
}  // namespace conica::lab
