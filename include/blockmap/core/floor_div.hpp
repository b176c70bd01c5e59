// Integer division that rounds towards minus infinity, and the remainder that goes with it:
// grid cells and ring slots of negative coordinates (west or south of the local frame's
// origin) must be numbered like the positive ones, which C++'s truncating `/` and `%` do not.
#pragma once

#include <cstdint>

namespace blockmap {

[[nodiscard]] constexpr std::int64_t floor_div(std::int64_t value, std::int64_t divisor) noexcept {
  const std::int64_t quotient = value / divisor;
  return (value % divisor != 0 && (value < 0) != (divisor < 0)) ? quotient - 1 : quotient;
}

// In [0, divisor) for a positive divisor.
[[nodiscard]] constexpr std::int64_t floor_mod(std::int64_t value, std::int64_t divisor) noexcept {
  return value - floor_div(value, divisor) * divisor;
}

static_assert(floor_div(-1, 32) == -1 && floor_div(31, 32) == 0 && floor_mod(-1, 32) == 31);

}  // namespace blockmap
