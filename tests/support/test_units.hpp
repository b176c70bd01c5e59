// Units the tests write their numbers in, one definition for every test program (unity builds
// put several test files in one translation unit, where two definitions would clash).
#pragma once

#include <numbers>

#include "blockmap/core/time.hpp"

namespace blockmap::testing {

inline constexpr TimestampNs kMs = 1'000'000;
inline constexpr double kDeg = std::numbers::pi / 180.0;

}  // namespace blockmap::testing
