// Arena: serves every init-time allocation of the runtime from one block, against a budget.
//
// Start-up sequence: construct the Arena with the configured budget (the one heap allocation,
// or a caller-supplied static buffer), let every component take its buffers from it in init(),
// then seal() it. After seal() the arena refuses to allocate (a CHECK failure): the steady
// state allocates nothing, and the ledger of owners is the runtime's memory report.
//
// Objects placed in the arena are never destroyed by it, so only trivially destructible types
// may live there (element storage of rings, queues, pools, grids).
#pragma once

#include <array>
#include <cstddef>
#include <memory>
#include <new>
#include <span>
#include <type_traits>

#include "blockmap/core/check.hpp"
#include "blockmap/core/counter.hpp"

namespace blockmap {

class Arena {
 public:
  // One line of the memory report: an owner's name and the bytes it took (padding included).
  struct OwnerBytes {
    const char* owner = nullptr;
    std::size_t bytes = 0;
  };
  // What one allocation may take beyond its bytes to align them (no type here is aligned to
  // more): a size computed before init adds this per allocation.
  static constexpr std::size_t kMaxPaddingBytes = 64;
  // The bytes allocate_array<T>(count) takes at most.
  template <typename T>
  [[nodiscard]] static constexpr std::size_t array_bytes(std::size_t count) noexcept {
    return count * sizeof(T) + kMaxPaddingBytes;
  }
  // Owners beyond this many are summed into the last line, named "(other owners)".
  static constexpr std::size_t kMaxOwners = 48;

  // Takes budget_bytes from the heap, once. budget_bytes > 0.
  explicit Arena(std::size_t budget_bytes);
  // Serves from caller-owned storage (for example a static buffer on a microcontroller-like
  // target); the storage must outlive the arena.
  explicit Arena(std::span<std::byte> storage);

  Arena(const Arena&) = delete;
  Arena& operator=(const Arena&) = delete;
  ~Arena() = default;

  // Returns `bytes` aligned to `alignment` (a power of two), charged to `owner` (a string
  // literal or other storage that outlives the arena), or nullptr when the budget cannot
  // cover it; a refusal is counted in failed_allocations(). CHECK-fails when sealed.
  [[nodiscard]] void* try_allocate(std::size_t bytes, std::size_t alignment, const char* owner);

  // As try_allocate, but running over the budget is a CHECK failure: budgets are set so that
  // init succeeds, and a configuration that does not fit must stop the program before it runs.
  [[nodiscard]] void* allocate(std::size_t bytes, std::size_t alignment, const char* owner);

  // `count` value-initialised elements of T.
  template <typename T>
  [[nodiscard]] std::span<T> allocate_array(std::size_t count, const char* owner) {
    static_assert(std::is_trivially_destructible_v<T>,
                  "the arena never runs destructors: store trivially destructible types only");
    BLOCKMAP_CHECK_MSG(count <= budget_bytes_ / (sizeof(T) == 0 ? 1 : sizeof(T)),
                       "arena array larger than the whole budget");
    void* memory = allocate(count * sizeof(T), alignof(T), owner);
    T* first = static_cast<T*>(memory);
    for (std::size_t i = 0; i < count; ++i) {
      ::new (static_cast<void*>(first + i)) T();
    }
    return std::span<T>(first, count);
  }

  // Ends init: from here on every allocation attempt is a CHECK failure.
  void seal() noexcept { sealed_ = true; }
  [[nodiscard]] bool sealed() const noexcept { return sealed_; }

  [[nodiscard]] std::size_t budget_bytes() const noexcept { return budget_bytes_; }
  [[nodiscard]] std::size_t used_bytes() const noexcept { return used_bytes_; }
  [[nodiscard]] std::size_t remaining_bytes() const noexcept { return budget_bytes_ - used_bytes_; }
  [[nodiscard]] const MonotonicCounter& failed_allocations() const noexcept { return failed_; }

  // The memory report: owners in order of their first allocation.
  [[nodiscard]] std::span<const OwnerBytes> owners() const noexcept {
    return {ledger_.data(), owner_count_};
  }

  // The block it serves plus its own bookkeeping.
  [[nodiscard]] std::size_t memory_bytes() const noexcept { return budget_bytes_ + sizeof(*this); }

 private:
  struct HeapBlockDeleter {
    std::align_val_t alignment;  // as the block was allocated
    void operator()(std::byte* block) const noexcept;
  };

  void charge(const char* owner, std::size_t bytes) noexcept;

  std::unique_ptr<std::byte, HeapBlockDeleter> heap_block_;  // null when serving caller storage
  std::byte* base_ = nullptr;
  std::size_t budget_bytes_ = 0;
  std::size_t used_bytes_ = 0;
  bool sealed_ = false;
  std::array<OwnerBytes, kMaxOwners> ledger_{};
  std::size_t owner_count_ = 0;
  MonotonicCounter failed_;
};

}  // namespace blockmap
