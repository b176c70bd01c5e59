// The mapper's steady state allocates nothing: ten seconds of the simulated robot's messages
// (odometry, GPS fixes, scans of both lasers) through the whole pipeline, extractions, window
// scrolling and the end of the run included. The default capacities fit the 64 MiB budget.
#include <gtest/gtest.h>

#include <memory>

#include "blockmap/core/arena.hpp"
#include "blockmap/hal/sim/simulated_robot.hpp"
#include "blockmap/hal/sim/world.hpp"
#include "blockmap/pipeline/mapper.hpp"
#include "memory_assertions.hpp"
#include "recorded_mapper_inputs.hpp"

namespace blockmap::pipeline {
namespace {

TEST(MapperBudget, TheDefaultCapacitiesFitSixtyFourMebibytes) {
  const MapperConfig config = hal::sim::mapper_config_for(hal::sim::load_robot("paper_rmp"));
  EXPECT_EQ(validate(config), "");
  EXPECT_LE(Mapper::arena_bytes(config), std::size_t{64} << 20);
  Arena arena(Mapper::arena_bytes(config));
  auto mapper = std::make_unique<Mapper>();
  mapper->init(arena, config);
  EXPECT_LE(arena.used_bytes(), arena.budget_bytes());
  // Every owner is in the report.
  std::size_t reported = 0;
  for (const Arena::OwnerBytes& owner : arena.owners()) {
    reported += owner.bytes;
  }
  EXPECT_EQ(reported, arena.used_bytes());
}

TEST(MapperBudget, MappingAllocatesNothing) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  const double duration_s = 6.0;
#else
  const double duration_s = 15.0;
#endif
  const testing::RecordedMapperInputs inputs("usc_block", duration_s);
  ASSERT_TRUE(inputs.started);
  ASSERT_GT(inputs.scans.size(), 500u);
  Arena arena(Mapper::arena_bytes(inputs.config));
  auto mapper = std::make_unique<Mapper>();
  mapper->init(arena, inputs.config);
  arena.seal();
  const auto map_everything = [&] { inputs.feed(*mapper); };
  EXPECT_NO_ALLOCATIONS(map_everything());
  EXPECT_GT(mapper->counters().extractions, 3u);
  EXPECT_GT(mapper->final_planes().size(), 0u);
  EXPECT_EQ(mapper->counters().scans_refused_full, 0u);
}

// With the free-space grid on (the blocks a robot drives around are traced in it): every
// level beam walks the grid, and every refit of the buildings traces its raster, all in
// memory taken at init.
TEST(MapperBudget, CarvingFreeSpaceAndTracingBlocksAllocatesNothing) {
  const testing::RecordedMapperInputs inputs("usc_block", 6.0);
  ASSERT_TRUE(inputs.started);
  MapperConfig config = inputs.config;
  config.free_space.tiles_across = 8;
  Arena arena(Mapper::arena_bytes(config));
  auto mapper = std::make_unique<Mapper>();
  mapper->init(arena, config);
  arena.seal();
  const auto map_everything = [&] { inputs.feed(*mapper); };
  EXPECT_NO_ALLOCATIONS(map_everything());
  EXPECT_GT(mapper->free_space().counters().beams, 20000u);
  EXPECT_GT(mapper->free_space().counters().cells_crossed, mapper->free_space().counters().beams);
  EXPECT_GT(mapper->building_fitter().counters().fits, 3u);
}

}  // namespace
}  // namespace blockmap::pipeline
