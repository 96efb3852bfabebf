// The worker thread that renews a scene's sparse factor (LinearSolver::kFactorCG, core/
// sparse_system.h) off the 1 kHz thread: the step assembles the next factor's values and hands
// them over (FactorScratch::next_state kAssembled); this thread runs the numeric factorisation,
// which allocates and takes milliseconds, and hands the factor back (kFactored); the step swaps
// it in at its next Newton iteration. The tick never waits for it: while a factorisation is
// running the step preconditions with the factor it has.
#pragma once

#include <thread>

#include "core/sparse_system.h"

namespace conica::loop {

class FactorWorker {
 public:
  // Starts the thread and marks `factor` as served by it (factor->worker). The thread runs at
  // normal priority (SCHED_OTHER), whatever the creating thread's policy.
  explicit FactorWorker(FactorScratch* factor);
  // Stops the thread (a factorisation under way is finished first) and gives `next` back to
  // the step (factor->worker false).
  ~FactorWorker();
  FactorWorker(const FactorWorker&) = delete;
  FactorWorker& operator=(const FactorWorker&) = delete;

 private:
  void run();
  FactorScratch* factor_;
  std::thread thread_;
};

}  // namespace conica::loop
