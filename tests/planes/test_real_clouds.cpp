// Real scans (../shared/data/real; skipped when absent): a Velodyne frame of a street and three
// tilting-SICK scans of a corridor, through the file readers and the detector.
#include <gtest/gtest.h>

#include <string>

#include "blockmap/core/arena.hpp"
#include "blockmap/hal/cloud/point_cloud_file.hpp"
#include "blockmap/planes/plane_detector.hpp"
#include "test_data.hpp"

namespace blockmap::planes {
namespace {

std::vector<msg::PlanePatch> detect_file(const std::filesystem::path& path) {
  const hal::cloud::PointCloud cloud = hal::cloud::read_point_cloud(path);
  PlanesConfig config;
  config.max_samples = 1 << 18;
  Arena arena(PlaneDetector::arena_budget_bytes(config));
  PlaneDetector detector;
  detector.init(arena, config);
  detector.add_points(cloud.points_m);
  const auto planes = detector.detect();
  return {planes.begin(), planes.end()};
}

// A plane of this kind whose normal is within 5 degrees of `axis` (either sign) and whose
// offset along +axis is within tolerance_m of offset_m.
bool has_plane(const std::vector<msg::PlanePatch>& planes, msg::PlaneKind kind,
               const Eigen::Vector3d& axis, double offset_m, double tolerance_m) {
  for (const msg::PlanePatch& plane : planes) {
    const double alignment = plane.normal.dot(axis);
    if (plane.kind == kind && std::abs(alignment) > std::cos(5.0 * 3.14159265 / 180.0) &&
        std::abs((alignment > 0 ? plane.d_m : -plane.d_m) - offset_m) < tolerance_m) {
      return true;
    }
  }
  return false;
}

TEST(RealClouds, KittiStreetGroundAndTheFacadeNearYMinus9_6) {
  const auto path = testing::shared_data("real/kitti-frame/kitti_00_000000.bin");
  if (!path) {
    GTEST_SKIP() << "../shared/data is absent";
  }
  const auto planes = detect_file(*path);
  // The Velodyne is 1.73 m above the road.
  EXPECT_TRUE(has_plane(planes, msg::PlaneKind::kGround, Eigen::Vector3d::UnitZ(), -1.75, 0.15));
  EXPECT_TRUE(has_plane(planes, msg::PlaneKind::kWall, Eigen::Vector3d::UnitY(), -9.6, 0.3));
}

TEST(RealClouds, CorridorFloorCeilingAndWallsInEachOfThree3dtkScans) {
  for (const char* name : {"scan000.3d", "scan001.3d", "scan002.3d"}) {
    const auto path = testing::shared_data(std::string("real/3dtk-dat/") + name);
    if (!path) {
      GTEST_SKIP() << "../shared/data is absent";
    }
    SCOPED_TRACE(name);
    const auto planes = detect_file(*path);
    EXPECT_TRUE(has_plane(planes, msg::PlaneKind::kGround, Eigen::Vector3d::UnitZ(), -0.36, 0.1));
    EXPECT_TRUE(has_plane(planes, msg::PlaneKind::kRoof, Eigen::Vector3d::UnitZ(), 2.06, 0.1));
    EXPECT_TRUE(has_plane(planes, msg::PlaneKind::kWall, Eigen::Vector3d::UnitY(), -0.97, 0.1));
    EXPECT_TRUE(has_plane(planes, msg::PlaneKind::kWall, Eigen::Vector3d::UnitY(), 3.79, 0.1));
  }
}

}  // namespace
}  // namespace blockmap::planes
