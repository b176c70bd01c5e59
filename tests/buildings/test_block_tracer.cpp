// Blocks traced from free space (BlockTracer through BuildingFitter): a block the robot drove
// around is one footprint, its unseen sides closed where beams stopped, and a map::
// FreeSpaceGrid marks free what beams crossed and nothing else.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "blockmap/buildings/building_fitter.hpp"
#include "blockmap/core/arena.hpp"
#include "blockmap/map/free_space_grid.hpp"
#include "blockmap/planes/polygon.hpp"
#include "footprint_score.hpp"
#include "synthetic_walls.hpp"

namespace blockmap::buildings {
namespace {

using Eigen::Vector2d;

constexpr double kCellM = 0.5;
constexpr std::uint32_t kAcross = 256;  // 128 m
const Vector2d kOrigin(-30.0, -40.0);

// A block with a step on its north side: 80 m x 20 m, its western 30 m 10 m deeper.
std::vector<Vector2d> stepped_block() {
  return testing::placed({{0, 0}, {80, 0}, {80, 20}, {30, 20}, {30, 30}, {0, 30}}, 15.0,
                         Vector2d(5.0, -5.0));
}

// What a robot driving round `block` at about 12 m sees through: the ground within ring_m of
// the block, outside it, is free; the block and everything beyond the ring are not. A tree
// stands in the street (an island), and another against the block's south side.
std::vector<std::uint8_t> ringed_raster(const std::vector<Vector2d>& block, double ring_m,
                                        bool open_channel = false) {
  std::vector<std::uint8_t> free(std::size_t{kAcross} * kAcross, 0);
  const std::vector<Vector2d> tree_by_block =
      testing::placed({{40, -2.5}, {43, -2.5}, {43, 0.5}, {40, 0.5}}, 15.0, Vector2d(5.0, -5.0));
  const Vector2d tree_in_street = testing::placed({{55, -8}}, 15.0, Vector2d(5.0, -5.0))[0];
  for (std::uint32_t y = 0; y < kAcross; ++y) {
    for (std::uint32_t x = 0; x < kAcross; ++x) {
      const Vector2d p = kOrigin + kCellM * Vector2d(x + 0.5, y + 0.5);
      double distance_m = std::numeric_limits<double>::infinity();
      for (std::size_t k = 0; k < block.size(); ++k) {
        distance_m = std::min(
            distance_m, planes::point_segment_distance(p, block[k], block[(k + 1) % block.size()]));
      }
      const bool inside = planes::inside_polygon(p, block);
      bool seen = !inside && distance_m <= ring_m;
      seen = seen && !planes::inside_polygon(p, tree_by_block) && (p - tree_in_street).norm() > 1.5;
      // A passage no beam went down, from the block out to unseen ground.
      const Vector2d local = testing::placed({p}, -15.0, Vector2d::Zero())[0];
      seen = seen && !(open_channel && std::abs(local.y() - 14.0) < 2.0 && local.x() > 70.0);
      free[std::size_t{y} * kAcross + x] = seen ? 1 : 0;
    }
  }
  return free;
}

class BlockTracerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    fitter_.init(arena_, config_, std::size_t{kAcross} * kAcross);
    arena_.seal();
  }

  std::span<const Building> fit(const std::vector<msg::PlanePatch>& planes,
                                const std::vector<std::uint8_t>& free) {
    fitter_.begin();
    fitter_.set_free_space({kOrigin, kCellM, kAcross, free});
    for (const msg::PlanePatch& plane : planes) {
      fitter_.add(plane);
    }
    return fitter_.finish();
  }

  BuildingsConfig config_;
  Arena arena_{BuildingFitter::arena_bytes(BuildingsConfig{}, std::size_t{kAcross} * kAcross)};
  BuildingFitter fitter_;
};

TEST_F(BlockTracerTest, ABlockRingedBySeenGroundIsOneFootprintWithItsStep) {
  const std::vector<Vector2d> block = stepped_block();
  const std::vector<msg::PlanePatch> all = testing::walls_around(block, 12.0);
  // Seen: the south side in two pieces (the tree), the west end and the step's north sides;
  // the east end and the step's short side were behind trees.
  std::vector<msg::PlanePatch> seen{all[5], all[2], all[4]};
  const Vector2d south_mid = block[0] + 0.45 * (block[1] - block[0]);
  const Vector2d south_on = block[0] + 0.55 * (block[1] - block[0]);
  seen.push_back(testing::vertical_plane(block[0], south_mid, 0.0, 12.0, 11));
  seen.push_back(testing::vertical_plane(south_on, block[1], 0.0, 12.0, 12));
  const std::span<const Building> buildings = fit(seen, ringed_raster(block, 12.0));
  ASSERT_EQ(buildings.size(), 1u) << "the walls' own building is the block's part";
  const Building& traced = buildings[0];
  EXPECT_EQ(traced.shape, BuildingShape::kL);
  ASSERT_EQ(traced.footprint_size, 6u);
  const double iou =
      testing::footprint_iou({traced.footprint_m.data(), traced.footprint_size}, block, 0.1);
  EXPECT_GT(iou, 0.97);
  // The east end and the step's short side are virtual, the rest observed.
  double virtual_m = 0.0;
  double observed_m = 0.0;
  for (std::size_t w = 0; w < traced.wall_count; ++w) {
    const double length_m = (traced.walls[w].p1_m - traced.walls[w].p0_m).norm();
    (traced.walls[w].is_virtual ? virtual_m : observed_m) += length_m;
  }
  EXPECT_NEAR(virtual_m, 20.0 + 10.0 + 8.0, 3.0) << "east end, step, the gap behind the tree";
  EXPECT_NEAR(observed_m, 80.0 + 30.0 + 50.0 + 30.0 - 8.0, 3.0);
  EXPECT_NEAR(traced.height_m, 12.0, 0.5);
}

TEST_F(BlockTracerTest, GroundOpenToUnseenGroundIsNoBlock) {
  const std::vector<Vector2d> block = stepped_block();
  const std::vector<msg::PlanePatch> all = testing::walls_around(block, 12.0);
  const std::span<const Building> buildings =
      fit(all, ringed_raster(block, 12.0, /*open_channel=*/true));
  // The walls make their own building, as without free space.
  ASSERT_EQ(buildings.size(), 1u);
  EXPECT_EQ(buildings[0].shape, BuildingShape::kL);
  BlockTracer tracer;
  Arena arena(BlockTracer::arena_bytes(config_, std::size_t{kAcross} * kAcross));
  tracer.init(arena, config_, std::size_t{kAcross} * kAcross);
  const std::vector<std::uint8_t> open = ringed_raster(block, 12.0, true);
  EXPECT_TRUE(tracer.find_blocks({kOrigin, kCellM, kAcross, open}).empty());
  const std::vector<std::uint8_t> closed = ringed_raster(block, 12.0, false);
  ASSERT_EQ(tracer.find_blocks({kOrigin, kCellM, kAcross, closed}).size(), 1u)
      << "the tree in the street is too small to be a block";
}

TEST_F(BlockTracerTest, AModelBoxOverGroundBeamsCrossedKeepsOnlyItsSeenWalls) {
  // A fence's corner in the street: two walls the fitter closes into a box, over ground the
  // robot saw through. The box is contradicted; the fence's walls stay.
  const std::vector<Vector2d> block = stepped_block();
  const std::vector<Vector2d> fence =
      testing::placed({{58, -10}, {66, -10}, {66, -4}}, 15.0, Vector2d(5.0, -5.0));
  std::vector<msg::PlanePatch> planes = testing::walls_around(block, 12.0);
  planes.push_back(testing::vertical_plane(fence[0], fence[1], 0.0, 2.5, 21));
  planes.push_back(testing::vertical_plane(fence[1], fence[2], 0.0, 2.5, 22));
  // Without the free space the fence is a box of its own.
  fitter_.begin();
  for (const msg::PlanePatch& plane : planes) {
    fitter_.add(plane);
  }
  std::span<const Building> buildings = fitter_.finish();
  ASSERT_EQ(buildings.size(), 2u);
  EXPECT_EQ(buildings[1].shape, BuildingShape::kRect);

  buildings = fit(planes, ringed_raster(block, 12.0));
  ASSERT_EQ(buildings.size(), 2u);
  const Building* box = &buildings[0];
  const Building* traced = &buildings[1];
  if (box->footprint_size > 0) {
    std::swap(box, traced);
  }
  EXPECT_EQ(traced->shape, BuildingShape::kL);
  EXPECT_EQ(box->shape, BuildingShape::kUnknown);
  EXPECT_EQ(box->footprint_size, 0u);
  ASSERT_EQ(box->wall_count, 2u);
  EXPECT_FALSE(box->walls[0].is_virtual);
  EXPECT_FALSE(box->walls[1].is_virtual);
  EXPECT_EQ(fitter_.counters().buildings_seen_through, 1u);
}

TEST_F(BlockTracerTest, UnseenGroundWithoutWallsIsNoBuilding) {
  // A park the robot drove round: nothing seen into it, and no wall along it.
  const std::vector<Vector2d> park = stepped_block();
  EXPECT_TRUE(fit({}, ringed_raster(park, 12.0)).empty());
}

TEST(FreeSpaceGrid, ABeamFreesTheCellsItCrossesUpToShortOfItsReturn) {
  map::FreeSpaceConfig config;
  config.tiles_across = 2;  // 32 m
  Arena arena(map::FreeSpaceGrid::arena_bytes(config));
  map::FreeSpaceGrid grid;
  grid.init(arena, config);
  const Vector2d from(0.25, 0.25);
  const Vector2d to(10.25, 0.25);
  grid.add_beam(from, to);
  map::FreeSpaceRaster raster = grid.raster();
  EXPECT_EQ(raster.free[0], 0) << "one beam is not enough";
  grid.add_beam(from, to);
  raster = grid.raster();
  ASSERT_EQ(raster.cells_across, 64u);
  ASSERT_EQ(raster.origin_m, Vector2d(0.0, 0.0));
  // 10 m less 0.75 m: cells 0-18 (0 to 9.5 m); the return's cell 20 is not free.
  for (std::size_t x = 0; x <= 18; ++x) {
    EXPECT_EQ(raster.free[x], 1) << x;
  }
  EXPECT_EQ(raster.free[19], 0);
  EXPECT_EQ(raster.free[20], 0);
  EXPECT_EQ(raster.free[64], 0) << "the row above was not crossed";
  // Returns outnumbering passes keep a cell occupied (a hedge a few beams got through).
  for (int k = 0; k < 2; ++k) {
    grid.add_beam(Vector2d(0.25, 0.25), Vector2d(5.25, 0.25));
  }
  raster = grid.raster();
  EXPECT_EQ(raster.free[10], 0) << "cell 10 ended two beams and two crossed it";
  EXPECT_EQ(raster.free[9], 1);
  // A diagonal beam crosses the cells of a grid walk, each once.
  const std::uint64_t before = grid.counters().cells_crossed;
  grid.add_beam(Vector2d(0.25, 2.25), Vector2d(8.25, 10.25));
  const std::uint64_t crossed = grid.counters().cells_crossed - before;
  EXPECT_GE(crossed, 29u);  // about 2 x 15.5 cells of x and y steps to 10.5 m
  EXPECT_LE(crossed, 33u);
}

TEST(FreeSpaceGrid, FarGroundTakesTheSlotOfTheGroundLeftBehind) {
  map::FreeSpaceConfig config;
  config.tiles_across = 2;
  Arena arena(map::FreeSpaceGrid::arena_bytes(config));
  map::FreeSpaceGrid grid;
  grid.init(arena, config);
  for (int k = 0; k < 2; ++k) {
    grid.add_beam(Vector2d(1.0, 1.0), Vector2d(9.0, 1.0));
  }
  EXPECT_EQ(grid.counters().tiles_recycled, 0u);
  // 1 km east: the same slots, other ground.
  for (int k = 0; k < 2; ++k) {
    grid.add_beam(Vector2d(1001.0, 1.0), Vector2d(1009.0, 1.0));
  }
  EXPECT_GE(grid.counters().tiles_recycled, 1u);
  const map::FreeSpaceRaster raster = grid.raster();
  EXPECT_NEAR(raster.origin_m.x(), 992.0, 1e-9) << "the ring around the last beam";
  EXPECT_EQ(raster.free[2 * 64 + 20], 1) << "1002 m east, 1 m north";
  EXPECT_GT(grid.memory_bytes(), 2u * 64u * 64u);
}

}  // namespace
}  // namespace blockmap::buildings
