#include "loop/clock.h"

#include <time.h>

#include <cerrno>

namespace conica::loop {

TimeNs SteadyClock::now_ns() {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<TimeNs>(ts.tv_sec) * 1'000'000'000ull + static_cast<TimeNs>(ts.tv_nsec);
}

void SteadyClock::sleep_until(TimeNs deadline) {
  timespec ts;
  ts.tv_sec = static_cast<time_t>(deadline / 1'000'000'000ull);
  ts.tv_nsec = static_cast<long>(deadline % 1'000'000'000ull);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

void ManualClock::sleep_until(TimeNs deadline) {
  sleeps_.fetch_add(1, std::memory_order_relaxed);
  TimeNs t = t_.load(std::memory_order_acquire);
  while (t < deadline && !t_.compare_exchange_weak(t, deadline, std::memory_order_acq_rel)) {
  }
}

}  // namespace conica::loop
