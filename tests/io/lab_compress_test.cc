// conica-lab compress --check-stability as a user runs it: the body's buckling strain, said before
// the run, against the material's own limit (the body with free faces buckles no later than its
// material loses strong ellipticity) and a compression short of it said to be stable.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>

#include "lab_run.h"

namespace {

using conica::testing::LabRun;
using conica::testing::run_lab;
using ::testing::HasSubstr;

const std::string kCube = std::string("'") + CONICA_SOURCE_DIR "/configs/paper-cube.pbtxt'";

// The percentage printed right after `key` (NaN when absent).
double percent_after(const std::string& out, const std::string& key) {
  const size_t at = out.find(key);
  double v = 0;
  if (at == std::string::npos || std::sscanf(out.c_str() + at + key.size(), "%lf", &v) != 1)
    return std::nan("");
  return v;
}

TEST(LabCompress, CheckStabilitySaysWhereTheBodyBucklesBeforeItsMaterial) {
  const LabRun r = run_lab("compress --scene " + kCube +
                           " --check-stability --static --samples 1 --to-strain 0.5 --out -");
  ASSERT_EQ(r.status, 0) << r.output;
  const double material = percent_after(r.output,
                                        "loses strong ellipticity under uniaxial "
                                        "compression at ");
  const double stable = percent_after(r.output, "the body's equilibrium is stable to ");
  const double unstable = percent_after(r.output, "% strain and unstable at ");
  std::printf("material %.1f %%, body stable to %.1f %%, unstable at %.1f %%\n", material, stable,
              unstable);
  EXPECT_THAT(r.output, HasSubstr("WARNING: the body's equilibrium"));
  ASSERT_GT(material, 0);
  ASSERT_GT(unstable, 0);
  EXPECT_LT(stable, unstable);
  EXPECT_NEAR(unstable - stable, 2.0, 1e-9);  // one increment of 25 to 50 %
  EXPECT_LE(unstable, material + 2.0);        // no later than the material (to an increment)
}

TEST(LabCompress, CheckStabilitySaysAShortCompressionIsStable) {
  const LabRun r = run_lab("compress --scene " + kCube +
                           " --check-stability --static --samples 1 --to-strain 0.15 --out -");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("the body's equilibrium is stable to 15.0 % strain"));
  EXPECT_THAT(r.output, ::testing::Not(HasSubstr("WARNING: the body's equilibrium")));
}

}  // namespace
