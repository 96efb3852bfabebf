// conica-lab mesh as a user runs it: the built binary on a good and a damaged file.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <fstream>
#include <string>

#include "lab_run.h"

namespace {

using ::testing::HasSubstr;

using conica::testing::LabRun;
using conica::testing::RemovedAtEnd;
using conica::testing::run_lab;

TEST(LabMesh, Liver2Summary) {
  const LabRun r = run_lab(std::string("mesh '") + CONICA_SHARED_DIR "/data/meshes/liver2.msh'");
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("\nnodes: 507\n"));
  EXPECT_THAT(r.output, HasSubstr("\ntetrahedra: 1493\n"));
  EXPECT_THAT(r.output, HasSubstr("\nhexahedra: 0\n"));
  // V - E + F - T = 1 for the solid liver gives E = 507 + 3416 - 1493 - 1.
  EXPECT_THAT(r.output, HasSubstr("\nsprings: 2429\n"));
  EXPECT_THAT(r.output, HasSubstr("\nbbox: ["));
  EXPECT_THAT(r.output, HasSubstr("region_2 (id 2): 1493 tetrahedra"));
  EXPECT_THAT(r.output, HasSubstr("repair:\n  clean\n"));
}

TEST(LabMesh, HexSpringsCountAllPairsOfTheCube) {
  const std::string path =
      ::testing::TempDir() + "conica_lab_hex_" + std::to_string(getpid()) + ".vtk";
  std::ofstream(path) << "# vtk DataFile Version 3.0\nhex\nASCII\nDATASET UNSTRUCTURED_GRID\n"
                         "POINTS 8 float\n0 0 0 1 0 0 1 1 0 0 1 0 0 0 1 1 0 1 1 1 1 0 1 1\n"
                         "CELLS 1 9\n8 0 1 2 3 4 5 6 7\nCELL_TYPES 1\n12\n";
  const LabRun r = run_lab("mesh '" + path + "'");
  std::remove(path.c_str());
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("\nhexahedra: 1\n"));
  EXPECT_THAT(r.output, HasSubstr("\nsprings: 28\n"));
  EXPECT_THAT(r.output, HasSubstr("\nbbox: [0, 0, 0] .. [1, 1, 1]\n"));
}

TEST(LabMesh, BadFileExitsNonZeroWithFileAndLine) {
  const std::string path =
      ::testing::TempDir() + "conica_lab_bad_" + std::to_string(getpid()) + ".msh";
  std::ofstream(path) << "$NOD\n2\n1 0 0 0\n2 1 0 0\n$ENDNOD\n$ELM\n1\n"
                         "37 4 1 1 4 1 2 9001 2\n$ENDELM\n";
  const LabRun r = run_lab("mesh '" + path + "'");
  std::remove(path.c_str());
  EXPECT_NE(r.status, 0);
  EXPECT_THAT(r.output, HasSubstr(path + ":8: element 37 references unknown node 9001"));
}

TEST(LabMesh, MissingFileExitsNonZero) {
  const LabRun r = run_lab("mesh /nonexistent/liver.msh");
  EXPECT_NE(r.status, 0);
  EXPECT_THAT(r.output, HasSubstr("/nonexistent/liver.msh"));
}

}  // namespace

// conica-lab run: deterministic headless runs (same inputs -> same bytes) and its summary line.
using conica::testing::slurp;

TEST(LabRun, SameInputsGiveTheSameBytesAndASummary) {
  const std::string scene = std::string(CONICA_SOURCE_DIR) + "/configs/paper-cube.pbtxt";
  const std::string script = std::string(CONICA_SOURCE_DIR) + "/configs/probes/press-center.csv";
  const std::string out1 = ::testing::TempDir() + "run1.csv",
                    out2 = ::testing::TempDir() + "run2.csv";
  const RemovedAtEnd cleanup{{out1, out2}};
  const std::string args =
      "run --scene '" + scene + "' --probe-script '" + script + "' --relative --ticks 1500 --out ";
  const LabRun a = run_lab(args + "'" + out1 + "'");
  const LabRun b = run_lab(args + "'" + out2 + "'");
  ASSERT_EQ(a.status, 0) << a.output;
  ASSERT_EQ(b.status, 0) << b.output;
  EXPECT_THAT(a.output,
              ::testing::MatchesRegex("max \\|force\\|: [0-9.e+-]+ N, nan: 0, rollbacks: 0\n"));
  const std::string c1 = slurp(out1), c2 = slurp(out2);
  EXPECT_EQ(c1, c2);  // bit for bit
  EXPECT_EQ(c1.rfind("tick,t,probe,fx,fy,fz,contact\n", 0), 0u);
  EXPECT_EQ(std::count(c1.begin(), c1.end(), '\n'), 1501);
  // The press reaches the body: some rows are in contact with an upward force on the probe.
  EXPECT_THAT(c1, HasSubstr(",1\n"));
}

TEST(LabRun, BadProbeScriptNamesFileLineAndColumn) {
  const std::string bad = ::testing::TempDir() + "bad-script.csv";
  const RemovedAtEnd cleanup{{bad}};
  std::ofstream(bad) << "t,probe,x,y,z\n0,0,0,0,0\n0.1,0,0,zero,0\n";
  const LabRun r =
      run_lab("run --scene '" + std::string(CONICA_SOURCE_DIR) +
              "/configs/paper-cube.pbtxt' --probe-script '" + bad + "' --ticks 10 --out -");
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.output, HasSubstr("bad-script.csv:3:9: field y: \"zero\" is not a finite number"));
}
