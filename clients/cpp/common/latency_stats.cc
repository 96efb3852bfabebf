#include "common/latency_stats.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>

namespace conica::client {

double percentile_nearest_rank(const std::vector<double>& sorted, double q) {
  if (sorted.empty()) return 0;
  const double n = static_cast<double>(sorted.size());
  // ceil(q n) computed with a small tolerance so 0.99 * 100 is 99, not 99.000000000000014.
  auto rank = static_cast<std::size_t>(std::ceil(q * n - 1e-9));
  rank = std::clamp<std::size_t>(rank, 1, sorted.size());
  return sorted[rank - 1];
}

LatencySummary summarize(std::vector<double> samples_us) {
  LatencySummary s;
  s.count = samples_us.size();
  if (samples_us.empty()) return s;
  std::sort(samples_us.begin(), samples_us.end());
  s.p50 = percentile_nearest_rank(samples_us, 0.50);
  s.p90 = percentile_nearest_rank(samples_us, 0.90);
  s.p99 = percentile_nearest_rank(samples_us, 0.99);
  s.p999 = percentile_nearest_rank(samples_us, 0.999);
  s.max = samples_us.back();
  s.mean = std::accumulate(samples_us.begin(), samples_us.end(), 0.0) / s.count;
  return s;
}

std::string summary_line(const LatencySummary& s, std::size_t lost, std::size_t sent) {
  char buf[200];
  std::snprintf(buf, sizeof buf,
                "p50_us=%.1f p99_us=%.1f p999_us=%.1f max_us=%.1f lost=%zu sent=%zu", s.p50, s.p99,
                s.p999, s.max, lost, sent);
  return buf;
}

LatencyRecorder::LatencyRecorder(std::size_t capacity)
    : scheduled_(capacity, -1), received_at_(capacity, -1) {}

bool LatencyRecorder::on_sent(std::uint64_t seq, std::int64_t scheduled_ns) {
  if (seq >= scheduled_.size() || scheduled_[seq] >= 0) return false;
  scheduled_[seq] = scheduled_ns;
  ++sent_;
  return true;
}

bool LatencyRecorder::on_reply(std::uint64_t seq, std::int64_t recv_ns) {
  if (seq >= scheduled_.size() || scheduled_[seq] < 0) {
    ++unknown_;
    return false;
  }
  if (received_at_[seq] >= 0) {
    ++duplicates_;
    return false;
  }
  received_at_[seq] = recv_ns;
  ++received_;
  return true;
}

double LatencyRecorder::latency_us(std::uint64_t seq) const {
  if (seq >= scheduled_.size() || received_at_[seq] < 0) return -1;
  return (received_at_[seq] - scheduled_[seq]) * 1e-3;
}

std::vector<double> LatencyRecorder::latencies_us() const {
  std::vector<double> out;
  out.reserve(received_);
  for (std::size_t i = 0; i < scheduled_.size(); ++i)
    if (received_at_[i] >= 0) out.push_back((received_at_[i] - scheduled_[i]) * 1e-3);
  return out;
}

}  // namespace conica::client
