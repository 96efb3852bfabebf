// conica-lab's sharded sweeps (stability, tradeoff) as a user runs them: N shards and the merge
// write the CSV one process writes (every column but the wall-time ones); a shard run again
// skips the units it finished; the merge names the units still missing; a unit store made with
// other options is refused; a bad --shard is refused.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "lab_run.h"

namespace conica {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using testing::run_lab;
using testing::slurp;

fs::path Temp(const std::string& name) {
  const fs::path p =
      fs::path(::testing::TempDir()) / ("conica_sweep_" + std::to_string(getpid()) + "_" + name);
  fs::remove_all(p);
  fs::remove_all(p.string() + ".units");
  fs::remove(p.string() + ".csv");
  return p;
}

// The CSV without the columns named in `drop`.
std::string Without(const std::string& csv, const std::vector<std::string>& drop) {
  std::istringstream in(csv);
  std::string line, out;
  std::vector<bool> keep;
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::stringstream ls(line);
    for (std::string c; std::getline(ls, c, ',');) cells.push_back(c);
    if (line.back() == ',') cells.emplace_back();
    if (keep.empty())
      for (const std::string& c : cells)
        keep.push_back(std::find(drop.begin(), drop.end(), c) == drop.end());
    for (size_t i = 0; i < cells.size(); ++i)
      if (i >= keep.size() || keep[i]) out += cells[i] + ",";
    out += "\n";
  }
  return out;
}

const std::string kStability = "stability --seconds 0.005 --no-plot --out ";

TEST(LabSweep, StabilityShardsAndMergeEqualOneProcessByteForByte) {
  const fs::path one = Temp("stab_one"), sh = Temp("stab_sh");
  auto r = run_lab(kStability + "'" + one.string() + "'");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("[41/41] unit 40 done"));
  const std::string single = slurp(one.string() + ".csv");
  ASSERT_GT(single.size(), 1000u);
  for (int i = 0; i < 3; ++i) {
    r = run_lab(kStability + "'" + sh.string() + "' --shard " + std::to_string(i) + "/3");
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_THAT(r.output, HasSubstr("shard " + std::to_string(i) + "/3: "));
    EXPECT_FALSE(fs::exists(sh.string() + ".csv")) << "a shard writes units, not the CSV";
  }
  r = run_lab(kStability + "'" + sh.string() + "' --merge");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(slurp(sh.string() + ".csv"), single);
}

// A job array starts its shards at once: each finds no unit store and writes the same key file.
// Eight shards started together all succeed and merge to the one-process CSV.
TEST(LabSweep, ShardsStartedTogetherAllSucceed) {
  const fs::path one = Temp("stab_one_c"), sh = Temp("stab_sh_c");
  auto r = run_lab(kStability + "'" + one.string() + "'");
  ASSERT_EQ(r.status, 0) << r.output;
  constexpr int kShards = 8;
  std::vector<testing::LabRun> runs(kShards);
  std::vector<std::thread> threads;
  for (int i = 0; i < kShards; ++i)
    threads.emplace_back([&, i] {
      runs[i] = run_lab(kStability + "'" + sh.string() + "' --shard " + std::to_string(i) + "/" +
                        std::to_string(kShards));
    });
  for (std::thread& t : threads) t.join();
  for (int i = 0; i < kShards; ++i)
    EXPECT_EQ(runs[i].status, 0) << "shard " << i << ": " << runs[i].output;
  r = run_lab(kStability + "'" + sh.string() + "' --merge");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(slurp(sh.string() + ".csv"), slurp(one.string() + ".csv"));
}

TEST(LabSweep, ARerunResumesTheMergeNamesWhatIsMissingOtherOptionsAreRefused) {
  const fs::path sh = Temp("stab_resume");
  auto r = run_lab(kStability + "'" + sh.string() + "' --shard 0/2");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("shard 0/2: 21 of 41 units (0 done before)"));
  // An interrupted shard: one unit lost; the rerun does only that one.
  ASSERT_TRUE(fs::remove(sh.string() + ".units/unit-4.csv"));
  r = run_lab(kStability + "'" + sh.string() + "' --shard 0/2");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("21 of 41 units (20 done before)"));
  EXPECT_THAT(r.output, HasSubstr("[1/1] unit 4 done"));
  r = run_lab(kStability + "'" + sh.string() + "' --merge");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("20 of 41 units missing (1, 3, 5,"));
  EXPECT_FALSE(fs::exists(sh.string() + ".csv"));
  r = run_lab("stability --seconds 0.01 --no-plot --out '" + sh.string() + "' --shard 1/2");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("holds units of other options"));
  for (const char* bad : {"2/2", "1", "a/b", "-1/3", "0/0"}) {
    r = run_lab(kStability + "'" + sh.string() + "' --shard " + bad);
    EXPECT_EQ(r.status, 2) << bad << ": " << r.output;
    EXPECT_THAT(r.output, HasSubstr("expected i/N")) << bad;
  }
}

TEST(LabSweep, TradeoffShardsAndMergeEqualOneProcessApartFromWallTimes) {
  const fs::path one = Temp("trade_one"), sh = Temp("trade_sh");
  const std::string t = "tradeoff --quick --no-plot --out ";
  auto r = run_lab(t + "'" + one.string() + "'");
  ASSERT_EQ(r.status, 0) << r.output;
  for (int i = 0; i < 2; ++i) {
    r = run_lab(t + "'" + sh.string() + "' --shard " + std::to_string(i) + "/2");
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_THAT(r.output, HasSubstr("shard " + std::to_string(i) + "/2: 2 of 4 units"));
  }
  r = run_lab(t + "'" + sh.string() + "' --merge");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("Pareto front"));
  const std::string a = slurp(one.string() + ".csv"), b = slurp(sh.string() + ".csv");
  ASSERT_GT(a.size(), 500u);
  EXPECT_EQ(Without(a, {"step_us", "cpu_us"}), Without(b, {"step_us", "cpu_us"}));
  EXPECT_NE(Without(a, {}), Without(b, {})) << "wall times measured twice are never equal";
}

}  // namespace
}  // namespace conica
