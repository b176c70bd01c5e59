// A part of the pipeline on an arena of its own, sized by the part's arena_bytes and sealed
// after init as the mapper seals its arena: a test then sees any allocation after start-up.
#pragma once

#include "blockmap/core/arena.hpp"

namespace blockmap::testing {

template <typename Part>
struct OnOwnArena {
  template <typename Config>
  explicit OnOwnArena(const Config& config) : arena(Part::arena_bytes(config)) {
    part.init(arena, config);
    arena.seal();
  }
  Arena arena;
  Part part;
};

}  // namespace blockmap::testing
