// The corner look on a scene whose walls are known: a building's front seen well, its east
// side only glimpsed, through pose errors, as a slab 0.3 m thick that no neighbourhood calls
// flat. The planes list the look starts from is given, so each test says what it is about.
#include <gtest/gtest.h>

#include <algorithm>
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
#include "test_units.hpp"

namespace blockmap::planes {
namespace {

using blockmap::testing::kDeg;

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

// An L whose notch faces away from the street: the building stands on x in [0, 12] and y in
// [0, 8] less the notch x in [8, 12], y in [4, 8]. Its front (y = 0) and its east side up to
// the notch (x = 12, y in [0, 4]) were found; the notch's own side (y = 4) faces away from
// every street and was never seen, and its back face (x = 8) only from far down the east
// street, by the level laser through the notch: strokes at many heights, each moved by its
// own pose error across the face (0.15 m) and sheared along it.
constexpr double kNotchX = 8.0;

struct NotchScene {
  Scene scene;

  NotchScene() {
    scene.front_wall();
    scene.street(-8.0f, -0.2f);
    east_side();
    east_ground();
    notch_face();
  }
  void east_side() {  // x = 12, y in [0, 4], crisp
    std::normal_distribution<float> noise(0.0f, 0.02f);
    for (float y = 0.0f; y <= 4.0f; y += 0.05f) {
      for (float z = 0.0f; z <= 6.0f; z += 0.05f) {
        scene.points.emplace_back(12.0f + noise(scene.random), y, z);
      }
    }
  }
  void east_ground() {  // the street east of the building
    std::normal_distribution<float> noise(0.0f, 0.02f);
    for (float x = 12.2f; x <= 20.0f; x += 0.1f) {
      for (float y = -8.0f; y <= 12.0f; y += 0.1f) {
        scene.points.emplace_back(x, y, noise(scene.random));
      }
    }
  }
  void notch_face() {
    std::normal_distribution<double> error(0.0, 0.15);
    std::uniform_real_distribution<float> height(0.4f, 3.0f);
    for (int scan = 0; scan < 60; ++scan) {
      const double across_m = error(scene.random);
      const auto shift_x = static_cast<float>(across_m);
      const auto shift_y = static_cast<float>(3.0 * across_m);  // sheared along the face
      const float z = height(scene.random);
      for (float y = 4.3f; y <= 8.0f; y += 0.05f) {
        scene.points.emplace_back(static_cast<float>(kNotchX) + shift_x, y + shift_y, z);
      }
    }
  }
  // The ground's fog behind the notch: a few points a metre along the face's line.
  void fog_beyond() {
    std::uniform_real_distribution<float> jitter(-0.1f, 0.1f);
    for (float y = 8.5f; y <= 20.0f; y += 0.3f) {
      scene.points.emplace_back(static_cast<float>(kNotchX) + jitter(scene.random), y,
                                0.7f + jitter(scene.random));
    }
  }
};

msg::PlanePatch east_side_patch(double from_y, double to_y) {
  return wall_patch({1, 0, 0}, 12.0, 0.1,
                    {{{12, from_y, 0}, {12, to_y, 0}, {12, to_y, 6}, {12, from_y, 6}}});
}

TEST(CornerLook, FindsTheNotchOfAnLWhereItsSideEnds) {
  const NotchScene notch;
  const std::array planes{front_patch(), ground_patch(), east_side_patch(0.0, 4.0)};
  const Looked looked = look_at(notch.scene, planes, 0.1);
  EXPECT_EQ(looked.counters.walls_found, 0u) << "no side square to the side where it ends";
  EXPECT_EQ(looked.counters.steps_found, 1u);
  ASSERT_EQ(looked.planes.size(), 1u);
  const msg::PlanePatch& face = looked.planes[0];
  EXPECT_EQ(face.kind, msg::PlaneKind::kWall);
  // Parallel to the side it stepped back from, seen from above: the shear of the strokes
  // alone would turn a free least-squares fit by several degrees. Its lean is fitted (60
  // strokes at random heights, each off by its own error: about 1.5 degrees).
  EXPECT_LT(std::abs(std::atan2(face.normal.y(), face.normal.x())), 0.1 * kDeg);
  EXPECT_GT(std::abs(face.normal.x()), std::cos(3.0 * kDeg));
  EXPECT_NEAR(std::abs(face.d_m), kNotchX, 0.1);
}

TEST(CornerLook, TheNotchEndsWhereItsPointsDoNotWhereTheFogDoes) {
  NotchScene notch;
  notch.fog_beyond();
  const std::array planes{front_patch(), ground_patch(), east_side_patch(0.0, 4.0)};
  const Looked looked = look_at(notch.scene, planes, 0.1);
  ASSERT_EQ(looked.planes.size(), 1u);
  double y_max = -1e9;
  for (std::size_t i = 0; i < looked.planes[0].polygon_size; ++i) {
    y_max = std::max(y_max, looked.planes[0].polygon_m[i].y());
  }
  EXPECT_LT(y_max, 9.0) << "the strokes end at y = 8 m (and their shear)";
}

// A blurred side whose found end lies 1.2 m short of the front it meets, and a slab parallel
// to the side in the street beyond its end (a row of parked vans, 4 m in from the side).
Scene side_and_vans(bool with_front) {
  Scene scene;
  if (with_front) {
    scene.front_wall();
  }
  scene.street(-8.0f, -0.2f);
  std::normal_distribution<float> noise(0.0f, 0.05f);
  for (float y = -6.0f; y <= -0.5f; y += 0.05f) {
    for (float z = 0.3f; z <= 2.5f; z += 0.1f) {
      scene.points.emplace_back(static_cast<float>(kNotchX) + noise(scene.random), y, z);
    }
  }
  for (float x = 12.2f; x <= 20.0f; x += 0.1f) {
    for (float y = -8.0f; y <= 8.0f; y += 0.1f) {
      scene.points.emplace_back(x, y, noise(scene.random));
    }
  }
  return scene;
}

TEST(CornerLook, NoStepWhereTheBuildingTurnsACornerShortOfTheWallsEnd) {
  // The side's end is a corner of the building, for the front (found) stands there: not a
  // step, though the vans stand where one could.
  const std::array turns{front_patch(), ground_patch(), east_side_patch(1.2, 8.0)};
  const Looked at_corner = look_at(side_and_vans(true), turns, 0.1);
  EXPECT_EQ(at_corner.counters.steps_found, 0u);
  // Without the front, nothing says the building turns there, and the vans are taken for
  // the step they could be.
  const std::array open{ground_patch(), east_side_patch(1.2, 8.0)};
  const Looked stepped = look_at(side_and_vans(false), open, 0.1);
  EXPECT_EQ(stepped.counters.steps_found, 1u);
}

}  // namespace
}  // namespace blockmap::planes
