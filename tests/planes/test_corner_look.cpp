// The corner look on a scene whose walls are known: a building's front seen well, its east
// side only glimpsed, through pose errors, as a slab 0.3 m thick that no neighbourhood calls
// flat. The planes list the look starts from is given, so each test says what it is about.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>
#include <span>
#include <vector>

#include "blockmap/core/arena.hpp"
#include "blockmap/planes/corner_look.hpp"
#include "blockmap/planes/plane_merger.hpp"
#include "blockmap/planes/voxel_grid.hpp"

namespace blockmap::planes {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

// The building stands on y in [0, 8] and x in [0, 12], 6 m high; the street is y < 0.
constexpr double kEastX = 12.0;

struct Scene {
  std::vector<Eigen::Vector3f> points;
  std::mt19937 random{5};

  void front_wall() {  // y = 0, 2 cm thick: seen well
    std::normal_distribution<float> noise(0.0f, 0.02f);
    for (float x = 0.0f; x <= 12.0f; x += 0.05f) {
      for (float z = 0.0f; z <= 6.0f; z += 0.05f) {
        points.emplace_back(x, noise(random), z);
      }
    }
  }
  void street(float y_from, float y_to) {  // the ground in front of it
    std::normal_distribution<float> noise(0.0f, 0.02f);
    for (float x = -2.0f; x <= 14.0f; x += 0.1f) {
      for (float y = y_from; y <= y_to; y += 0.1f) {
        points.emplace_back(x, y, noise(random));
      }
    }
  }
  // A side at x = kEastX from y_from to y_to, seen in `scans` vertical strokes from z_from up,
  // each moved across by its own pose error (sigma_m).
  void glimpsed_side(float y_from, float y_to, int scans, double sigma_m, float z_from = 0.2f) {
    std::normal_distribution<double> error(0.0, sigma_m);
    std::normal_distribution<float> range_noise(0.0f, 0.01f);
    std::uniform_real_distribution<float> along(y_from, y_to);
    for (int scan = 0; scan < scans; ++scan) {
      const auto shift = static_cast<float>(error(random));
      const float y = along(random);
      for (float z = z_from; z <= 6.0f; z += 0.05f) {
        points.emplace_back(static_cast<float>(kEastX) + shift + range_noise(random), y + 0.1f * z,
                            z);
      }
    }
  }
  // A hedge 3 m high along the side, outside it: leaves scattered through 0.8 m.
  void hedge(int leaves) {
    std::uniform_real_distribution<float> x(static_cast<float>(kEastX) + 0.4f,
                                            static_cast<float>(kEastX) + 1.2f);
    std::uniform_real_distribution<float> y(0.5f, 8.0f);
    std::uniform_real_distribution<float> z(0.2f, 3.0f);
    for (int i = 0; i < leaves; ++i) {
      points.emplace_back(x(random), y(random), z(random));
    }
  }
};

msg::PlanePatch wall_patch(const Eigen::Vector3d& normal, double d_m, double rmse_m,
                           std::array<Eigen::Vector3d, 4> corners) {
  msg::PlanePatch p;
  p.kind = msg::PlaneKind::kWall;
  p.normal = normal;
  p.d_m = d_m;
  p.rmse_m = rmse_m;
  p.support = 10000;
  p.centroid_m = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < corners.size(); ++i) {
    p.polygon_m[i] = corners[i];
    p.centroid_m += 0.25 * corners[i];
  }
  p.polygon_size = 4;
  return p;
}

msg::PlanePatch front_patch() {
  return wall_patch({0, 1, 0}, 0.0, 0.02, {{{0, 0, 0}, {12, 0, 0}, {12, 0, 6}, {0, 0, 6}}});
}

msg::PlanePatch ground_patch() {
  msg::PlanePatch p;
  p.kind = msg::PlaneKind::kGround;
  p.normal = {0, 0, 1};
  p.rmse_m = 0.02;
  p.support = 10000;
  p.polygon_m[0] = {-2, -8, 0};
  p.polygon_m[1] = {14, -8, 0};
  p.polygon_m[2] = {14, -0.2, 0};
  p.polygon_m[3] = {-2, -0.2, 0};
  p.centroid_m = {6, -4, 0};
  p.polygon_size = 4;
  return p;
}

// The building's front, the street before it and its east side glimpsed in 12 scans through
// 0.25 m of pose error.
Scene front_and_glimpsed_side() {
  Scene scene;
  scene.front_wall();
  scene.street(-8.0f, -0.2f);
  scene.glimpsed_side(0.5f, 8.0f, 12, 0.25);
  return scene;
}

struct Looked {
  CornerLookCounters counters;
  std::vector<msg::PlanePatch> planes;  // what the merger makes of the walls found
};

Looked look_at(const Scene& scene, std::span<const msg::PlanePatch> planes,
               double surface_noise_m) {
  PlanesConfig config;
  config.max_samples = 1 << 17;
  Arena arena(VoxelGrid::arena_bytes(config.max_samples) + PlaneMerger::arena_bytes(config));
  VoxelGrid voxels;
  voxels.init(arena, config.sample_size_m, config.max_samples);
  PlaneMerger merger;
  merger.init(arena, config);
  arena.seal();
  voxels.add_points(scene.points);
  voxels.compact();
  Looked out;
  out.counters = CornerLook(config).look(planes, surface_noise_m, voxels, merger);
  const std::span<const msg::PlanePatch> found = merger.merge();
  out.planes.assign(found.begin(), found.end());
  return out;
}

TEST(CornerLook, FindsASideGlimpsedThroughPoseErrorsWhereTheFrontEnds) {
  const Scene scene = front_and_glimpsed_side();
  const std::array planes{front_patch(), ground_patch()};
  // A blurred cloud: its surfaces are 0.1 m thick (RMS), the glimpsed side about 0.25 m.
  const Looked looked = look_at(scene, planes, 0.1);
  EXPECT_EQ(looked.counters.corners_tried, 2u);
  EXPECT_EQ(looked.counters.walls_found, 1u);
  ASSERT_EQ(looked.planes.size(), 1u);
  const msg::PlanePatch& side = looked.planes[0];
  EXPECT_GT(std::abs(side.normal.x()), std::cos(3.0 * kDeg));
  EXPECT_NEAR(std::abs(side.d_m), kEastX, 0.15);
  EXPECT_EQ(side.kind, msg::PlaneKind::kWall);
}

TEST(CornerLook, FindsASideAboveTheHedgeInFrontOfIt) {
  // partial's southern L: the side's lower half stands behind a hedge, and a fit of both
  // leans. The look tries the side's upper half again, clear of it.
  Scene scene;
  scene.front_wall();
  scene.street(-8.0f, -0.2f);
  scene.glimpsed_side(0.5f, 8.0f, 12, 0.15, 3.2f);
  scene.hedge(20000);
  const std::array planes{front_patch(), ground_patch()};
  const Looked looked = look_at(scene, planes, 0.15);
  EXPECT_EQ(looked.counters.walls_found, 1u);
  ASSERT_EQ(looked.planes.size(), 1u);
  const msg::PlanePatch& side = looked.planes[0];
  EXPECT_GT(std::abs(side.normal.x()), std::cos(3.0 * kDeg));
  EXPECT_NEAR(std::abs(side.d_m), kEastX, 0.15);
  EXPECT_GT(side.centroid_m.z(), 3.0) << "the side above the hedge";
}

TEST(CornerLook, LooksOnlyIntoTheBuildingNotAlongTheStreet) {
  // The same side, mirrored to the street's side of the front: the front has returns there
  // (the street) and none behind it, so the look goes behind it and finds nothing.
  Scene scene;
  scene.front_wall();
  scene.street(-8.0f, -0.2f);
  scene.glimpsed_side(-8.0f, -0.5f, 12, 0.25);
  const std::array planes{front_patch(), ground_patch()};
  const Looked looked = look_at(scene, planes, 0.1);
  EXPECT_EQ(looked.counters.walls_found, 0u);
  EXPECT_EQ(looked.counters.corners_tried, 2u) << "both ends of the front, into the building";
}

TEST(CornerLook, ACornerWhoseSideWasFoundIsNotLookedAt) {
  const Scene scene = front_and_glimpsed_side();
  const std::array planes{
      front_patch(), ground_patch(),
      wall_patch({1, 0, 0}, kEastX, 0.25, {{{12, 0, 0}, {12, 8, 0}, {12, 8, 6}, {12, 0, 6}}})};
  const Looked looked = look_at(scene, planes, 0.1);
  EXPECT_EQ(looked.counters.walls_found, 0u);
  // The side's own corners face the street on neither side (its other side is empty too):
  // only the front's west end is tried.
  EXPECT_EQ(looked.counters.corners_tried, 1u);
}

TEST(CornerLook, ASlabThickerThanTheCloudsSurfacesIsNoWall) {
  // In a crisp cloud (surfaces 2 cm thick) a slab 0.25 m thick is a hedge, not a wall.
  const Scene scene = front_and_glimpsed_side();
  const std::array planes{front_patch(), ground_patch()};
  const Looked looked = look_at(scene, planes, 0.02);
  EXPECT_EQ(looked.counters.corners_tried, 2u);
  EXPECT_EQ(looked.counters.walls_found, 0u);
  EXPECT_TRUE(looked.planes.empty());
}

}  // namespace
}  // namespace blockmap::planes
