#include "loop/factor_worker.h"

#include <pthread.h>
#include <sched.h>

namespace conica::loop {

FactorWorker::FactorWorker(FactorScratch* factor) : factor_(factor) {
  factor_->worker = true;
  thread_ = std::thread([this] { run(); });
}

FactorWorker::~FactorWorker() {
  factor_->next_state.store(FactorScratch::kStop, std::memory_order_release);
  factor_->next_state.notify_all();
  thread_.join();
  factor_->worker = false;
  factor_->wanted = true;  // the values handed over may not have been factored
  factor_->next_state.store(FactorScratch::kIdle, std::memory_order_release);
}

void FactorWorker::run() {
  sched_param p{};
  p.sched_priority = 0;
  pthread_setschedparam(pthread_self(), SCHED_OTHER, &p);  // not the loop's real-time policy
  for (;;) {
    const int v = factor_->next_state.load(std::memory_order_acquire);
    if (v == FactorScratch::kStop) return;
    if (v == FactorScratch::kAssembled) {
      const bool ok = factor_->next->factorize();
      int expected = FactorScratch::kAssembled;
      factor_->next_state.compare_exchange_strong(
          expected, ok ? FactorScratch::kFactored : FactorScratch::kFailed,
          std::memory_order_acq_rel);
      continue;
    }
    factor_->next_state.wait(v, std::memory_order_acquire);
  }
}

}  // namespace conica::loop
