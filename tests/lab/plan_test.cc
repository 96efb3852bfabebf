// The planner: on a small hand-made table it picks the cheapest setting that meets the tolerance
// within the budget (not the cheapest, not the most accurate), applies the cost scale, ignores
// unstable rows and other experiments or laws, and says when no setting can. Then conica-lab plan
// end to end on that table: its choice, the fragment it writes, and its errors for bad inputs.
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

#include "lab/tradeoff.h"

namespace conica::lab {
namespace {

TradeoffRow Row(const std::string& integ, int substeps, double us, double err, bool stable = true,
                const std::string& scene = "compression", const std::string& law = "conical",
                const std::string& res = "10mm", int nodes = 245) {
  TradeoffRow r;
  r.scene = scene;
  r.resolution = res;
  r.nodes = nodes;
  r.springs = nodes * 9;
  r.integrator = integ;
  r.newton = integ == "implicit" ? 2 : 0;
  r.cg = integ == "implicit" ? 40 : 0;
  r.substeps = substeps;
  r.law = law;
  r.step_us = us;
  r.error = err;
  r.stable = stable;
  return r;
}

std::vector<TradeoffRow> Table() {
  return {
      Row("symplectic", 1, 20, 0.12),                                // 0 cheapest, 12 %
      Row("symplectic", 2, 40, 0.06),                                // 1
      Row("symplectic", 4, 80, 0.03),                                // 2
      Row("implicit", 1, 300, 0.04),                                 // 3 dearer, less exact than 2
      Row("explicit", 1, 10, 0.01, false),                           // 4 unstable
      Row("symplectic", 8, 160, 0.015),                              // 5
      Row("symplectic", 1, 5, 0.001, true, "indentation"),           // 6 other experiment
      Row("symplectic", 1, 5, 0.001, true, "compression", "hooke"),  // 7 other law
      Row("symplectic", 1, 900, 0.002, true, "compression", "conical", "5mm", 1521),  // 8
  };
}

PlanRequest Request(double tol, double budget, double scale = 1) {
  PlanRequest q;
  q.scene = "compression";
  q.law = "conical";
  q.tolerance = tol;
  q.budget_us = budget;
  q.cost_scale = scale;
  return q;
}

TEST(PlanTest, PicksTheCheapestSettingMeetingTheTolerance) {
  const auto rows = Table();
  Plan p = plan(rows, Request(0.05, 1000));
  ASSERT_TRUE(p.found);
  EXPECT_EQ(p.chosen.row, 2) << "symplectic x4: 80 us at 3 %";
  EXPECT_EQ(p.candidates, 6) << "the unstable row and the other experiment and law are not";
  ASSERT_EQ(p.runners_up.size(), 3u);
  EXPECT_EQ(p.runners_up[0].row, 5);
  EXPECT_EQ(p.runners_up[1].row, 3);
  EXPECT_EQ(p.runners_up[2].row, 8);
  // A looser tolerance: the cheapest of all.
  EXPECT_EQ(plan(rows, Request(0.2, 1000)).chosen.row, 0);
  // A tighter one: the finest lattice.
  EXPECT_EQ(plan(rows, Request(0.005, 1000)).chosen.row, 8);
}

TEST(PlanTest, CostScaleMovesSettingsOutOfTheBudget) {
  const auto rows = Table();
  // A scene 10x as expensive: x4 costs 800 us, x8 1600 us, the 5 mm lattice 9 ms.
  Plan p = plan(rows, Request(0.02, 1000, 10));
  EXPECT_FALSE(p.found) << "x8 (1.5 %) costs 1600 us";
  Plan q = plan(rows, Request(0.05, 1000, 10));
  ASSERT_TRUE(q.found);
  EXPECT_EQ(q.chosen.row, 2);
  EXPECT_DOUBLE_EQ(q.chosen.cost_us, 800);
}

TEST(PlanTest, SaysNoSettingAndGivesTheClosest) {
  const auto rows = Table();
  Plan p = plan(rows, Request(0.01, 100));
  EXPECT_FALSE(p.found);
  ASSERT_EQ(p.closest.size(), 2u);
  EXPECT_EQ(p.closest[0].row, 8) << "the cheapest accurate enough, over budget";
  EXPECT_EQ(p.closest[1].row, 2) << "the most accurate within budget, over tolerance";
  Plan none = plan(rows, Request(0.0001, 1));
  EXPECT_FALSE(none.found);
  ASSERT_EQ(none.closest.size(), 1u);
  EXPECT_EQ(none.closest[0].row, 0) << "nothing on either side: the cheapest";
}

// conica-lab plan end to end.
#ifdef CONICA_LAB_BIN
struct LabRun {
  int status;
  std::string out;
};

LabRun Lab(const std::string& args) {
  const std::string cmd = std::string(CONICA_LAB_BIN) + " plan " + args + " 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  LabRun r{-1, ""};
  if (!p) return r;
  std::array<char, 512> buf{};
  while (fgets(buf.data(), buf.size(), p)) r.out += buf.data();
  const int st = pclose(p);
  r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  return r;
}

class PlanCliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    // Files named after the test: CTest runs these tests as parallel processes.
    const std::string name = ::testing::UnitTest::GetInstance()->current_test_info()->name();
    data_ = testing::TempDir() + "plan_test_data_" + name + ".csv";
    out_ = testing::TempDir() + "plan_test_solver_" + name + ".pbtxt";
    // The table, with a symplectic x1 row at the scene's resolution to calibrate against; the
    // paper cube (320 nodes) is nearest the 245-node rows.
    std::ofstream f(data_);
    f << tradeoff_csv_header();
    for (const TradeoffRow& r : Table()) f << to_csv(r);
  }
  void TearDown() override {
    std::remove(data_.c_str());
    std::remove(out_.c_str());
  }
  const std::string scene_ = std::string(CONICA_SOURCE_DIR) + "/configs/paper-cube.pbtxt";
  std::string data_, out_;
};

TEST_F(PlanCliTest, ChoosesAndWritesTheSolverBlock) {
  // A loose budget: the choice does not depend on the machine's speed within a factor of 10.
  const LabRun r = Lab("--scene " + scene_ + " --data " + data_ +
                       " --tolerance 0.05 --budget-us 100000 --calibration-ticks 50 --out " + out_);
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("chosen: symplectic Euler, 4 substeps"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("the scene's own resolution"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("runners-up:"), std::string::npos) << r.out;
  std::ifstream f(out_);
  std::stringstream ss;
  ss << f.rdbuf();
  const std::string frag = ss.str();
  EXPECT_NE(frag.find("integrator: SYMPLECTIC_EULER"), std::string::npos) << frag;
  EXPECT_NE(frag.find("substeps: 4"), std::string::npos) << frag;
  EXPECT_NE(frag.find("rate_hz: 1000"), std::string::npos) << frag;
  EXPECT_NE(frag.find("mass_damping: 5"), std::string::npos) << frag;
}

TEST_F(PlanCliTest, SaysWhenNoSettingCan) {
  const LabRun r = Lab("--scene " + scene_ + " --data " + data_ +
                       " --tolerance 0.0001 --budget-us 100000 --calibration-ticks 20");
  EXPECT_EQ(r.status, 3) << r.out;
  EXPECT_NE(r.out.find("no setting meets 0.01 %"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("Closest:"), std::string::npos) << r.out;
}

TEST_F(PlanCliTest, BadInputsAreNamed) {
  LabRun r = Lab("--scene " + scene_ + " --data " + data_ + " --tolerance -0.1");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.out.find("--tolerance must be a relative error > 0"), std::string::npos) << r.out;
  r = Lab("--scene " + scene_ + " --data " + data_ + " --tolerance 0.05 --budget-us 0");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.out.find("--budget-us must be > 0"), std::string::npos) << r.out;
  r = Lab("--scene no-such-scene.pbtxt --data " + data_ + " --tolerance 0.05");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.out.find("no-such-scene.pbtxt"), std::string::npos) << r.out;
  r = Lab("--scene " + scene_ + " --data no-such-data.csv --tolerance 0.05");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.out.find("--data no-such-data.csv: no such file"), std::string::npos) << r.out;
  {
    std::ofstream f(data_);
    f << "scene,resolution\ncompression,10mm\n";
  }
  r = Lab("--scene " + scene_ + " --data " + data_ + " --tolerance 0.05");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.out.find("no column 'nodes'"), std::string::npos) << r.out;
}
#endif

}  // namespace
}  // namespace conica::lab
