#include "blockmap/planes/cell_index.hpp"

#include <algorithm>
#include <bit>

#include "blockmap/core/check.hpp"
#include "blockmap/core/linear_probing.hpp"

namespace blockmap::planes {

void CellIndex::init(Arena& arena, std::size_t max_keys, const char* owner) {
  BLOCKMAP_CHECK_MSG(max_keys > 0, "cell index needs a capacity");
  const std::size_t slots = half_full_slots(max_keys);
  shift_ = 64u - static_cast<std::uint32_t>(std::countr_zero(slots));
  mask_ = slots - 1;
  slots_ = arena.allocate_array<Slot>(slots, owner);
  max_keys_ = max_keys;
  clear();
}

void CellIndex::clear() noexcept {
  std::fill(slots_.begin(), slots_.end(), Slot{});
  size_ = 0;
}

bool CellIndex::find_or_insert(CellKey key, std::uint32_t value, std::uint32_t& found) noexcept {
  Slot& slot = slots_[probe(
      home_slot(key), mask_, [this](std::size_t at) { return slots_[at].value == kAbsent; },
      [this, key](std::size_t at) { return slots_[at].key == key; })];
  if (slot.value == kAbsent) {
    if (size_ == max_keys_) {
      return false;
    }
    slot = Slot{key, value};
    ++size_;
  }
  found = slot.value;
  return true;
}

void CellIndex::erase(CellKey key) noexcept {
  const std::size_t slot = probe(
      home_slot(key), mask_, [this](std::size_t at) { return slots_[at].value == kAbsent; },
      [this, key](std::size_t at) { return slots_[at].key == key; });
  if (slots_[slot].value == kAbsent) {
    return;
  }
  erase_shifting_back(
      slot, mask_, [this](std::size_t at) { return slots_[at].value != kAbsent; },
      [this](std::size_t at) { return home_slot(slots_[at].key); },
      [this](std::size_t from, std::size_t to) { slots_[to] = slots_[from]; },
      [this](std::size_t at) { slots_[at] = Slot{}; });
  --size_;
}

std::size_t CellIndex::arena_bytes(std::size_t max_keys) noexcept {
  return Arena::array_bytes<Slot>(half_full_slots(max_keys));
}

}  // namespace blockmap::planes
