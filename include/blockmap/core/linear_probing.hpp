// Deletion from an open-addressing table with linear probing (power-of-two size), without
// tombstones: the backward shift. Every later entry of the hole's run whose home slot does not
// lie cyclically between the hole and itself moves into the hole, so a lookup never meets a
// gap before its key and the table stays as if the deleted key had never been inserted.
#pragma once

#include <cstddef>

namespace blockmap {

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
