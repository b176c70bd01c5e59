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

// A mapper whose arena is sealed after init, fed every recorded message: the steady state, which
// must allocate nothing. The arena outlives the mapper, so the caller holds it.
std::unique_ptr<Mapper> map_with_the_arena_sealed(Arena& arena, const MapperConfig& config,
                                                  const testing::RecordedMapperInputs& inputs) {
  auto mapper = std::make_unique<Mapper>();
  mapper->init(arena, config);
  arena.seal();
  const auto map_everything = [&] { inputs.feed(*mapper); };
  EXPECT_NO_ALLOCATIONS(map_everything());
  return mapper;
}

TEST(MapperBudget, TheDefaultCapacitiesFitSixtyFourMebibytes) {
  // Both robots: the paper's two LMS291 and the modern variant's two TiM571 (longer scans, a
  // larger scan queue), which the daemon maps from with no --budget-mib.
  for (const char* robot : {"paper_rmp", "rmp_tim"}) {
    SCOPED_TRACE(robot);
    const MapperConfig config = hal::config::mapper_config_for(hal::config::load_robot(robot));
    EXPECT_EQ(validate(config), "");
    EXPECT_LE(Mapper::arena_bytes(config), std::size_t{64} << 20);
    Arena arena(Mapper::arena_bytes(config));
    auto mapper = std::make_unique<Mapper>();
    mapper->init(arena, config);
    EXPECT_LE(arena.used_bytes(), arena.budget_bytes());
    EXPECT_LE(arena.used_bytes(), std::size_t{64} << 20);
    // Every owner is in the report.
    std::size_t reported = 0;
    for (const Arena::OwnerBytes& owner : arena.owners()) {
      reported += owner.bytes;
    }
    EXPECT_EQ(reported, arena.used_bytes());
  }
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
  const auto mapper = map_with_the_arena_sealed(arena, inputs.config, inputs);
  EXPECT_GT(mapper->counters().extractions, 3u);
  EXPECT_GT(mapper->final_planes().size(), 0u);
  EXPECT_EQ(mapper->counters().scans_refused_full, 0u);
}

// A window reaching beyond its core whose pool is too small for the whole ring: tiles leave
// early and take no points while closed, all within what init() took.
TEST(MapperBudget, TilesLeavingEarlyForRoomAllocateNothing) {
  const testing::RecordedMapperInputs inputs("usc_block", 8.0);
  ASSERT_TRUE(inputs.started);
  MapperConfig config = inputs.config;
  config.window.tiles_across = 11;
  config.window.core_tiles_across = 3;
  config.window.max_samples = 8192;
  config.window.reserve_samples = 1024;
  config.projection.max_range_m = 60.0;
  EXPECT_EQ(validate(config), "");
  Arena arena(Mapper::arena_bytes(config));
  const auto mapper = map_with_the_arena_sealed(arena, config, inputs);
  EXPECT_GT(mapper->window().counters().tiles_left_early, 0u);
  EXPECT_GT(mapper->counters().extractions, 3u);
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
  const auto mapper = map_with_the_arena_sealed(arena, config, inputs);
  EXPECT_GT(mapper->free_space().counters().beams, 20000u);
  EXPECT_GT(mapper->free_space().counters().cells_crossed, mapper->free_space().counters().beams);
  EXPECT_GT(mapper->building_fitter().counters().fits, 3u);
}

// With the rigid path (localize::PathSmoother fed by every matched scan and fix, solved every
// 10 s, and the final planes moved at the end): its keyframes and normal equations are taken at
// init, and the default budget still holds them.
TEST(MapperBudget, TheRigidPathAllocatesNothingAndFitsTheBudget) {
  const testing::RecordedMapperInputs inputs("usc_block", 12.0);
  ASSERT_TRUE(inputs.started);
  MapperConfig config = inputs.config;
  config.rigid_path = pipeline::RigidPath::kOn;
  EXPECT_EQ(validate(config), "");
  EXPECT_LE(Mapper::arena_bytes(config), std::size_t{64} << 20);
  Arena arena(Mapper::arena_bytes(config));
  const auto mapper = map_with_the_arena_sealed(arena, config, inputs);
  EXPECT_GT(mapper->rigid_path().keyframe_count(), 20u);
  EXPECT_GT(mapper->rigid_path().counters().solves, 1u);
  EXPECT_GT(mapper->rigid_path_counters().planes_moved, 0u);
}

// When the path is solved: by default wherever the level scans are matched and no free-space
// grid is kept (it is not moved with the walls); asked for where it cannot run, refused.
TEST(MapperBudget, TheRigidPathRunsByDefaultWhereScansAreMatched) {
  MapperConfig config;
  ASSERT_EQ(config.rigid_path, RigidPath::kWhereScansAreMatched);
  const std::size_t without = [] {
    MapperConfig off;
    off.rigid_path = RigidPath::kOff;
    return Mapper::arena_bytes(off);
  }();
  EXPECT_GT(Mapper::arena_bytes(config), without) << "the keyframes are taken";
  MapperConfig lagged = config;
  lagged.localizer.map_pose_lag_s = 30.0;
  EXPECT_EQ(validate(lagged), "") << "a pose lag runs without it";
  MapperConfig traced = config;
  traced.free_space.tiles_across = 8;
  EXPECT_EQ(validate(traced), "") << "so does a free-space grid";
  MapperConfig true_poses = config;
  true_poses.pose_source = PoseSource::kExternal;
  EXPECT_EQ(validate(true_poses), "");
  for (MapperConfig* asked : {&lagged, &traced, &true_poses}) {
    asked->rigid_path = RigidPath::kOn;
    EXPECT_NE(validate(*asked), "") << "asked for, it is refused where it cannot run";
  }
  // Without it nothing is taken for it: the path's bytes are the difference.
  lagged.rigid_path = RigidPath::kWhereScansAreMatched;
  MapperConfig lagged_off = lagged;
  lagged_off.rigid_path = RigidPath::kOff;
  EXPECT_EQ(Mapper::arena_bytes(lagged), Mapper::arena_bytes(lagged_off));
}

// The detector's blocks follow the window: a quarter of its samples (a block each in a small
// window, up to 4,096) unless [planes] max_blocks says otherwise (the default window's 81,920
// samples get 20,480). A window grown to 15 tiles and 300,000 samples once kept 20,480, filled
// them, and its samples beyond went silently unused. Too few blocks for the window are reported,
// not hidden.
TEST(MapperBudget, TheDetectorsBlocksFollowTheWindowAndTooFewAreReported) {
  const testing::RecordedMapperInputs inputs("usc_block", 6.0);
  ASSERT_TRUE(inputs.started);
  const auto block_capacity_for = [](const MapperConfig& config) {
    Arena arena(Mapper::arena_bytes(config));
    auto mapper = std::make_unique<Mapper>();
    mapper->init(arena, config);
    return planes::block_capacity(mapper->detector().config());
  };
  MapperConfig config = inputs.config;
  EXPECT_EQ(block_capacity_for(config), config.window.max_samples / 6);
  config.window.max_samples = 160000;
  EXPECT_EQ(block_capacity_for(config), 26666u);
  config.planes.max_blocks = 3000;
  EXPECT_EQ(block_capacity_for(config), 3000u);
  // A small window's samples are scattered over more blocks: a block each, up to 4,096.
  config.planes.max_blocks = 0;
  config.window.max_samples = 4096;
  EXPECT_EQ(block_capacity_for(config), 4096u);
  config.window.max_samples = 12000;
  EXPECT_EQ(block_capacity_for(config), 4096u);

  // 200 blocks for a window that holds thousands: the counter says how many samples missed.
  config = inputs.config;
  config.planes.max_blocks = 200;
  Arena arena(Mapper::arena_bytes(config));
  auto mapper = std::make_unique<Mapper>();
  mapper->init(arena, config);
  inputs.feed(*mapper);
  EXPECT_LE(mapper->counters().peak_blocks, 200u);
  EXPECT_GT(mapper->counters().peak_samples_without_room, 1000u);
  MapperConfig roomy = inputs.config;
  Arena roomy_arena(Mapper::arena_bytes(roomy));
  auto roomy_mapper = std::make_unique<Mapper>();
  roomy_mapper->init(roomy_arena, roomy);
  inputs.feed(*roomy_mapper);
  EXPECT_EQ(roomy_mapper->counters().peak_samples_without_room, 0u);
}

}  // namespace
}  // namespace blockmap::pipeline
