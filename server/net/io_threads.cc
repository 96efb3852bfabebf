#include "net/io_threads.h"

#include <pthread.h>
#include <sched.h>

#include <thread>

namespace conica::net {

bool fifo_allowed(int priority) {
  bool ok = false;
  std::thread([&] {
    sched_param sp{};
    sp.sched_priority = priority;
    ok = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp) == 0;
  }).join();
  return ok;
}

bool set_io_threads_fifo(zmq::context_t& context, int priority) {
  if (!fifo_allowed(priority)) return false;
  context.set(zmq::ctxopt::thread_sched_policy, SCHED_FIFO);
  context.set(zmq::ctxopt::thread_priority, priority);
  return true;
}

}  // namespace conica::net
