// Round-trip bookkeeping for open-loop latency runs (no coordinated omission): each request is
// registered with its *scheduled* send time, a reply is matched by its echoed sequence, and its
// latency is receive time - scheduled time. Unanswered requests are lost; duplicate and unknown
// sequences are counted and ignored.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace conica::client {

// Nearest-rank percentiles of a sample set, microseconds.
struct LatencySummary {
  std::size_t count = 0;
  double p50 = 0, p90 = 0, p99 = 0, p999 = 0, max = 0, mean = 0;
};

// Nearest rank: the smallest sample with at least q * n samples <= it (q in (0, 1]); sorted
// input, 0 when empty.
double percentile_nearest_rank(const std::vector<double>& sorted, double q);
LatencySummary summarize(std::vector<double> samples_us);

// "p50_us=A p99_us=B p999_us=C max_us=D lost=E sent=F" (one decimal for the times).
std::string summary_line(const LatencySummary& s, std::size_t lost, std::size_t sent);

class LatencyRecorder {
 public:
  // Room for `capacity` requests with sequences 0 .. capacity-1 (allocated here, not later).
  explicit LatencyRecorder(std::size_t capacity);

  // Request `seq` is scheduled at `scheduled_ns`. Returns false when seq is out of range.
  bool on_sent(std::uint64_t seq, std::int64_t scheduled_ns);
  // A reply with echoed `seq` arrived at `recv_ns`. Returns false (and counts) for sequences
  // never sent or already answered.
  bool on_reply(std::uint64_t seq, std::int64_t recv_ns);

  std::size_t sent() const { return sent_; }
  std::size_t received() const { return received_; }
  std::size_t lost() const { return sent_ - received_; }
  std::size_t duplicates() const { return duplicates_; }
  std::size_t unknown() const { return unknown_; }

  // Latency (us) of request seq, or a negative value when unanswered / not sent.
  double latency_us(std::uint64_t seq) const;
  std::int64_t scheduled_ns(std::uint64_t seq) const { return scheduled_[seq]; }
  std::size_t capacity() const { return scheduled_.size(); }
  // Latencies of all answered requests, us, in sequence order.
  std::vector<double> latencies_us() const;

 private:
  std::vector<std::int64_t> scheduled_, received_at_;  // ns; -1: not sent / not answered
  std::size_t sent_ = 0, received_ = 0, duplicates_ = 0, unknown_ = 0;
};

}  // namespace conica::client
