// Compression curves: the phantom tests of shared/data/phantoms read as the instrument wrote them,
// and every kind of bad file refused naming the file, the line and the column.
#include "io/curve_reader.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

namespace conica::io {
namespace {

const std::string kPhantoms = CONICA_SHARED_DIR "/data/phantoms";

// A small test in the phantom format: 30 mm specimen, compression to 3 mm and back.
const char* kHead =
    "T_A1\nCompression test;\nCylinder Height: 30mm;\n"
    "Time (s),Compression (mm),Load (N),Engineering Strain [-]\n";
const char* kRows =
    "0.0,0.000,0.020,0\n"
    "0.1,1.000,1.500,-0.0333\n"
    "0.2,2.000,3.250,-0.0667\n"
    "0.3,3.000,5.000,-0.1\n"
    "0.4,2.000,2.000,-0.0667\n";

std::string ErrorOf(const std::string& text, const CurveRequest& request = {}) {
  auto r = parse_curve(text, "t.csv", request);
  return r ? std::string() : r.error();
}

TEST(CurveReaderTest, ReadsAPhantomTestAsTheInstrumentWroteIt) {
  // EF30_0T_A1.csv: the header on line 8, the first row on line 9 (0.000000 mm, 0.022750 N),
  // then 0.007460 mm, 0.015810 N; the last, line 1210, 20.000070 mm, 744.310790 N.
  auto r = read_curve(kPhantoms + "/EF30_0T/EF30_0T_A1.csv");
  ASSERT_TRUE(r) << r.error();
  const ForceCurve& c = r.value();
  EXPECT_EQ(c.displacement_unit, "mm");
  EXPECT_EQ(c.force_unit, "N");
  EXPECT_DOUBLE_EQ(c.file_height, 0.030);  // "Cylinder Height: 30mm;"
  ASSERT_GT(c.samples.size(), 1000u);
  EXPECT_EQ(c.samples[0].displacement, 0.0);
  EXPECT_EQ(c.samples[0].force, 0.02275);
  EXPECT_EQ(c.samples[1].displacement, 0.007460 * 1e-3);
  EXPECT_EQ(c.samples[1].force, 0.015810);
  // The test stops at its largest compression, 66.7 % of 30 mm: every row is loading.
  EXPECT_EQ(c.rows, 1202);
  EXPECT_EQ(c.samples.size(), 1202u);
  EXPECT_EQ(c.last_line, 1210);
  EXPECT_EQ(c.samples.back().displacement, 20.000070 * 1e-3);
  EXPECT_EQ(c.samples.back().force, 744.310790);
  for (const CurveSample& s : c.samples) EXPECT_LE(s.displacement, c.samples.back().displacement);
  EXPECT_TRUE(c.warnings.empty());
}

TEST(CurveReaderTest, EveryPhantomTestReadsAgainstTheSpecimenHeight) {
  int files = 0;
  for (const auto& dir : std::filesystem::directory_iterator(kPhantoms)) {
    if (!dir.is_directory()) continue;
    for (const auto& f : std::filesystem::directory_iterator(dir.path())) {
      if (f.path().extension() != ".csv") continue;
      CurveRequest q;
      q.height = 0.030;
      auto r = read_curve(f.path().string(), q);
      EXPECT_TRUE(r) << r.error();
      ++files;
    }
  }
  EXPECT_GE(files, 20);
}

TEST(CurveReaderTest, KeepsTheLoadingBranchAndConvertsUnits) {
  auto r = parse_curve(std::string(kHead) + kRows, "t.csv");
  ASSERT_TRUE(r) << r.error();
  ASSERT_EQ(r.value().samples.size(), 4u);
  EXPECT_EQ(r.value().rows, 5);
  EXPECT_EQ(r.value().last_line, 8);
  EXPECT_EQ(r.value().samples[3].displacement, 3.0 * 1e-3);
  EXPECT_EQ(r.value().samples[3].force, 5.0);
  // The same test in metres and kilonewtons.
  auto si = parse_curve("Compression (m),Load (kN)\n0,0.00002\n0.003,0.005\n", "si.csv");
  ASSERT_TRUE(si) << si.error();
  EXPECT_EQ(si.value().samples[1].displacement, 0.003);
  EXPECT_DOUBLE_EQ(si.value().samples[1].force, 5.0);
  EXPECT_DOUBLE_EQ(si.value().samples[0].force, 0.02);
}

TEST(CurveReaderTest, MissingColumnsAreNamedWithTheirLine) {
  EXPECT_EQ(ErrorOf("T\nTime (s),Compression (mm)\n0,0\n"),
            "t.csv:2: no column \"Load (N)\" (columns: Time (s), Compression (mm))");
  EXPECT_EQ(ErrorOf("a,b\n1,2\n"),
            "t.csv: no header row naming the columns \"Compression (mm)\" and \"Load (N)\"");
  // A row too short for the load column.
  EXPECT_EQ(ErrorOf(std::string(kHead) + "0,0,0.1,0\n0.1,1.0\n"),
            "t.csv:6: column 3 (Load (N)) missing: the row has 2 columns");
  // A unit the reader does not know.
  EXPECT_EQ(ErrorOf("Compression (in),Load (N)\n0,0\n1,1\n"),
            "t.csv:1: column 1 (Compression (in)): unit 'in' is not mm or m");
  EXPECT_EQ(ErrorOf("Compression (mm),Load (lbf)\n0,0\n1,1\n"),
            "t.csv:1: column 2 (Load (lbf)): unit 'lbf' is not N or kN");
}

TEST(CurveReaderTest, NonNumbersAndNaNAreRefusedAtTheirCell) {
  EXPECT_EQ(ErrorOf(std::string(kHead) + "0,0,0.1,0\n0.1,1.0,abc,0\n"),
            "t.csv:6: column 3 (Load (N)): 'abc' is not a finite number");
  EXPECT_EQ(ErrorOf(std::string(kHead) + "0,nan,0.1,0\n"),
            "t.csv:5: column 2 (Compression (mm)): 'nan' is not a finite number");
  EXPECT_EQ(ErrorOf(std::string(kHead) + "0,0,0.1,0\n0.1,1.0,inf,0\n"),
            "t.csv:6: column 3 (Load (N)): 'inf' is not a finite number");
  EXPECT_EQ(ErrorOf(std::string(kHead) + "0,0,0.1,0\n"),
            "t.csv: fewer than two data rows after the header (line 4)");
}

TEST(CurveReaderTest, TensionCurvesAreRefused) {
  // Negative compression: the specimen was pulled (or the sign convention is the other one).
  EXPECT_EQ(ErrorOf(std::string(kHead) + "0,0,0,0\n0.1,-1.0,-1.5,0.03\n0.2,-2.0,-3.0,0.07\n"),
            "t.csv:5: column 2 (Compression (mm)): the largest compression is 0 mm: a tension "
            "test (this reader takes compression positive)");
  // Compression positive but the load pulls.
  EXPECT_EQ(ErrorOf(std::string(kHead) + "0,0,0,0\n0.1,1.0,-1.5,0\n0.2,2.0,-3.0,0\n"),
            "t.csv:7: column 3 (Load (N)): the load at the largest compression is -3 N: a "
            "tension curve, or the load's sign is reversed (compression is positive)");
}

TEST(CurveReaderTest, UnitsThatLookLikeTheOtherAreRefused) {
  CurveRequest q;
  q.height = 0.030;
  // Millimetres in a metre column: 3 "m" on a 30 mm specimen.
  EXPECT_EQ(ErrorOf("Compression (m),Load (N)\n0,0.1\n1.5,1\n3,5\n", q),
            "t.csv:4: column 1 (Compression (m)): reaches 3 m, more than the specimen's height "
            "of 0.03 m: the values look like millimetres");
  // Metres in a millimetre column: 0.003 "mm" on a 30 mm specimen.
  EXPECT_EQ(ErrorOf("Compression (mm),Load (N)\n0,0.1\n0.0015,1\n0.003,5\n", q),
            "t.csv:4: column 1 (Compression (mm)): ends at 0.003 mm, 0.01 % of the specimen's "
            "height of 30 mm: the values look like metres");
  // Beyond the height in its own unit: not a unit slip, still impossible.
  EXPECT_EQ(ErrorOf("Compression (mm),Load (N)\n0,0.1\n40,5\n", q),
            "t.csv:3: column 1 (Compression (mm)): reaches 40 mm, more than the specimen's height "
            "of 30 mm");
  // Without a height from the request the file's own is used.
  EXPECT_EQ(ErrorOf("Height: 30mm\nCompression (mm),Load (N)\n0,0.1\n40,5\n"),
            "t.csv:4: column 1 (Compression (mm)): reaches 40 mm, more than the specimen's height "
            "of 30 mm");
  // The right units pass.
  EXPECT_EQ(ErrorOf(std::string(kHead) + kRows, q), "");
}

TEST(CurveReaderTest, DataThatStopBeforeTheAskedStrainAreRefusedSayingWhatThereIs) {
  CurveRequest q;
  q.height = 0.030;
  q.max_strain = 0.2;  // 6 mm; the test stops at 3 mm
  EXPECT_EQ(ErrorOf(std::string(kHead) + kRows, q),
            "t.csv:8: column 2 (Compression (mm)): the curve ends at 3 mm (strain 0.1 of 30 mm), "
            "before the 6 mm asked (strain 0.2)");
  q.max_strain = 0.1;  // exactly what it reaches
  EXPECT_EQ(ErrorOf(std::string(kHead) + kRows, q), "");
  // A body of another height than the file's specimen: read, with a warning.
  q.height = 0.025;
  q.max_strain = 0;
  auto r = parse_curve(std::string(kHead) + kRows, "t.csv", q);
  ASSERT_TRUE(r) << r.error();
  ASSERT_EQ(r.value().warnings.size(), 1u);
  EXPECT_EQ(r.value().warnings[0],
            "t.csv: the file's specimen height 30 mm is not the body's 25 mm; strains are the "
            "body's");
}

TEST(CurveReaderTest, AMissingFileSaysSo) {
  auto r = read_curve("/nonexistent/curve.csv");
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error(), "/nonexistent/curve.csv: cannot open curve file");
}

}  // namespace
}  // namespace conica::io
