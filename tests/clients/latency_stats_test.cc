// Latency statistics: nearest-rank percentiles on known sets, matching by sequence, lost,
// duplicate and unknown replies, the summary line.
#include "common/latency_stats.h"

#include <gtest/gtest.h>

namespace conica::client {
namespace {

TEST(LatencyStats, PercentilesOfOneToThousand) {
  std::vector<double> v;
  for (int i = 1000; i >= 1; --i) v.push_back(i);  // unsorted on purpose
  const LatencySummary s = summarize(v);
  EXPECT_EQ(s.count, 1000u);
  // Nearest rank on 1..1000: the q-th percentile is ceil(q n).
  EXPECT_EQ(s.p50, 500);
  EXPECT_EQ(s.p90, 900);
  EXPECT_EQ(s.p99, 990);
  EXPECT_EQ(s.p999, 999);
  EXPECT_EQ(s.max, 1000);
  EXPECT_DOUBLE_EQ(s.mean, 500.5);
}

TEST(LatencyStats, SmallAndEmptySets) {
  EXPECT_EQ(summarize({}).count, 0u);
  EXPECT_EQ(summarize({}).p99, 0);
  const LatencySummary one = summarize({42});
  EXPECT_EQ(one.p50, 42);
  EXPECT_EQ(one.p999, 42);
  // Ten samples with one outlier: p50 = 5th, p90 = 9th, p99 = p99.9 = max = 10th.
  const LatencySummary s = summarize({1, 2, 3, 4, 5, 6, 7, 8, 9, 1000});
  EXPECT_EQ(s.p50, 5);
  EXPECT_EQ(s.p90, 9);
  EXPECT_EQ(s.p99, 1000);
  EXPECT_EQ(s.max, 1000);
}

TEST(LatencyRecorder, MatchesBySequenceFromTheScheduledTime) {
  LatencyRecorder r(5);
  for (std::uint64_t i = 0; i < 5; ++i) ASSERT_TRUE(r.on_sent(i, 1'000'000 * i));
  // Replies out of order; request 2 never answered, request 4 answered twice.
  EXPECT_TRUE(r.on_reply(3, 3'000'000 + 250'000));
  EXPECT_TRUE(r.on_reply(0, 0 + 100'000));
  EXPECT_TRUE(r.on_reply(1, 1'000'000 + 2'500'000));  // late: measured from its schedule
  EXPECT_TRUE(r.on_reply(4, 4'000'000 + 50'000));
  EXPECT_FALSE(r.on_reply(4, 4'000'000 + 60'000));
  EXPECT_FALSE(r.on_reply(17, 0));
  EXPECT_EQ(r.sent(), 5u);
  EXPECT_EQ(r.received(), 4u);
  EXPECT_EQ(r.lost(), 1u);
  EXPECT_EQ(r.duplicates(), 1u);
  EXPECT_EQ(r.unknown(), 1u);
  EXPECT_DOUBLE_EQ(r.latency_us(1), 2500);
  EXPECT_LT(r.latency_us(2), 0);
  const auto l = r.latencies_us();
  ASSERT_EQ(l.size(), 4u);
  EXPECT_DOUBLE_EQ(l[0], 100);
  EXPECT_DOUBLE_EQ(l[3], 50);
  EXPECT_FALSE(r.on_sent(2, 5));  // a sequence is sent once
  EXPECT_FALSE(r.on_sent(5, 5));  // out of range
}

TEST(LatencyStats, SummaryLineFormat) {
  LatencySummary s;
  s.p50 = 61.25;
  s.p99 = 130;
  s.p999 = 400.04;
  s.max = 2500;
  EXPECT_EQ(summary_line(s, 3, 10000),
            "p50_us=61.2 p99_us=130.0 p999_us=400.0 max_us=2500.0 lost=3 sent=10000");
}

}  // namespace
}  // namespace conica::client
