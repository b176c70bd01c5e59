// The simulator's random numbers: the core's Random, one stream per noise source (seeded from
// the run's seed and the source's name).
#pragma once

#include <random>

#include "blockmap/core/random.hpp"

namespace blockmap::hal::sim {

using SimRandom = Random;

// A uniform double in [0, 1) from a minstd engine, the same on every platform: the fault
// injectors (the loopback CAN bus, the scripted byte stream) draw their drops from one.
[[nodiscard]] inline double uniform_unit(std::minstd_rand& random) noexcept {
  return static_cast<double>(random() - std::minstd_rand::min()) /
         (static_cast<double>(std::minstd_rand::max() - std::minstd_rand::min()) + 1.0);
}

}  // namespace blockmap::hal::sim
