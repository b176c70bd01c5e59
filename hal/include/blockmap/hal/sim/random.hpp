// The simulator's random numbers: the core's Random, one stream per noise source (seeded from
// the run's seed and the source's name).
#pragma once

#include "blockmap/core/random.hpp"

namespace blockmap::hal::sim {

using SimRandom = Random;

}  // namespace blockmap::hal::sim
