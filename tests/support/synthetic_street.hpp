// A synthetic street for loop closing (tests/localize/test_loop_closer.cpp and the memory
// tests): buildings on both sides with gaps between them, driven out along it and back on
// the other side of the road, and what a forward-looking level laser sees there.
#pragma once

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "blockmap/core/angles.hpp"
#include "blockmap/localize/particle_filter.hpp"
#include "blockmap/localize/prior_map.hpp"

namespace blockmap::synthetic_street {

using localize::Pose2;

struct Facade {
  Eigen::Vector2d from_m;
  Eigen::Vector2d to_m;
};

// Facades 8 m either side of the street's axis, in irregular lengths, and the side walls of
// the gaps between them going back 12 m: what holds a match along the street.
inline std::vector<Facade> street_of(double facade_north_m) {
  std::vector<Facade> walls;
  const double north_blocks[][2] = {{0, 17},  {20, 41},   {45, 52},  {58, 80},
                                    {83, 99}, {104, 130}, {133, 160}};
  const double south_blocks[][2] = {{0, 9},    {12, 33},   {38, 61},  {64, 70},
                                    {76, 102}, {107, 121}, {126, 160}};
  for (const auto& [from, to] : north_blocks) {
    walls.push_back({{from, facade_north_m}, {to, facade_north_m}});
    walls.push_back({{from, facade_north_m}, {from, facade_north_m + 12.0}});
    walls.push_back({{to, facade_north_m}, {to, facade_north_m + 12.0}});
  }
  for (const auto& [from, to] : south_blocks) {
    walls.push_back({{from, -8.0}, {to, -8.0}});
    walls.push_back({{from, -8.0}, {from, -20.0}});
    walls.push_back({{to, -8.0}, {to, -20.0}});
  }
  return walls;
}

// The facades as a prior map's walls (lines: they enclose nothing).
inline std::vector<localize::MapWall> map_walls_of(const std::vector<Facade>& facades) {
  std::vector<localize::MapWall> walls;
  walls.reserve(facades.size());
  for (const Facade& facade : facades) {
    walls.push_back({facade.from_m, facade.to_m});
  }
  return walls;
}

// What a forward-looking level laser returns at `pose` (no occlusion): the walls' points
// every 10 cm within 30 m and ahead of the robot, in the robot frame, by bearing.
inline std::vector<Eigen::Vector2d> laser_scan_at(const std::vector<Facade>& walls,
                                                  const Pose2& pose) {
  const Eigen::Rotation2Dd to_robot(-pose.yaw_rad);
  const Eigen::Vector2d at_m(pose.x_m, pose.y_m);
  std::vector<Eigen::Vector2d> points;
  for (const Facade& wall : walls) {
    const double length_m = (wall.to_m - wall.from_m).norm();
    for (double s = 0.0; s <= length_m; s += 0.1) {
      const Eigen::Vector2d in_robot =
          to_robot * (wall.from_m + (wall.to_m - wall.from_m) * (s / length_m) - at_m);
      if (in_robot.x() > 0.0 && in_robot.norm() < 30.0) {
        points.push_back(in_robot);
      }
    }
  }
  std::sort(points.begin(), points.end(), [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return std::atan2(a.y(), a.x()) < std::atan2(b.y(), b.x());
  });
  // Every point would make thousands; a scan's match keeps about 500.
  std::vector<Eigen::Vector2d> kept;
  const std::size_t step = std::max<std::size_t>(1, points.size() / 500);
  for (std::size_t i = 0; i < points.size(); i += step) {
    kept.push_back(points[i]);
  }
  return kept;
}

inline constexpr double kStreetM = 140.0;
inline constexpr double kScanStepM = 0.5;

// The true pose at `s` metres along the drive: out east 1 m north of the axis, back west
// 1 m south of it (the turn itself is left out: the scans of a U-turn add nothing here).
inline Pose2 street_truth_at(double s_m) {
  const auto stamp = static_cast<TimestampNs>(s_m / 1.2 * 1e9);
  if (s_m <= kStreetM) {
    return {stamp, s_m, 1.0, 0.0};
  }
  return {stamp, 2.0 * kStreetM - s_m, -1.0, std::numbers::pi};
}

// The way back's odometry: turned (by 1 degree) about a point (the turn) and shifted.
inline Pose2 drifted_back(const Pose2& truth, double turn_deg = 1.0,
                          const Eigen::Vector2d& about_m = Eigen::Vector2d(kStreetM, 0.0)) {
  if (truth.yaw_rad == 0.0) {
    return truth;
  }
  const Eigen::Rotation2Dd turn(radians_from_degrees(turn_deg));
  const Eigen::Vector2d moved_m = turn * (Eigen::Vector2d(truth.x_m, truth.y_m) - about_m) +
                                  about_m + Eigen::Vector2d(0.5, 0.3);
  return {truth.stamp_ns, moved_m.x(), moved_m.y(), truth.yaw_rad + radians_from_degrees(turn_deg)};
}

}  // namespace blockmap::synthetic_street
