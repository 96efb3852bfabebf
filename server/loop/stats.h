// Rolling-window statistics for the fixed-rate loop: a preallocated ring of samples per stage
// and percentiles computed on demand into preallocated scratch (nth_element). Recording a sample
// is a store; nothing allocates after construction.
#pragma once

#include <algorithm>
#include <cstddef>
#include <vector>

namespace conica::loop {

class RollingWindow {
 public:
  explicit RollingWindow(std::size_t capacity)
      : ring_(std::max<std::size_t>(capacity, 1), 0.0), scratch_(ring_.size(), 0.0) {}

  void add(double sample) {
    ring_[head_] = sample;
    head_ = (head_ + 1) % ring_.size();
    if (count_ < ring_.size()) ++count_;
  }
  std::size_t size() const { return count_; }
  void clear() { head_ = count_ = 0; }

  struct Summary {
    double p50 = 0, p99 = 0, max = 0;
  };
  // p50, p99 (nearest rank) and max over the samples in the window; zeros when empty.
  Summary summary() {
    Summary s;
    if (count_ == 0) return s;
    std::copy(ring_.begin(), ring_.begin() + count_, scratch_.begin());
    auto first = scratch_.begin(), last = scratch_.begin() + count_;
    auto at = [&](double q) {
      const std::size_t k = std::min(count_ - 1, static_cast<std::size_t>(q * (count_ - 1) + 0.5));
      std::nth_element(first, first + k, last);
      return first[k];
    };
    s.p50 = at(0.50);
    s.p99 = at(0.99);
    s.max = *std::max_element(first, last);
    return s;
  }

 private:
  std::vector<double> ring_, scratch_;
  std::size_t head_ = 0, count_ = 0;
};

}  // namespace conica::loop
