// The batch pipeline on a simulated world's truth cloud: the detector's planes fitted to
// buildings, each truth building against the fitted one that overlaps it most. Shared by the
// building world tests (tests/buildings) and the accuracy tables (tests/bench).
#pragma once

#include <cstdio>
#include <span>
#include <string>
#include <vector>

#include "blockmap/buildings/building_fitter.hpp"
#include "blockmap/core/arena.hpp"
#include "blockmap/hal/config/robot.hpp"
#include "blockmap/hal/sim/truth_cloud.hpp"
#include "blockmap/hal/sim/world.hpp"
#include "blockmap/planes/plane_detector.hpp"
#include "footprint_score.hpp"

namespace blockmap::buildings {

#if defined(BLOCKMAP_QUICK_WORLDS)
inline constexpr double kDurationS = 60.0;
inline constexpr std::size_t kMaxSamples = std::size_t{1} << 18;
#else
inline constexpr double kDurationS = 0.0;
inline constexpr std::size_t kMaxSamples = std::size_t{1} << 20;
#endif

// One truth building against the fitted building that overlaps it most.
struct BuildingMatch {
  int truth_id = 0;
  std::string truth_shape;
  std::string shape;  // "" when no fitted building overlaps it
  double iou = 0.0;
  std::size_t walls_seen = 0;  // truth walls with at least 200 returns
  std::size_t walls = 0;
};

inline std::vector<BuildingMatch> fit_world(const std::string& world_name, std::uint64_t seed) {
  const hal::sim::World world = hal::sim::load_world(world_name);
  hal::sim::SimOptions options;
  options.seed = seed;
  options.max_duration_s = kDurationS;
  const hal::sim::TruthCloud cloud =
      hal::sim::simulate_truth_cloud(world, hal::config::load_robot("paper_rmp"), options);
  planes::PlanesConfig planes_config;
  planes_config.max_samples = kMaxSamples;
  BuildingsConfig config;
  Arena arena(planes::PlaneDetector::arena_budget_bytes(planes_config) +
              BuildingFitter::arena_bytes(config));
  planes::PlaneDetector detector;
  detector.init(arena, planes_config);
  BuildingFitter fitter;
  fitter.init(arena, config);
  arena.seal();
  detector.add_points(cloud.points_m);
  const std::span<const msg::PlanePatch> planes = detector.detect();
  const std::span<const Building> buildings = fitter.fit(planes);

  std::vector<BuildingMatch> matches;
  for (const hal::sim::Building& truth : world.buildings) {
    BuildingMatch match;
    match.truth_id = truth.id;
    match.truth_shape = hal::sim::to_string(truth.shape);
    for (const hal::sim::TruthFace& face : cloud.faces) {
      if (face.building_id == truth.id && face.kind == hal::sim::SurfaceKind::kWall) {
        ++match.walls;
        match.walls_seen += face.returns >= 200 ? 1U : 0U;
      }
    }
    for (const Building& building : buildings) {
      const double iou = testing::footprint_iou(
          std::span<const Eigen::Vector2d>(building.footprint_m.data(), building.footprint_size),
          truth.footprint_m);
      if (iou > match.iou) {
        match.iou = iou;
        match.shape = to_string(building.shape);
      }
    }
    matches.push_back(match);
  }
  std::printf("%s seed %llu: %zu planes, %zu buildings\n", world_name.c_str(),
              static_cast<unsigned long long>(seed), planes.size(), buildings.size());
  for (const Building& building : buildings) {
    std::printf("  building %u %s, height %.1f m, confidence %.2f, %u walls:", building.id,
                std::string(to_string(building.shape)).c_str(), building.height_m,
                building.confidence, building.wall_count);
    for (std::size_t k = 0; k < building.footprint_size; ++k) {
      std::printf(" (%.1f %.1f)", building.footprint_m[k].x(), building.footprint_m[k].y());
    }
    std::printf("\n");
  }
  for (const msg::PlanePatch& plane : planes) {
    WallSegment segment;
    msg::PlanePatch as_wall = plane;
    as_wall.kind = msg::PlaneKind::kWall;
    if (plane.kind != msg::PlaneKind::kGround && wall_segment_of(as_wall, segment)) {
      std::printf("  %s ", std::string(msg::to_string(plane.kind)).c_str());
      std::printf("  wall plane %u: (%.1f %.1f) - (%.1f %.1f), z %.1f - %.1f, support %.0f\n",
                  plane.id, segment.p0_m.x(), segment.p0_m.y(), segment.p1_m.x(), segment.p1_m.y(),
                  segment.z0_m, segment.z1_m, plane.support);
    }
  }
  for (const hal::sim::TruthFace& face : cloud.faces) {
    if (face.kind == hal::sim::SurfaceKind::kWall) {
      std::printf("  truth wall %d of %d: (%.1f %.1f) - (%.1f %.1f), %llu returns\n", face.id,
                  face.building_id, face.corners_m[0].x(), face.corners_m[0].y(),
                  face.corners_m[1].x(), face.corners_m[1].y(),
                  static_cast<unsigned long long>(face.returns));
    }
  }
  for (const BuildingMatch& match : matches) {
    std::printf("  truth %d %s (%zu/%zu walls seen): %s, IoU %.3f\n", match.truth_id,
                match.truth_shape.c_str(), match.walls_seen, match.walls,
                match.shape.empty() ? "not found" : match.shape.c_str(), match.iou);
  }
  return matches;
}

// The figures: shape right, IoU >= 0.85 for a rect, >= 0.8 for an L or a T.
inline bool completed(const BuildingMatch& match) {
  return match.shape == match.truth_shape &&
         match.iou >= (match.truth_shape == "rect" ? 0.85 : 0.8);
}

}  // namespace blockmap::buildings
