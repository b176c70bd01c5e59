// Open-addressing tables with linear probing (power-of-two size): the lookup, and deletion
// without tombstones by the backward shift. Every later entry of the hole's run whose home slot
// does not lie cyclically between the hole and itself moves into the hole, so a lookup never meets
// a gap before its key and the table stays as if the deleted key had never been inserted.
#pragma once

#include <algorithm>
#include <bit>
#include <cstddef>

namespace blockmap {

// Where a lookup that starts at `home` stops: the slot whose entry holds(slot) the key, or the
// first empty(slot) of the run, where an insert puts it. mask: table size - 1. The table is
// never full, so the walk ends.
template <typename Empty, typename Holds>
[[nodiscard]] std::size_t probe(std::size_t home, std::size_t mask, Empty&& empty, Holds&& holds) {
  std::size_t slot = home;
  while (!empty(slot) && !holds(slot)) {
    slot = (slot + 1) & mask;
  }
  return slot;
}

// The slots of a table that stays at most half full with `max_keys` (short probe runs), and
// at least `min_slots`.
[[nodiscard]] constexpr std::size_t half_full_slots(std::size_t max_keys,
                                                    std::size_t min_slots = 64) noexcept {
  return std::bit_ceil(std::max(2 * max_keys, min_slots));
}

// hole: the slot of the deleted entry. mask: table size - 1. occupied(slot) and
// home_of(slot) read the table; move(from, to) moves an entry (and whatever goes with its
// slot); clear(slot) empties the last hole.
template <typename Occupied, typename HomeOf, typename Move, typename Clear>
void erase_shifting_back(std::size_t hole, std::size_t mask, Occupied&& occupied, HomeOf&& home_of,
                         Move&& move, Clear&& clear) {
  for (std::size_t at = (hole + 1) & mask; occupied(at); at = (at + 1) & mask) {
    const std::size_t home = home_of(at);
    const bool stays = hole <= at ? (hole < home && home <= at) : (hole < home || home <= at);
    if (!stays) {
      move(at, hole);
      hole = at;
    }
  }
  clear(hole);
}

}  // namespace blockmap
