// Merging a few new entries into a long sorted array without a second array: the new ones
// are sorted at the array's far end and merged in from the back. The voxel grid's block order
// and the section grid's block list change by a few entries between two extractions, and a
// sort of every entry cost more than everything else they did.
#pragma once

#include <cstddef>
#include <span>

#include "blockmap/core/check.hpp"

namespace blockmap {

// The first `front` entries of `array` and its last `back` entries are each sorted by `less`;
// afterwards its first front + back entries are all of them, sorted (an entry of the front
// comes first among equals). Writing from the back, an entry lands at or after the position
// front + back - 1 of the next one read, so the back entries are all read before they are
// written over when front + 2 back <= the array's size (the caller sorts afresh otherwise; a
// CHECK refuses less room).
template <typename T, typename Less>
void merge_back_into_front(std::span<T> array, std::size_t front, std::size_t back, Less less) {
  BLOCKMAP_CHECK_MSG(front + 2 * back <= array.size(), "no room to merge in place");
  const std::size_t first_back = array.size() - back;
  std::size_t out = front + back;
  std::size_t a = front;  // front entries left, from the back
  std::size_t b = back;   // back entries left
  while (b > 0) {
    const T next_back = array[first_back + b - 1];
    if (a > 0 && less(next_back, array[a - 1])) {
      array[--out] = array[--a];
    } else {
      array[--out] = next_back;
      --b;
    }
  }
}

}  // namespace blockmap
