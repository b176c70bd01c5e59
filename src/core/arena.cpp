#include "blockmap/core/arena.hpp"

#include <cstdint>
#include <cstring>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace blockmap {
namespace {

// The block is aligned for anything the runtime stores, including cache-line-aligned queues.
constexpr std::align_val_t kBlockAlignment{64};
// Large blocks are aligned to 2 MiB and offered to the kernel's transparent huge pages: the
// voxel table and the Hough grids are read at random, and with 4 KiB pages a lookup in a
// table of tens of MiB missed the TLB as often as the cache.
constexpr std::size_t kHugePageBytes = std::size_t{2} << 20;

std::align_val_t block_alignment(std::size_t budget_bytes) noexcept {
  return budget_bytes >= 2 * kHugePageBytes ? std::align_val_t{kHugePageBytes} : kBlockAlignment;
}

// Advice only: without huge pages (another kernel, THP off) the block works the same.
void advise_huge_pages(std::byte* block, std::size_t budget_bytes) noexcept {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  if (budget_bytes >= 2 * kHugePageBytes) {
    static_cast<void>(madvise(block, budget_bytes & ~(kHugePageBytes - 1), MADV_HUGEPAGE));
  }
#else
  static_cast<void>(block);
  static_cast<void>(budget_bytes);
#endif
}

constexpr bool is_power_of_two(std::size_t value) noexcept {
  return value != 0 && (value & (value - 1)) == 0;
}

}  // namespace

void Arena::HeapBlockDeleter::operator()(std::byte* block) const noexcept {
  ::operator delete(static_cast<void*>(block), alignment);
}

Arena::Arena(std::size_t budget_bytes)
    : heap_block_(
          static_cast<std::byte*>(::operator new(budget_bytes, block_alignment(budget_bytes))),
          HeapBlockDeleter{block_alignment(budget_bytes)}),
      base_(heap_block_.get()),
      budget_bytes_(budget_bytes) {
  BLOCKMAP_CHECK_MSG(budget_bytes > 0, "arena budget must be positive");
  advise_huge_pages(base_, budget_bytes);
}

Arena::Arena(std::span<std::byte> storage)
    : heap_block_(nullptr, HeapBlockDeleter{kBlockAlignment}),
      base_(storage.data()),
      budget_bytes_(storage.size()) {
  BLOCKMAP_CHECK_MSG(!storage.empty(), "arena storage must not be empty");
}

void* Arena::try_allocate(std::size_t bytes, std::size_t alignment, const char* owner) {
  BLOCKMAP_CHECK_MSG(!sealed_, "arena allocation after seal(): the steady state must not allocate");
  BLOCKMAP_CHECK_MSG(is_power_of_two(alignment), "arena alignment must be a power of two");
  BLOCKMAP_CHECK_MSG(owner != nullptr, "every arena allocation names its owner");

  const auto base_address = reinterpret_cast<std::uintptr_t>(base_);
  const std::uintptr_t unaligned = base_address + used_bytes_;
  const std::uintptr_t aligned = (unaligned + (alignment - 1)) & ~(std::uintptr_t{alignment} - 1);
  const auto padding = static_cast<std::size_t>(aligned - unaligned);
  if (padding > remaining_bytes() || bytes > remaining_bytes() - padding) {
    failed_.increment();
    return nullptr;
  }
  used_bytes_ += padding + bytes;
  charge(owner, padding + bytes);
  return base_ + (static_cast<std::size_t>(aligned - base_address));
}

void* Arena::allocate(std::size_t bytes, std::size_t alignment, const char* owner) {
  void* memory = try_allocate(bytes, alignment, owner);
  BLOCKMAP_CHECK_MSG(memory != nullptr,
                     "memory budget exceeded at init: raise the arena budget or lower a capacity");
  return memory;
}

void Arena::charge(const char* owner, std::size_t bytes) noexcept {
  for (std::size_t i = 0; i < owner_count_; ++i) {
    if (ledger_[i].owner == owner || std::strcmp(ledger_[i].owner, owner) == 0) {
      ledger_[i].bytes += bytes;
      return;
    }
  }
  if (owner_count_ < kMaxOwners) {
    ledger_[owner_count_++] = OwnerBytes{owner, bytes};
    return;
  }
  OwnerBytes& last = ledger_[kMaxOwners - 1];
  last.owner = "(other owners)";
  last.bytes += bytes;
}

}  // namespace blockmap
