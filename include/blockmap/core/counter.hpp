// MonotonicCounter: a count that only grows, for drops, faults and health reporting.
//
// One thread writes a given counter (its owner); any thread may read it. Increments are a
// relaxed load and store, not a read-modify-write, so they cost a plain add on every target.
#pragma once

#include <atomic>
#include <cstdint>

namespace blockmap {

class MonotonicCounter {
 public:
  static_assert(std::atomic<std::uint64_t>::is_always_lock_free,
                "health counters must be lock-free on every target (armhf included)");

  MonotonicCounter() = default;
  MonotonicCounter(const MonotonicCounter&) = delete;
  MonotonicCounter& operator=(const MonotonicCounter&) = delete;

  // Owner thread only.
  void increment(std::uint64_t by = 1) noexcept {
    value_.store(value_.load(std::memory_order_relaxed) + by, std::memory_order_relaxed);
  }

  // Any thread; a value that was true at some instant since the last increment.
  [[nodiscard]] std::uint64_t value() const noexcept {
    return value_.load(std::memory_order_relaxed);
  }

 private:
  std::atomic<std::uint64_t> value_{0};
};

}  // namespace blockmap
