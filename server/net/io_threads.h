// Scheduling of a ZeroMQ context's I/O threads, shared by the server and the clients.
#pragma once

#include <zmq.hpp>

namespace conica::net {

// Can a thread of this process run SCHED_FIFO at `priority`? Tried on a scratch thread.
bool fifo_allowed(int priority);

// Makes the context's I/O threads (created after this call) run SCHED_FIFO at `priority` when the
// process may; libzmq aborts when it cannot apply these options, so they are set only after
// fifo_allowed(). Returns whether they were set.
bool set_io_threads_fifo(zmq::context_t& context, int priority);

}  // namespace conica::net
