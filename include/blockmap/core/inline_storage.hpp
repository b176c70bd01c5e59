// Storage for the containers whose capacity is part of their type (RingBuffer<T, N>,
// SpscQueue<T, N>, FixedPool<T, N>). It is a base class listed before the size-erased view, so
// it is constructed first and the view never points at storage that does not exist yet.
#pragma once

#include <array>
#include <cstddef>

namespace blockmap::detail {

template <typename T, std::size_t N>
struct InlineStorage {
  std::array<T, N> slots{};
};

}  // namespace blockmap::detail
