// conica-lab library as a user runs it, on two recipes of shared/data/phantoms with a fast
// setting (cell surrogate only, 12 points, one Poisson ratio): two shards and the merge write the
// same bytes as one process; a rerun skips what is done; the merge refuses a missing shard; a
// recipe with a bad file stops naming file and line and writes no card.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "io/scene.h"
#include "lab_run.h"

namespace conica {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using testing::run_lab;
using testing::slurp;

const std::string kScene = CONICA_SOURCE_DIR "/configs/phantom-cylinder.pbtxt";
const std::string kData = CONICA_SHARED_DIR "/data/phantoms";
// --stability-margin 0: the sweep's sharding, not the fit, is under test here (the margin's fit
// runs in ci-cluster.sh and the calibration tests); it keeps the sanitizer build's run short.
const std::string kFast =
    " --full-iterations -1 --points 12 --poisson-grid 1 --threads 1 --stability-margin 0"
    " --recipes EF30_50T,EF50_50T";

fs::path Temp(const std::string& name) {
  const fs::path p =
      fs::path(::testing::TempDir()) / ("conica_library_" + std::to_string(getpid()) + "_" + name);
  fs::remove_all(p);
  return p;
}

std::string Lib(const fs::path& out, const std::string& more = "") {
  return "library --scene '" + kScene + "' --data-dir '" + kData + "' --out '" + out.string() +
         "'" + kFast + more;
}

TEST(LabLibrary, ShardsAndMergeEqualOneProcessAndResume) {
  const fs::path one = Temp("one"), sharded = Temp("sharded");
  auto r = run_lab(Lib(one));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("[2/2] EF50_50T: "));
  EXPECT_THAT(r.output, HasSubstr("ETA"));
  ASSERT_EQ(run_lab(Lib(one, " --merge")).status, 0);
  r = run_lab(Lib(sharded, " --shard 1/2"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("shard 1/2: 1 of 2 recipes"));
  r = run_lab(Lib(sharded, " --merge"));
  EXPECT_EQ(r.status, 3) << r.output;
  EXPECT_THAT(r.output, HasSubstr("no card with the current key for EF30_50T"));
  EXPECT_FALSE(fs::exists(sharded / "index.csv"));
  ASSERT_EQ(run_lab(Lib(sharded, " --shard 0/2")).status, 0);
  ASSERT_EQ(run_lab(Lib(sharded, " --merge")).status, 0);
  for (const char* f : {"EF30_50T.card", "EF50_50T.card", "index.csv"})
    EXPECT_EQ(slurp(one / f), slurp(sharded / f)) << f;
  // Provenance, and the card is a material a scene names.
  const std::string card = slurp(one / "EF30_50T.card");
  EXPECT_THAT(card, HasSubstr("# data: EF30_50T/EF30_50T_A1.csv ("));
  EXPECT_THAT(card, HasSubstr("# program: conica "));
  EXPECT_THAT(card, HasSubstr("# strain range: error over 0.03 to 0.5"));
  EXPECT_THAT(card, HasSubstr("# error: "));
  const fs::path scene_dir = Temp("scene");
  fs::create_directories(scene_dir);
  fs::create_symlink(one, scene_dir / "materials");
  auto organ = io::parse_scene(
      "cylinder { radius: 0.025 height: 0.03 cells_across: 4 cells_high: 3 }\ndensity: 1070\n"
      "material: \"EF30_50T\"\n",
      "organ.pbtxt", scene_dir.string());
  ASSERT_TRUE(organ) << organ.error();
  EXPECT_GT(organ.value().spec.bulk_modulus, 0);
  // Resume: nothing refitted, nothing changed.
  r = run_lab(Lib(sharded));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("[1/2] EF30_50T: card up to date, skipped"));
  EXPECT_THAT(r.output, HasSubstr("[2/2] EF50_50T: card up to date, skipped"));
  EXPECT_EQ(slurp(one / "EF30_50T.card"), slurp(sharded / "EF30_50T.card"));
}

TEST(LabLibrary, ABadFileStopsItsRecipeNamingFileAndLine) {
  const fs::path db = Temp("db"), out = Temp("out");
  fs::create_directories(db / "BAD");
  std::ofstream(db / "BAD" / "BAD_A1.csv")
      << "Cylinder Height: 30mm;\nCompression (mm),Load (N)\n0,0\n1,0.5\nnan,1\n";
  auto r = run_lab("library --scene '" + kScene + "' --data-dir '" + db.string() + "' --out '" +
                   out.string() + "' --full-iterations -1");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("BAD_A1.csv:5: column 1 (Compression (mm)): 'nan' is not a "
                                  "finite number"));
  EXPECT_FALSE(fs::exists(out / "BAD.card"));
  // Data that stop before the strain asked.
  std::ofstream(db / "BAD" / "BAD_A1.csv") << "Compression (mm),Load (N)\n0,0\n3,1.5\n6,4\n";
  r = run_lab("library --scene '" + kScene + "' --data-dir '" + db.string() + "' --out '" +
              out.string() + "' --full-iterations -1");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("BAD_A1.csv:4: column 1 (Compression (mm)): the curve ends at "
                                  "6 mm"));
  EXPECT_FALSE(fs::exists(out / "BAD.card"));
  r = run_lab("library --scene '" + kScene + "' --data-dir '" + db.string() + "' --out '" +
              out.string() + "' --shard 2/2");
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.output, HasSubstr("--shard 2/2: expected i/N with 0 <= i < N"));
}

}  // namespace
}  // namespace conica
