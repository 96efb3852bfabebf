// CSV trajectories (errors with file:line:column) and the built-in probe scripts.
#include "common/trajectory.h"

#include <gtest/gtest.h>

#include <sstream>

namespace conica::client {
namespace {

std::string parse_error(const std::string& text) {
  std::istringstream in(text);
  std::vector<TrajectoryRow> rows;
  std::string error;
  EXPECT_FALSE(parse_trajectory(in, "moves.csv", &rows, &error)) << text;
  return error;
}

TEST(Trajectory, ParsesHeaderCommentsAndRows) {
  std::istringstream in(
      "# a press\nt,probe,x,y,z\n0,0,0.02,0.02,0.05\n\n0.001, 1 ,0.02,0.02,4.9e-2\r\n");
  std::vector<TrajectoryRow> rows;
  std::string error;
  ASSERT_TRUE(parse_trajectory(in, "m.csv", &rows, &error)) << error;
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[1].probe, 1);
  EXPECT_DOUBLE_EQ(rows[1].t, 0.001);
  EXPECT_DOUBLE_EQ(rows[1].position.z(), 0.049);
  EXPECT_EQ(rows[1].line, 5);
}

TEST(Trajectory, ErrorsNameFileLineAndColumn) {
  EXPECT_EQ(parse_error("t,probe,x,y,z\n0,0,1,2,3\n0.1,0,1,2\n"),
            "moves.csv:3:10: expected 5 fields (t,probe,x,y,z), got 4");
  EXPECT_EQ(parse_error("0,0,0.1,abc,0\n"),
            "moves.csv:1:9: field y: \"abc\" is not a finite number");
  EXPECT_EQ(parse_error("0,0,0.1,0,0\n0,0.5,0,0,0\n"),
            "moves.csv:2:3: probe must be an integer in 0..1000000, got 0.5");
  EXPECT_EQ(parse_error("0,0,0,0,nan\n"), "moves.csv:1:9: field z: \"nan\" is not a finite number");
  EXPECT_EQ(parse_error("# c\n\n0.2,0,0,0,0\n0.1,1,0,0,0\n0.1,0,0,0,0\n"),
            "moves.csv:5:1: time goes backwards for probe 0 (0.1 s after 0.2 s)");
  EXPECT_EQ(parse_error("-1,0,0,0,0\n"), "moves.csv:1:1: time must be >= 0 s, got -1");
  EXPECT_EQ(
      parse_error("0,0,20,0,300\n"),
      "moves.csv:1:10: position more than 100 m from the origin (the file must be in metres)");
  EXPECT_EQ(parse_error("t,probe,x,y,z\n"), "moves.csv: no samples (expected lines t,probe,x,y,z)");
  EXPECT_EQ(parse_error("0,0,1,2,3,\n"),
            "moves.csv:1:11: expected 5 fields (t,probe,x,y,z), got 6");
  // Columns count from the start of the raw line, blanks included.
  EXPECT_EQ(parse_error("  0, 0 ,  0.1,  x1 ,0\n"),
            "moves.csv:1:17: field y: \"x1\" is not a finite number");
}

TEST(Trajectory, RepeatedTimesAndLargeProbeIndicesAreAccepted) {
  // The client format: a probe may get two samples at the same time; probe indices past 63.
  std::istringstream in("0,0,0,0,0\n0,0,0,0,0.001\n0.5,200,1,2,3\n");
  std::vector<TrajectoryRow> rows;
  std::string error;
  ASSERT_TRUE(parse_trajectory(in, "m.csv", &rows, &error)) << error;
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_EQ(rows[2].probe, 200);
  EXPECT_EQ(rows[2].line, 3);
}

TEST(Trajectory, MissingFile) {
  std::vector<TrajectoryRow> rows;
  std::string error;
  EXPECT_FALSE(load_trajectory("/nonexistent/x.csv", &rows, &error));
  EXPECT_EQ(error, "/nonexistent/x.csv: cannot open");
}

std::vector<Sample> run(ProbeSource& s, int max = 1000000) {
  std::vector<Sample> out;
  Sample x;
  while (max-- > 0 && s.next(nullptr, &x)) out.push_back(x);
  return out;
}

TEST(Scripts, PressApproachesPressesAndHolds) {
  ScriptParams p;
  p.at = Vec3(0.02, 0.02, 0.045);
  p.axis = Vec3(0, 0, -1);
  p.approach = 0.002;
  p.depth = 0.003;
  p.speed = 0.01;
  p.hold = 0.1;
  std::string error;
  auto s = make_script("press", p, &error);
  ASSERT_TRUE(s) << error;
  const auto v = run(*s);
  // 5 mm at 10 mm/s = 0.5 s, then 0.1 s hold, samples every 1 ms: 601 samples.
  ASSERT_EQ(v.size(), 601u);
  EXPECT_NEAR(v.front().position.z(), 0.047, 1e-12);
  EXPECT_NEAR(v[250].position.z(), 0.047 - 0.0025, 1e-12);
  EXPECT_NEAR(v.back().position.z(), 0.042, 1e-12);
  EXPECT_NEAR(v.back().t, 0.6, 1e-12);
}

TEST(Trajectory, ReplayInterpolatesBetweenKnotsAtTheSampleRate) {
  // Knots at 0, 0.01 and 0.0105 s (the last closer than a period) and a repeated time.
  std::vector<TrajectoryRow> rows(4);
  rows[0] = {0.0, 0, Vec3(0, 0, 0.05), 1};
  rows[1] = {0.01, 0, Vec3(0.01, 0, 0.04), 2};
  rows[2] = {0.0105, 0, Vec3(0.01, 0, 0.039), 3};
  rows[3] = {0.0105, 0, Vec3(0.02, 0, 0.039), 4};
  auto replay = make_replay(rows, 0.001);
  const auto v = run(*replay);
  // 0, 1, ..., 10 ms (11 samples on the first segment), then the two rows at 10.5 ms.
  ASSERT_EQ(v.size(), 13u);
  for (int k = 0; k <= 10; ++k) {
    EXPECT_NEAR(v[k].t, 0.001 * k, 1e-12) << k;
    EXPECT_NEAR(v[k].position.x(), 0.001 * k, 1e-12) << k;
    EXPECT_NEAR(v[k].position.z(), 0.05 - 0.001 * k, 1e-12) << k;
  }
  EXPECT_EQ(v[11].position, rows[2].position);
  EXPECT_EQ(v[12].position, rows[3].position);
  EXPECT_EQ(run(*make_replay(rows, 0)).size(), 4u);  // dt <= 0: the rows alone
}

TEST(Scripts, RampSineSweep) {
  ScriptParams p;
  p.approach = 0;
  p.depth = 0.004;
  p.speed = 0.01;
  std::string error;
  auto ramp = run(*make_script("ramp", p, &error));
  EXPECT_NEAR(ramp[400].position.z(), p.at.z() - 0.004, 1e-12);  // deepest at 0.4 s
  EXPECT_NEAR(ramp.back().position.z(), p.at.z(), 1e-12);        // back out at 0.8 s
  p.freq = 2;
  p.cycles = 1;
  auto sine = run(*make_script("sine", p, &error));
  EXPECT_NEAR(sine[250].position.z(), p.at.z() - 0.004, 1e-12);  // half a period at 2 Hz
  p.length = 0.01;
  p.sweep_dir = Vec3(1, 0, 1);  // made perpendicular to the axis
  auto sweep = run(*make_script("sweep", p, &error));
  EXPECT_NEAR(sweep[400].position.z(), p.at.z() - 0.004, 1e-12);
  EXPECT_NEAR(sweep[1400].position.x() - p.at.x(), 0.01, 1e-12);
  EXPECT_NEAR(sweep[1400].position.z(), p.at.z() - 0.004, 1e-12);
}

TEST(Scripts, CreepHoldsTheTargetForce) {
  // A linear "tissue" of 400 N/m under the contact point: the controller settles where
  // 400 N/m * d = 0.5 N, i.e. d = 1.25 mm.
  ScriptParams p;
  p.approach = 0.001;
  p.depth = 0.01;
  p.target_force = 0.5;
  p.gain = 0.05;
  p.hold = 2;
  std::string error;
  auto s = make_script("creep", p, &error);
  ASSERT_TRUE(s) << error;
  Feedback fb;
  Sample x;
  const Feedback* last = nullptr;
  int n = 0;
  while (s->next(last, &x)) {
    const double d = (x.position - p.at).dot(p.axis);  // depth along the axis
    fb.force = Vec3(0, 0, 400 * std::max(0.0, d));     // pushes back up (+z)
    fb.contact = d > 0;
    last = &fb;
    ++n;
  }
  EXPECT_NEAR(-(x.position - p.at).z(), 0.00125, 2e-5);
  EXPECT_GT(n, 2000);
  EXPECT_LT(n, 3000);
}

TEST(Scripts, BadParametersAreReported) {
  ScriptParams p;
  std::string error;
  EXPECT_FALSE(make_script("wiggle", p, &error));
  EXPECT_NE(error.find("unknown script"), std::string::npos);
  p.speed = 0;
  EXPECT_FALSE(make_script("press", p, &error));
  EXPECT_EQ(error, "press: speed must be > 0 m/s");
  p.speed = 0.01;
  p.sweep_dir = Vec3(0, 0, 2);
  EXPECT_FALSE(make_script("sweep", p, &error));
}

TEST(Parsing, VectorsAndAxes) {
  EXPECT_EQ(*parse_vec3("0.1,-2,3e-3"), Vec3(0.1, -2, 0.003));
  EXPECT_FALSE(parse_vec3("1,2"));
  EXPECT_FALSE(parse_vec3("1,2,3,4"));
  EXPECT_FALSE(parse_vec3("1,x,3"));
  EXPECT_EQ(*parse_axis("-z"), Vec3(0, 0, -1));
  EXPECT_EQ(*parse_axis("x"), Vec3(1, 0, 0));
  EXPECT_NEAR((*parse_axis("0,3,4") - Vec3(0, 0.6, 0.8)).norm(), 0, 1e-15);
  EXPECT_FALSE(parse_axis("0,0,0"));
  EXPECT_FALSE(parse_axis("w"));
}

}  // namespace
}  // namespace conica::client
