// conica-lab calibrate as a user runs it: the curves read and the card and scene written through
// server/io carry exactly the numbers the fit found in-process; bad curves stop it naming the
// file and the line.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "io/curve_reader.h"
#include "io/scene.h"
#include "lab/calibration.h"
#include "lab_run.h"

namespace conica {
namespace {

using ::testing::HasSubstr;
using testing::RemovedAtEnd;
using testing::run_lab;

const std::string kScene = CONICA_SOURCE_DIR "/configs/phantom-cylinder.pbtxt";
const std::string kData = CONICA_SHARED_DIR "/data/phantoms/EF30_0T/EF30_0T_A1.csv";

std::string TempPath(const std::string& name) {
  return ::testing::TempDir() + "conica_lab_calibrate_" + std::to_string(getpid()) + "_" + name;
}

TEST(LabCalibrate, CardAndSceneCarryTheFittedNumbers) {
  const std::string card = TempPath("card.pbtxt"), scene = TempPath("scene.pbtxt");
  const RemovedAtEnd cleanup{{card, scene}};
  const auto r = run_lab("calibrate --scene '" + kScene + "' --data '" + kData +
                         "' --max-strain 0.5 --full-iterations -1 --stability-margin 0 --out '" +
                         card + "' --scene-out '" + scene + "'");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("fitted scene written to " + scene));
  // The same fit in-process, from the same file.
  BodySpec spec;
  ASSERT_EQ(io::load_scene(kScene, &spec), "");
  const size_t plates = spec.planes.size();
  lab::ensure_top_plate(&spec);
  auto curve = io::read_curve(kData);
  ASSERT_TRUE(curve) << curve.error();
  lab::Curve c;
  for (const io::CurveSample& s : curve.value().samples) c.push_back({s.displacement, s.force});
  lab::FitOptions o;
  o.full_iterations = -1;
  o.stability_margin = 0;  // as on the command line: the written numbers, not the fit, under test
  const lab::FitResult fit = lab::calibrate(spec, {c}, o);
  ASSERT_EQ(fit.error, "");
  // The written scene loads, with the fitted card and volume terms to the last bit.
  auto back = io::read_scene(scene);
  ASSERT_TRUE(back) << back.error();
  const BodySpec& b = back.value().spec;
  ASSERT_EQ(b.groups.size(), 1u);
  const ConicalCard& k = b.groups[0].card.conical;
  EXPECT_EQ(k.G, fit.card.G);
  EXPECT_EQ(k.d, fit.card.d);
  EXPECT_EQ(k.D1, fit.card.D1);
  EXPECT_EQ(k.precompression, fit.card.precompression);
  EXPECT_EQ(b.bulk_modulus, fit.bulk_modulus);
  EXPECT_EQ(b.spread_modulus, fit.spread_modulus);
  EXPECT_EQ(b.shear_modulus, fit.shear_modulus);
  EXPECT_EQ(b.planes.size(), plates) << "the scene's plates, not the fit's";
  EXPECT_EQ(b.mesh.nodes.size(), spec.mesh.nodes.size());
  // The card file: the same material pasted into the scene in place of its own.
  std::ifstream in(card);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_THAT(text, HasSubstr("# Fitted by conica-lab calibrate to 1 curve(s)"));
  auto pasted = io::parse_scene(
      "cylinder { radius: 0.025 height: 0.03 cells_across: 4 cells_high: 3 }\ndensity: 1000\n" +
          text,
      "pasted", ".");
  ASSERT_TRUE(pasted) << pasted.error();
  EXPECT_EQ(pasted.value().spec.groups[0].card.conical.G, fit.card.G);
  EXPECT_EQ(pasted.value().spec.bulk_modulus, fit.bulk_modulus);
}

TEST(LabCalibrate, BadCurvesStopItNamingFileAndLine) {
  const std::string card = TempPath("bad.pbtxt");
  // A1 reaches 66 % of the 30 mm cylinder: 70 % is more than it holds.
  auto r = run_lab("calibrate --scene '" + kScene + "' --data '" + kData +
                   "' --max-strain 0.7 --full-iterations -1 --out '" + card + "'");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr(kData + ":"));
  EXPECT_THAT(r.output, HasSubstr("before the 21 mm asked (strain 0.7)"));
  // A tension curve.
  const std::string tension = TempPath("tension.csv");
  const RemovedAtEnd cleanup{{card, tension}};
  std::ofstream(tension) << "Compression (mm),Load (N)\n0,0\n-1,-2\n-2,-4\n";
  r = run_lab("calibrate --scene '" + kScene + "' --data '" + tension +
              "' --full-iterations -1 --out '" + card + "'");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr(tension + ":2: column 1 (Compression (mm)): the largest "
                                            "compression is 0 mm: a tension test"));
  EXPECT_FALSE(std::filesystem::exists(card));
}

}  // namespace
}  // namespace conica
