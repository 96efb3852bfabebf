// The loop's time source: an interface with now_ns() and sleep_until(), so the fixed-rate loop can
// run on the real monotonic clock or, in tests, on a manual clock that only moves when told to.
// Times are nanoseconds on one monotonic time line (CLOCK_MONOTONIC for the real clock, the same
// base as the clients' send times).
#pragma once

#include <atomic>
#include <cstdint>

namespace conica::loop {

using TimeNs = std::uint64_t;  // ns

class Clock {
 public:
  virtual ~Clock() = default;
  virtual TimeNs now_ns() = 0;
  // Returns at the absolute time `deadline` or later (at once when it has passed).
  virtual void sleep_until(TimeNs deadline) = 0;
};

// CLOCK_MONOTONIC: clock_gettime and clock_nanosleep(TIMER_ABSTIME), retried on EINTR.
class SteadyClock final : public Clock {
 public:
  TimeNs now_ns() override;
  void sleep_until(TimeNs deadline) override;
};

// Time stands still until advanced: sleep_until() jumps to the deadline at once, advance() moves
// time forward (a test's way to make a tick "take" long). Readable from any thread.
class ManualClock final : public Clock {
 public:
  explicit ManualClock(TimeNs start = 1'000'000'000) : t_(start) {}
  TimeNs now_ns() override { return t_.load(std::memory_order_acquire); }
  void sleep_until(TimeNs deadline) override;
  void advance(TimeNs dt) { t_.fetch_add(dt, std::memory_order_acq_rel); }
  std::uint64_t sleeps() const { return sleeps_.load(std::memory_order_relaxed); }

 private:
  std::atomic<TimeNs> t_;
  std::atomic<std::uint64_t> sleeps_{0};
};

}  // namespace conica::loop
