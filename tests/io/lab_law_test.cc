// conica-lab law as a user runs it: the printed curve reads back to the doubles of the law.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <sstream>
#include <string>
#include <vector>

#include "core/conical.h"
#include "lab_run.h"

namespace {

using ::testing::HasSubstr;

using conica::testing::LabRun;
using conica::testing::run_lab;

struct Row {
  double x = 0, force = 0, stiffness = 0;
  std::string phase;
  std::string text;  // the line as printed
};

std::vector<Row> parse_csv(const std::string& out) {
  std::vector<Row> rows;
  std::istringstream in(out);
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "deflection,force,stiffness,phase");
  while (std::getline(in, line)) {
    Row r;
    r.text = line;
    std::istringstream f(line);
    std::string a, b, c;
    std::getline(f, a, ',');
    std::getline(f, b, ',');
    std::getline(f, c, ',');
    std::getline(f, r.phase);
    char* end = nullptr;
    r.x = std::strtod(a.c_str(), &end);
    EXPECT_EQ(*end, '\0') << line;
    r.force = std::strtod(b.c_str(), &end);
    EXPECT_EQ(*end, '\0') << line;
    r.stiffness = std::strtod(c.c_str(), &end);
    EXPECT_EQ(*end, '\0') << line;
    rows.push_back(r);
  }
  return rows;
}

// The card and sampling of the README example; the law evaluated here is the reference.
const conica::ConicalCard kCard{50, 0.5, 2, 8, 90, 3};
constexpr const char* kArgs =
    "law --G 50 --d 0.5 --D1 2 --D2 8 --L0 90 --na 3 --from 0 --to 89 "
    "--steps 90";

double sample_x(int i) { return 0.0 + (89.0 - 0.0) * i / (90 - 1); }

TEST(LabLaw, DefaultOutputReadsBackToTheSameDoubles) {
  const LabRun r = run_lab(kArgs);
  ASSERT_EQ(r.status, 0) << r.output;
  const std::vector<Row> rows = parse_csv(r.output);
  ASSERT_EQ(rows.size(), 90u);
  const conica::ConicalLaw law(kCard);
  int inexact_at_9_digits = 0;
  for (int i = 0; i < 90; ++i) {
    const conica::LawSample s = law.evaluate(sample_x(i));
    EXPECT_EQ(rows[i].x, sample_x(i)) << rows[i].text;
    EXPECT_EQ(rows[i].force, s.force) << rows[i].text;
    EXPECT_EQ(rows[i].stiffness, s.stiffness) << rows[i].text;
    EXPECT_EQ(rows[i].phase, conica::phase_name(s.phase)) << rows[i].text;
    char nine[64];
    std::snprintf(nine, sizeof nine, "%.9g", s.force);
    inexact_at_9_digits += std::strtod(nine, nullptr) != s.force;
  }
  // The check can fail: nine digits (the old output) lose most of these forces.
  EXPECT_GT(inexact_at_9_digits, 45);
}

TEST(LabLaw, PrecisionOptionRoundsToThatManyDigits) {
  const LabRun r = run_lab(std::string(kArgs) + " --precision 3");
  ASSERT_EQ(r.status, 0) << r.output;
  const std::vector<Row> rows = parse_csv(r.output);
  ASSERT_EQ(rows.size(), 90u);
  const conica::ConicalLaw law(kCard);
  for (int i = 0; i < 90; ++i) {
    const conica::LawSample s = law.evaluate(sample_x(i));
    char expect[64];
    std::snprintf(expect, sizeof expect, "%.3g", s.force);
    EXPECT_EQ(rows[i].force, std::strtod(expect, nullptr)) << rows[i].text;
    EXPECT_NEAR(rows[i].force, s.force, 5e-3 * std::abs(s.force) + 1e-300) << rows[i].text;
  }
  EXPECT_EQ(rows[1].text.substr(0, rows[1].text.find(',')), "1");
}

TEST(LabLaw, PrecisionOutOfRangeIsRefused) {
  for (const char* p : {"0", "18", "-1", "many"}) {
    const LabRun r = run_lab(std::string(kArgs) + " --precision " + p);
    EXPECT_NE(r.status, 0) << p << ": " << r.output;
    EXPECT_THAT(r.output, HasSubstr("--precision")) << p;
  }
}

}  // namespace
