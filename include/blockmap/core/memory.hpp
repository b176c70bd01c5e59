// Memory reporting: every owner of a buffer can say how many bytes it holds.
#pragma once

#include <concepts>
#include <cstddef>

namespace blockmap {

// An owner reports the bytes of the storage it was given at init (element storage plus its own
// bookkeeping). The numbers are fixed after init: nothing grows in the steady state.
template <typename T>
concept ReportsMemory = requires(const T& owner) {
  { owner.memory_bytes() } -> std::convertible_to<std::size_t>;
};

inline constexpr std::size_t kCacheLineBytes = 64;

}  // namespace blockmap
