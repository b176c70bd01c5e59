// Memory-budget test support: counts every heap allocation the process makes.
//
// Linking this library into a test executable replaces the global operator new/new[] (all
// forms) and interposes malloc, calloc, realloc, memalign, aligned_alloc and posix_memalign,
// so each call is counted before it reaches glibc's allocator. Under AddressSanitizer, whose
// allocator must stay in charge, the same counts come from the sanitizer's allocation hook.
//
// Usage, the steady-state pattern:
//   init();                              // may allocate
//   { SteadyStateScope steady;           // from here on, nothing may allocate
//     for (...) step();
//     EXPECT_EQ(steady.allocations(), 0u); }
// or EXPECT_NO_ALLOCATIONS(statement) from memory_assertions.hpp.
#pragma once

#include <cstddef>
#include <cstdint>

namespace blockmap::testing {

struct AllocationTally {
  std::uint64_t calls = 0;  // allocating calls (new, new[], malloc, calloc, realloc, ...)
  std::uint64_t bytes = 0;  // bytes requested by those calls
};

// Every allocation by every thread since the process started.
[[nodiscard]] AllocationTally allocations_since_start() noexcept;
// The calling thread's allocations since it started (a pipeline thread among others).
[[nodiscard]] AllocationTally allocations_on_this_thread() noexcept;

// True when the counting hooks are in place (always, in a binary linking this library; the
// harness's own test checks it so that a broken link cannot make every budget test pass).
[[nodiscard]] bool allocation_counting_active() noexcept;

// Marks the start of the steady state: allocations() counts from construction, and Eigen's
// runtime no-malloc mode is on for the scope (EIGEN_RUNTIME_NO_MALLOC is defined project-wide;
// with assertions enabled an Eigen heap allocation inside the scope stops the test at once,
// in every build the counter sees it). Scopes do not nest.
class SteadyStateScope {
 public:
  SteadyStateScope() noexcept;
  ~SteadyStateScope();
  SteadyStateScope(const SteadyStateScope&) = delete;
  SteadyStateScope& operator=(const SteadyStateScope&) = delete;

  [[nodiscard]] std::uint64_t allocations() const noexcept;
  [[nodiscard]] std::uint64_t allocated_bytes() const noexcept;

 private:
  AllocationTally mark_;
  bool eigen_was_allowed_;
};

// Keeps the optimiser from deleting an allocation whose result is unused (C++14 lets
// compilers elide new/delete pairs): the harness's own test must allocate for real.
void escape(const void* pointer) noexcept;

}  // namespace blockmap::testing
