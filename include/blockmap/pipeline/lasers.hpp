// How many lasers one mapper takes: every per-laser table of the pipeline has this many slots.
#pragma once

#include <cstddef>

namespace blockmap::pipeline {

inline constexpr std::size_t kMaxLasers = 4;

}  // namespace blockmap::pipeline
