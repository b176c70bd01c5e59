// Lock-free single-producer/single-consumer queue for handing messages between threads
// (a device reader thread to the pipeline thread, the pipeline to the output thread).
//
// Wait-free on both sides: no locks, no allocation, no system calls. Exactly one thread may
// call the producer methods and exactly one the consumer methods; the counters and size
// estimates may be read from anywhere. Overflow policy: the producer's try_push rejects the
// newest message when the queue is full and counts it (a producer cannot drop the oldest
// without racing the consumer); the reader decides what a rejection means for its device.
//
// Lamport's ring with one spare slot, indices kept in [0, slots), each side caching the other
// side's index so that the shared cache line is touched only when the cached value runs out.
#pragma once

#include <atomic>
#include <concepts>
#include <cstddef>
#include <span>
#include <utility>

#include "blockmap/core/arena.hpp"
#include "blockmap/core/check.hpp"
#include "blockmap/core/counter.hpp"
#include "blockmap/core/inline_storage.hpp"
#include "blockmap/core/memory.hpp"

namespace blockmap {

template <typename T>
class SpscQueueRef {
 public:
  // Uses `slots` as the ring: the capacity is slots.size() - 1 (at least 1).
  explicit SpscQueueRef(std::span<T> slots) : slots_(slots.data()), slot_count_(slots.size()) {
    BLOCKMAP_CHECK_MSG(slot_count_ >= 2, "an SPSC queue needs at least two slots");
  }
  // Takes capacity + 1 slots from the arena at init.
  SpscQueueRef(Arena& arena, std::size_t capacity, const char* owner)
      : SpscQueueRef(arena.allocate_array<T>(capacity + 1, owner)) {}

  SpscQueueRef(const SpscQueueRef&) = delete;
  SpscQueueRef& operator=(const SpscQueueRef&) = delete;
  ~SpscQueueRef() = default;

  [[nodiscard]] std::size_t capacity() const noexcept { return slot_count_ - 1; }

  // Producer: enqueues `value`, or rejects it when the queue is full (counted).
  template <typename U>
  requires std::assignable_from<T&, U&&>
  [[nodiscard]] bool try_push(U&& value) {
    const std::size_t tail = tail_.load(std::memory_order_relaxed);
    const std::size_t next = advance(tail);
    if (next == producer_cached_head_) {
      producer_cached_head_ = head_.load(std::memory_order_acquire);
      if (next == producer_cached_head_) {
        rejected_newest_.increment();
        return false;
      }
    }
    slots_[tail] = std::forward<U>(value);
    tail_.store(next, std::memory_order_release);
    return true;
  }

  // Consumer: moves the oldest message into `out`; false when the queue is empty.
  [[nodiscard]] bool try_pop(T& out) {
    const std::size_t head = head_.load(std::memory_order_relaxed);
    if (head == consumer_cached_tail_) {
      consumer_cached_tail_ = tail_.load(std::memory_order_acquire);
      if (head == consumer_cached_tail_) {
        return false;
      }
    }
    out = std::move(slots_[head]);
    head_.store(advance(head), std::memory_order_release);
    return true;
  }

  // Any thread: the number of queued messages at some recent instant.
  [[nodiscard]] std::size_t size_approx() const noexcept {
    const std::size_t head = head_.load(std::memory_order_acquire);
    const std::size_t tail = tail_.load(std::memory_order_acquire);
    return tail >= head ? tail - head : tail + slot_count_ - head;
  }

  // Messages the producer could not enqueue because the queue was full.
  [[nodiscard]] const MonotonicCounter& rejected_newest() const noexcept {
    return rejected_newest_;
  }

  [[nodiscard]] std::size_t memory_bytes() const noexcept {
    return slot_count_ * sizeof(T) + sizeof(SpscQueueRef);
  }

 private:
  [[nodiscard]] std::size_t advance(std::size_t index) const noexcept {
    return index + 1 == slot_count_ ? 0 : index + 1;
  }

  T* const slots_ = nullptr;
  const std::size_t slot_count_ = 0;
  // Consumer-owned line: where the consumer reads next, and its copy of the producer's index.
  alignas(kCacheLineBytes) std::atomic<std::size_t> head_{0};
  std::size_t consumer_cached_tail_ = 0;
  // Producer-owned line.
  alignas(kCacheLineBytes) std::atomic<std::size_t> tail_{0};
  std::size_t producer_cached_head_ = 0;
  MonotonicCounter rejected_newest_;
};

template <typename T, std::size_t Capacity>
class SpscQueue : private detail::InlineStorage<T, Capacity + 1>, public SpscQueueRef<T> {
  static_assert(Capacity > 0, "an SPSC queue needs a capacity of at least one");

 public:
  SpscQueue()
      : detail::InlineStorage<T, Capacity + 1>(), SpscQueueRef<T>(std::span<T>(this->slots)) {}
};

}  // namespace blockmap
