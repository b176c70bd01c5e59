// The sliding window: samples keep the detector's sums, the ring scrolls with the robot, tiles
// that leave are handed over whole and their samples come back to the pool.
#include <gtest/gtest.h>

#include <limits>
#include <vector>

#include "blockmap/core/arena.hpp"
#include "blockmap/map/voxel_window.hpp"
#include "own_arena.hpp"

namespace blockmap::map {
namespace {

struct CollectingSink final : VoxelWindow::EvictionSink {
  void on_evicted(const VoxelWindow::EvictedTile& tile) noexcept override {
    tiles.push_back(tile.bounds_m);
    for (const planes::VoxelSums& sums : tile.samples) {
      points += sums.point_count;
    }
    samples += tile.samples.size();
  }
  std::vector<Eigen::AlignedBox2d> tiles;
  std::size_t samples = 0;
  std::size_t points = 0;
};

using Window = testing::OnOwnArena<VoxelWindow>;

VoxelWindowConfig small_config() {
  VoxelWindowConfig config;
  config.voxel_size_m = 0.2;
  config.tile_size_m = 3.2;
  config.tiles_across = 3;
  config.max_samples = 256;
  return config;
}

TEST(VoxelWindow, AcceptsNothingUntilPlacedThenKeepsSumsAboutTheVoxelCentre) {
  Window w(small_config());
  CollectingSink sink;
  w.part.add_point(Eigen::Vector3f(0.1f, 0.1f, 0.1f));
  EXPECT_EQ(w.part.counters().points_outside, 1u);
  w.part.recentre(Eigen::Vector2d(1.0, 1.0), sink);
  EXPECT_TRUE(sink.tiles.empty()) << "placing the window evicts nothing";
  // Two points in the voxel [0, 0.2)^3: its centre is (0.1, 0.1, 0.1).
  w.part.add_point(Eigen::Vector3f(0.05f, 0.12f, 0.1f));
  w.part.add_point(Eigen::Vector3f(0.15f, 0.08f, 0.1f));
  ASSERT_EQ(w.part.size(), 1u);
  std::size_t visited = 0;
  w.part.for_each_sample([&](const planes::VoxelSums& sums) {
    ++visited;
    EXPECT_EQ(sums.point_count, 2u);
    EXPECT_NEAR(sums.sum_m[0], 0.0f, 1e-6f);  // -0.05 + 0.05
    EXPECT_NEAR(sums.sum_m[1], 0.0f, 1e-6f);
    EXPECT_NEAR(sums.sum_outer_m2[0], 2 * 0.05f * 0.05f, 1e-7f);
    EXPECT_NEAR(sums.sum_outer_m2[1], -2 * 0.05f * 0.02f, 1e-7f);
    EXPECT_EQ(sums.key, planes::pack_cell(0, 0, 0));
  });
  EXPECT_EQ(visited, 1u);
  EXPECT_EQ(w.part.counters().points_added, 2u);
}

TEST(VoxelWindow, DropsAndCountsWhatItCannotTake) {
  Window w(small_config());
  CollectingSink sink;
  w.part.recentre(Eigen::Vector2d(0.0, 0.0), sink);
  // The window is tiles -1..1 of 3.2 m: [-3.2, 6.4) on each axis.
  w.part.add_point(Eigen::Vector3f(6.5f, 0.0f, 0.0f));
  w.part.add_point(Eigen::Vector3f(-3.3f, 0.0f, 0.0f));
  w.part.add_point(Eigen::Vector3f(std::numeric_limits<float>::quiet_NaN(), 0.0f, 0.0f));
  // Far beyond any key (a corrupt range): outside, and never converted to an integer.
  w.part.add_point(Eigen::Vector3f(0.0f, 0.0f, 1e30f));
  EXPECT_EQ(w.part.counters().points_outside, 3u);
  EXPECT_EQ(w.part.counters().points_non_finite, 1u);
  // In batches (add_points), the same.
  const std::vector<Eigen::Vector3f> odd{
      Eigen::Vector3f(-1e30f, 0.0f, 0.0f),
      Eigen::Vector3f::Constant(std::numeric_limits<float>::infinity())};
  w.part.add_points(odd);
  EXPECT_EQ(w.part.counters().points_outside, 4u);
  EXPECT_EQ(w.part.counters().points_non_finite, 2u);
  const Eigen::AlignedBox2d bounds = w.part.bounds_m();
  EXPECT_NEAR(bounds.min().x(), -3.2, 1e-9);
  EXPECT_NEAR(bounds.max().y(), 6.4, 1e-9);
  // 256 samples, then the pool is full: new voxels are dropped, known ones still count.
  for (int i = 0; i < 300; ++i) {
    const int column = i % 16;
    const int row = i / 16;
    w.part.add_point(Eigen::Vector3f(0.2f * static_cast<float>(column) + 0.1f,
                                     0.2f * static_cast<float>(row) + 0.1f, 0.1f));
  }
  EXPECT_EQ(w.part.size(), 256u);
  EXPECT_EQ(w.part.counters().points_dropped_full, 300u - 256u);
  w.part.add_point(Eigen::Vector3f(0.1f, 0.1f, 0.1f));
  EXPECT_EQ(w.part.counters().points_dropped_full, 300u - 256u);
}

TEST(VoxelWindow, ScrollsWithTheRobotAndHandsOverTheTilesItLeaves) {
  Window w(small_config());
  CollectingSink sink;
  w.part.recentre(Eigen::Vector2d(0.0, 0.0), sink);
  // Ten points in each of the nine tiles, at the tiles' centres.
  for (int tx = -1; tx <= 1; ++tx) {
    for (int ty = -1; ty <= 1; ++ty) {
      for (int k = 0; k < 10; ++k) {
        w.part.add_point(Eigen::Vector3f(3.2f * static_cast<float>(tx) + 1.6f,
                                         3.2f * static_cast<float>(ty) + 1.6f,
                                         0.2f * static_cast<float>(k) + 0.1f));
      }
    }
  }
  ASSERT_EQ(w.part.size(), 90u);
  // One tile east: the western column (three tiles) leaves, whole.
  w.part.recentre(Eigen::Vector2d(3.3, 0.0), sink);
  EXPECT_EQ(sink.tiles.size(), 3u);
  EXPECT_EQ(sink.samples, 30u);
  EXPECT_EQ(sink.points, 30u);
  for (const Eigen::AlignedBox2d& tile : sink.tiles) {
    EXPECT_NEAR(tile.min().x(), -3.2, 1e-9);
  }
  EXPECT_EQ(w.part.size(), 60u);
  // The samples that stayed are still found: more points in them make no new samples.
  w.part.add_point(Eigen::Vector3f(1.6f, 1.6f, 0.1f));
  EXPECT_EQ(w.part.size(), 60u);
  // The new eastern column takes the slots the western one left.
  w.part.add_point(Eigen::Vector3f(8.0f, 1.6f, 0.1f));
  EXPECT_EQ(w.part.size(), 61u);
  EXPECT_EQ(w.part.counters().tiles_evicted, 3u);
  // Far away: everything leaves, and the pool is whole again.
  w.part.recentre(Eigen::Vector2d(100.0, 100.0), sink);
  EXPECT_EQ(w.part.size(), 0u);
  EXPECT_EQ(sink.samples, 91u);
  for (int i = 0; i < 256; ++i) {
    const int column = i % 16;
    const int row = i / 16;
    w.part.add_point(Eigen::Vector3f(100.1f + 0.2f * static_cast<float>(column),
                                     100.1f + 0.2f * static_cast<float>(row), 0.1f));
  }
  EXPECT_EQ(w.part.size(), 256u);
  EXPECT_EQ(w.part.counters().points_dropped_full, 0u);
  EXPECT_EQ(w.part.counters().peak_samples, 256u);
}

// `count` points in distinct voxels of tile (tile_x, tile_y) of 3.2 m (16 voxels across).
std::vector<Eigen::Vector3f> points_in_tile(int tile_x, int tile_y, int count) {
  std::vector<Eigen::Vector3f> points;
  points.reserve(static_cast<std::size_t>(count));
  for (int i = 0; i < count; ++i) {
    const int column = i % 16;
    const int row = i / 16;
    points.emplace_back(
        3.2f * static_cast<float>(tile_x) + 0.1f + 0.2f * static_cast<float>(column),
        3.2f * static_cast<float>(tile_y) + 0.1f + 0.2f * static_cast<float>(row), 0.1f);
  }
  return points;
}

// A window of 5 x 5 tiles whose core is the 3 x 3 around the robot: when the pool runs low,
// the outer tile that points reached least recently leaves, whole, and takes nothing more
// until the robot comes near it.
VoxelWindowConfig config_with_core() {
  VoxelWindowConfig config = small_config();
  config.tiles_across = 5;
  config.core_tiles_across = 3;
  config.reserve_samples = 32;
  return config;
}

TEST(VoxelWindow, TilesBeyondTheCoreLeaveEarlyLeastRecentlyTouchedFirst) {
  Window w(config_with_core());
  CollectingSink sink;
  w.part.recentre(Eigen::Vector2d(1.0, 1.0), sink);  // tile (0, 0): the ring is -2..2
  w.part.add_points(points_in_tile(2, 0, 100));      // east, outer
  w.part.add_points(points_in_tile(-2, 0, 100));     // west, outer, touched later
  w.part.add_points(points_in_tile(0, 0, 40));       // the robot's own tile
  ASSERT_EQ(w.part.size(), 240u);
  w.part.make_room(sink);  // 16 free of the 32 kept: the east tile leaves
  ASSERT_EQ(sink.tiles.size(), 1u);
  EXPECT_NEAR(sink.tiles[0].min().x(), 6.4, 1e-9);
  EXPECT_EQ(sink.samples, 100u);
  EXPECT_EQ(w.part.size(), 140u);
  EXPECT_EQ(w.part.counters().tiles_left_early, 1u);
  EXPECT_EQ(w.part.counters().tiles_evicted, 1u);
  w.part.make_room(sink);  // room enough now
  EXPECT_EQ(sink.tiles.size(), 1u);
  // The east tile is closed: its points are counted and dropped, the others still taken.
  w.part.add_points(points_in_tile(2, 0, 5));
  EXPECT_EQ(w.part.counters().points_in_closed_tiles, 5u);
  w.part.add_points(points_in_tile(-2, 0, 101));  // one new voxel in the west tile
  EXPECT_EQ(w.part.size(), 141u);
  // A step east: the east tile is in the core now and maps again; the west one left the ring.
  w.part.recentre(Eigen::Vector2d(4.0, 1.0), sink);
  EXPECT_EQ(sink.samples, 100u + 101u);
  w.part.add_points(points_in_tile(2, 0, 5));
  EXPECT_EQ(w.part.counters().points_in_closed_tiles, 5u);
  EXPECT_EQ(w.part.size(), 40u + 5u);
}

TEST(VoxelWindow, AClosedTileThatLeavesTheWindowIsOpenWhenItComesBack) {
  Window w(config_with_core());
  CollectingSink sink;
  w.part.recentre(Eigen::Vector2d(1.0, 1.0), sink);
  w.part.add_points(points_in_tile(2, 0, 230));
  w.part.make_room(sink);
  ASSERT_EQ(w.part.counters().tiles_left_early, 1u);
  // West by one tile: the east tile (2, 0) leaves the ring (-3..1); back: it is open again.
  w.part.recentre(Eigen::Vector2d(-2.0, 1.0), sink);
  w.part.recentre(Eigen::Vector2d(1.0, 1.0), sink);
  w.part.add_points(points_in_tile(2, 0, 10));
  EXPECT_EQ(w.part.counters().points_in_closed_tiles, 0u);
  EXPECT_EQ(w.part.size(), 10u);
}

TEST(VoxelWindow, TheCoreNeverLeavesEarlyAndAWindowWithoutOneNeverDoes) {
  {
    Window w(config_with_core());
    CollectingSink sink;
    w.part.recentre(Eigen::Vector2d(1.0, 1.0), sink);
    w.part.add_points(points_in_tile(0, 0, 250));  // the core alone nearly fills the pool
    w.part.make_room(sink);
    EXPECT_TRUE(sink.tiles.empty());
    EXPECT_EQ(w.part.size(), 250u);
  }
  {
    VoxelWindowConfig config = config_with_core();
    config.core_tiles_across = 0;
    Window w(config);
    CollectingSink sink;
    w.part.recentre(Eigen::Vector2d(1.0, 1.0), sink);
    w.part.add_points(points_in_tile(2, 0, 250));
    w.part.make_room(sink);
    EXPECT_TRUE(sink.tiles.empty());
    EXPECT_EQ(w.part.counters().tiles_left_early, 0u);
  }
}

TEST(VoxelWindow, AValidConfigurationIsOneTheDetectorsBlocksFit) {
  EXPECT_EQ(validate(VoxelWindowConfig{}), "");
  VoxelWindowConfig config;
  config.tile_size_m = 8.1;  // not whole 0.8 m blocks
  EXPECT_NE(validate(config), "");
  config = VoxelWindowConfig{};
  config.tiles_across = 8;  // even: no middle tile
  EXPECT_NE(validate(config), "");
  config = VoxelWindowConfig{};
  config.max_samples = 10;
  EXPECT_NE(validate(config), "");
  // A core is odd and inside the window, and keeps less than the pool in reserve.
  EXPECT_EQ(validate(config_with_core()), "");
  config = config_with_core();
  config.core_tiles_across = 4;
  EXPECT_NE(validate(config), "");
  config.core_tiles_across = 7;
  EXPECT_NE(validate(config), "");
  config = config_with_core();
  config.reserve_samples = config.max_samples;
  EXPECT_NE(validate(config), "");
}

}  // namespace
}  // namespace blockmap::map
