// The probe-script CSV (server/io/probe_script.h) in its default, server format: the header is
// required, times strictly increase per probe, probes 0..63; keyframes interpolate linearly.
#include "io/probe_script.h"

#include <gtest/gtest.h>

#include <fstream>

namespace conica::io {
namespace {

std::string Error(std::string_view text) {
  auto r = parse_probe_script(text, "s.csv");
  EXPECT_FALSE(r.ok()) << text;
  return r.ok() ? std::string() : r.error();
}

TEST(ProbeScript, KeyframesInterpolateLinearlyAndHold) {
  auto r = parse_probe_script("# press\n\nt,probe,x,y,z\r\n0,0,0,0,1\n1,0,0,0,0\n0.5,1,1,1,1\n",
                              "s.csv");
  ASSERT_TRUE(r.ok()) << r.error();
  const ProbeScript& s = r.value();
  ASSERT_EQ(s.probes.size(), 2u);
  Vec3 x;
  ASSERT_TRUE(s.position(0, 0.25, &x));
  EXPECT_DOUBLE_EQ(x.z(), 0.75);  // a quarter of the way from z = 1 to z = 0
  ASSERT_TRUE(s.position(0, 7, &x));
  EXPECT_EQ(x, Vec3(0, 0, 0));           // holds after the last keyframe
  EXPECT_FALSE(s.position(1, 0.4, &x));  // not present before its first keyframe
  EXPECT_FALSE(s.position(2, 0.4, &x));
  EXPECT_DOUBLE_EQ(s.end_time(), 1.0);
}

TEST(ProbeScript, ServerFormatErrorsNameFileLineAndColumn) {
  EXPECT_EQ(Error("0,0,0,0,0\n"), "s.csv:1:1: expected the header t,probe,x,y,z");
  EXPECT_EQ(Error("# only a comment\n"),
            "s.csv: empty probe script (expected the header t,probe,x,y,z)");
  EXPECT_EQ(Error("t,probe,x,y,z\n"), "s.csv: no samples (expected lines t,probe,x,y,z)");
  EXPECT_EQ(Error("t,probe,x,y,z\n0,0,0,0,0\n0,0,0,0,1\n"),
            "s.csv:3:1: time must increase for probe 0 (0 s twice)");
  EXPECT_EQ(Error("t,probe,x,y,z\n1,0,0,0,0\n0.5,0,0,0,1\n"),
            "s.csv:3:1: time goes backwards for probe 0 (0.5 s after 1 s)");
  EXPECT_EQ(Error("t,probe,x,y,z\n0,64,0,0,0\n"),
            "s.csv:2:3: probe must be an integer in 0..63, got 64");
  EXPECT_EQ(Error("t,probe,x,y,z\n0,0,0,,0\n"), "s.csv:2:7: field y: \"\" is not a finite number");
  EXPECT_EQ(Error("t,probe,x,y,z\n0,0,0,0,inf\n"),
            "s.csv:2:9: field z: \"inf\" is not a finite number");
  // Fractions of a bounding box (relative scripts) have no metre limit in the server format.
  EXPECT_TRUE(parse_probe_script("t,probe,x,y,z\n0,0,0.5,0.5,140\n", "s.csv").ok());
}

TEST(ProbeScript, ClientFormatChecksMetres) {
  const ProbeScriptFormat f = client_trajectory_format();
  auto r = parse_probe_rows("0,0,0.02,0.02,450\n", "mm.csv", f);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error(),
            "mm.csv:1:15: position more than 100 m from the origin (the file must be in metres)");
  r = parse_probe_rows("time,probe,x,y,z\n0,3,0.02,0.02,0.045\n", "m.csv", f);
  ASSERT_TRUE(r.ok()) << r.error();
  EXPECT_EQ(r.value().front().line, 2);
  EXPECT_EQ(r.value().front().probe, 3);
}

TEST(ProbeScript, MissingFile) {
  auto r = read_probe_script("/nonexistent/p.csv");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error(), "/nonexistent/p.csv: cannot open probe script");
}

TEST(ProbeScript, RepositoryScriptsParse) {
  for (const char* name : {"press-center.csv", "press-block20k.csv"}) {
    auto r = read_probe_script(std::string(CONICA_SOURCE_DIR) + "/configs/probes/" + name);
    ASSERT_TRUE(r.ok()) << r.error();
    EXPECT_GT(r.value().end_time(), 0) << name;
  }
}

}  // namespace
}  // namespace conica::io
