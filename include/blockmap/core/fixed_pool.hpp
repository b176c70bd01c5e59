// Fixed pool: a set number of slots for objects that are created and released in any order
// (for example plane patches waiting for the merger). No allocation after init.
//
// try_create returns nullptr when every slot is in use and counts it (policy: reject newest);
// release() destroys the object and returns its slot. Releasing a pointer that the pool did not
// hand out, or releasing twice, is a CHECK failure. Single-threaded.
#pragma once

#include <cstddef>
#include <functional>
#include <new>
#include <span>
#include <utility>

#include "blockmap/core/arena.hpp"
#include "blockmap/core/check.hpp"
#include "blockmap/core/counter.hpp"
#include "blockmap/core/inline_storage.hpp"

namespace blockmap {

// Raw, correctly aligned room for one T; the pool constructs and destroys T in it.
template <typename T>
struct alignas(T) PoolSlot {
  std::byte bytes[sizeof(T)];
};

template <typename T>
class FixedPoolRef {
 public:
  using SlotIndex = std::size_t;

  // `slots` holds the objects, `free_stack` and `in_use` the bookkeeping; all three the same
  // size (the capacity).
  FixedPoolRef(std::span<PoolSlot<T>> slots, std::span<SlotIndex> free_stack,
               std::span<bool> in_use)
      : slots_(slots), free_stack_(free_stack), in_use_(in_use) {
    BLOCKMAP_CHECK_MSG(!slots.empty(), "a pool needs a capacity of at least one");
    BLOCKMAP_CHECK_MSG(free_stack.size() == slots.size() && in_use.size() == slots.size(),
                       "pool bookkeeping must match its capacity");
    for (std::size_t i = 0; i < slots.size(); ++i) {
      // Filled so that slot 0 is handed out first.
      free_stack_[i] = slots.size() - 1 - i;
      in_use_[i] = false;
    }
    free_count_ = slots.size();
  }
  FixedPoolRef(Arena& arena, std::size_t capacity, const char* owner)
      : FixedPoolRef(arena.allocate_array<PoolSlot<T>>(capacity, owner),
                     arena.allocate_array<SlotIndex>(capacity, owner),
                     arena.allocate_array<bool>(capacity, owner)) {}

  FixedPoolRef(const FixedPoolRef&) = delete;
  FixedPoolRef& operator=(const FixedPoolRef&) = delete;
  // Objects still alive are destroyed with the pool.
  ~FixedPoolRef() {
    for (std::size_t i = 0; i < slots_.size(); ++i) {
      if (in_use_[i]) {
        object_at(i)->~T();
      }
    }
  }

  // Constructs a T from `args` in a free slot; nullptr (counted) when none is free. O(1).
  template <typename... Args>
  [[nodiscard]] T* try_create(Args&&... args) {
    if (free_count_ == 0) {
      exhausted_.increment();
      return nullptr;
    }
    const SlotIndex index = free_stack_[--free_count_];
    in_use_[index] = true;
    return ::new (static_cast<void*>(slots_[index].bytes)) T(std::forward<Args>(args)...);
  }

  // Destroys `object` and frees its slot. O(1).
  void release(T* object) {
    const std::size_t index = index_of(object);
    BLOCKMAP_CHECK_MSG(in_use_[index], "pool object released twice");
    object->~T();
    in_use_[index] = false;
    free_stack_[free_count_++] = index;
  }

  [[nodiscard]] std::size_t capacity() const noexcept { return slots_.size(); }
  [[nodiscard]] std::size_t in_use() const noexcept { return slots_.size() - free_count_; }
  [[nodiscard]] std::size_t available() const noexcept { return free_count_; }
  // Requests refused because every slot was taken.
  [[nodiscard]] const MonotonicCounter& exhausted() const noexcept { return exhausted_; }

  [[nodiscard]] std::size_t memory_bytes() const noexcept {
    return slots_.size() * (sizeof(PoolSlot<T>) + sizeof(SlotIndex) + sizeof(bool)) +
           sizeof(FixedPoolRef);
  }

 private:
  [[nodiscard]] T* object_at(std::size_t index) noexcept {
    return std::launder(static_cast<T*>(static_cast<void*>(slots_[index].bytes)));
  }
  // The slot that holds `object`; CHECK-fails for a pointer the pool did not hand out.
  [[nodiscard]] std::size_t index_of(const T* object) const {
    const void* first = slots_.data();
    const void* last = slots_.data() + slots_.size();
    const void* candidate = object;
    // std::less gives a total order over pointers, also for ones outside the array.
    BLOCKMAP_CHECK_MSG(
        !std::less<const void*>{}(candidate, first) && std::less<const void*>{}(candidate, last),
        "pointer released to a pool that did not create it");
    const auto offset = static_cast<std::size_t>(static_cast<const std::byte*>(candidate) -
                                                 static_cast<const std::byte*>(first));
    BLOCKMAP_CHECK_MSG(offset % sizeof(PoolSlot<T>) == 0, "pointer into the middle of a pool slot");
    return offset / sizeof(PoolSlot<T>);
  }

  std::span<PoolSlot<T>> slots_;
  std::span<SlotIndex> free_stack_;
  std::span<bool> in_use_;
  std::size_t free_count_ = 0;
  MonotonicCounter exhausted_;
};

namespace detail {
template <typename T, std::size_t N>
struct PoolStorage {
  InlineStorage<PoolSlot<T>, N> object_storage;
  InlineStorage<std::size_t, N> free_stack_storage;
  InlineStorage<bool, N> in_use_storage;
};
}  // namespace detail

template <typename T, std::size_t N>
class FixedPool : private detail::PoolStorage<T, N>, public FixedPoolRef<T> {
  static_assert(N > 0, "a pool needs a capacity of at least one");

 public:
  FixedPool()
      : detail::PoolStorage<T, N>(),
        FixedPoolRef<T>(std::span<PoolSlot<T>>(this->object_storage.slots),
                        std::span<std::size_t>(this->free_stack_storage.slots),
                        std::span<bool>(this->in_use_storage.slots)) {}
};

}  // namespace blockmap
