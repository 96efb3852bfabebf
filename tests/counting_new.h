// Counting global operator new for the allocation tests: include it in exactly one source file of
// a test binary. Allocations are counted per thread, so a worker thread beside the code under test
// (a factor or body thread) is not counted.
#pragma once

#include <cstdlib>
#include <new>

namespace counting_new {
inline thread_local bool counting = false;
inline thread_local long allocations = 0;

// Operator new calls (and whatever else counts through `allocations`) this thread makes in f.
template <class F>
long during(F&& f) {
  allocations = 0;
  counting = true;
  f();
  counting = false;
  return allocations;
}
}  // namespace counting_new

void* operator new(std::size_t n) {
  if (counting_new::counting) ++counting_new::allocations;
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) { return operator new(n); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
