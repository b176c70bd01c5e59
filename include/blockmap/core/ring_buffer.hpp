// Fixed-capacity ring buffer: the capacity is set once (by the type, or by the storage handed
// over at init) and the buffer never allocates.
//
// RingBufferRef<T> is the size-erased view that code passes around; RingBuffer<T, N> holds its
// own storage, built in a base class that is constructed before the view that points at it.
// Storage may also come from the Arena, with a capacity read from configuration.
//
// Overflow policy is in the method name and every drop is counted:
//   try_push        rejects the newest element when full (returns false, rejected_newest())
//   push_overwrite  drops the oldest element when full (dropped_oldest())
// Single-threaded: for handing messages between threads use SpscQueue.
#pragma once

#include <cstddef>
#include <span>
#include <utility>

#include "blockmap/core/arena.hpp"
#include "blockmap/core/check.hpp"
#include "blockmap/core/counter.hpp"
#include "blockmap/core/inline_storage.hpp"

namespace blockmap {

template <typename T>
class RingBufferRef {
 public:
  // Views `storage`; its size is the capacity (at least 1). The storage must outlive the view.
  explicit RingBufferRef(std::span<T> storage) : data_(storage.data()), capacity_(storage.size()) {
    BLOCKMAP_CHECK_MSG(capacity_ > 0, "a ring buffer needs a capacity of at least one");
  }
  // Takes `capacity` slots from the arena at init.
  RingBufferRef(Arena& arena, std::size_t capacity, const char* owner)
      : RingBufferRef(arena.allocate_array<T>(capacity, owner)) {}
  // A member whose capacity comes from configuration: no storage until init().
  RingBufferRef() = default;
  void init(Arena& arena, std::size_t capacity, const char* owner) {
    BLOCKMAP_CHECK_MSG(capacity > 0, "a ring buffer needs a capacity of at least one");
    data_ = arena.allocate_array<T>(capacity, owner).data();
    capacity_ = capacity;
    head_ = 0;
    size_ = 0;
  }

  RingBufferRef(const RingBufferRef&) = delete;
  RingBufferRef& operator=(const RingBufferRef&) = delete;
  ~RingBufferRef() = default;

  [[nodiscard]] std::size_t capacity() const noexcept { return capacity_; }
  [[nodiscard]] std::size_t size() const noexcept { return size_; }
  [[nodiscard]] bool empty() const noexcept { return size_ == 0; }
  [[nodiscard]] bool full() const noexcept { return size_ == capacity_; }

  // Appends a copy of `value`, or rejects it when full (counted). O(1).
  [[nodiscard]] bool try_push(const T& value) {
    if (full()) {
      rejected_newest_.increment();
      return false;
    }
    data_[slot(size_)] = value;
    ++size_;
    return true;
  }

  // Appends a copy of `value`; when full the oldest element is dropped first (counted). O(1).
  void push_overwrite(const T& value) {
    if (full()) {
      drop_oldest();
      dropped_oldest_.increment();
    }
    data_[slot(size_)] = value;
    ++size_;
  }

  // Moves the oldest element into `out`; false when empty. O(1).
  [[nodiscard]] bool try_pop(T& out) {
    if (empty()) {
      return false;
    }
    out = std::move(data_[head_]);
    drop_oldest();
    return true;
  }

  // Removes the oldest element. Precondition: not empty.
  void pop_front() {
    BLOCKMAP_CHECK_MSG(!empty(), "pop_front on an empty ring buffer");
    drop_oldest();
  }

  // Element `index` counted from the oldest (0) to the newest (size() - 1).
  [[nodiscard]] T& operator[](std::size_t index) {
    BLOCKMAP_CHECK_MSG(index < size_, "ring buffer index out of range");
    return data_[slot(index)];
  }
  [[nodiscard]] const T& operator[](std::size_t index) const {
    BLOCKMAP_CHECK_MSG(index < size_, "ring buffer index out of range");
    return data_[slot(index)];
  }
  [[nodiscard]] T& front() { return (*this)[0]; }
  [[nodiscard]] const T& front() const { return (*this)[0]; }
  [[nodiscard]] T& back() { return (*this)[size_ - 1]; }
  [[nodiscard]] const T& back() const { return (*this)[size_ - 1]; }

  // Forgets every element (the storage keeps its bytes; nothing is freed).
  void clear() noexcept {
    head_ = 0;
    size_ = 0;
  }

  [[nodiscard]] const MonotonicCounter& rejected_newest() const noexcept {
    return rejected_newest_;
  }
  [[nodiscard]] const MonotonicCounter& dropped_oldest() const noexcept { return dropped_oldest_; }

  // Element storage plus this view's bookkeeping.
  [[nodiscard]] std::size_t memory_bytes() const noexcept {
    return capacity_ * sizeof(T) + sizeof(RingBufferRef);
  }

 private:
  // Physical slot of the element `offset` places after the oldest; offset < capacity.
  [[nodiscard]] std::size_t slot(std::size_t offset) const noexcept {
    const std::size_t position = head_ + offset;
    return position < capacity_ ? position : position - capacity_;
  }
  void drop_oldest() noexcept {
    head_ = slot(1);
    --size_;
  }

  T* data_ = nullptr;
  std::size_t capacity_ = 0;
  std::size_t head_ = 0;
  std::size_t size_ = 0;
  MonotonicCounter rejected_newest_;
  MonotonicCounter dropped_oldest_;
};

template <typename T, std::size_t N>
class RingBuffer : private detail::InlineStorage<T, N>, public RingBufferRef<T> {
  static_assert(N > 0, "a ring buffer needs a capacity of at least one");

 public:
  RingBuffer() : detail::InlineStorage<T, N>(), RingBufferRef<T>(std::span<T>(this->slots)) {}
};

}  // namespace blockmap
