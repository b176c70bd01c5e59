// The daemon tests' view of a map: its walls, and whether a wall is among another map's within
// the particle filter's run-to-run spread. On a minute of the simulated usc_block, replays of
// the same logs with seeds 1, 2 and 3 put the largest walls up to 5 deg and 2.3 m apart
// (docs/daemon.md), so two maps made by two runs of the filter agree only that closely.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <numbers>
#include <vector>

#include "cli_runner.hpp"

namespace blockmap::cli::testing {

struct Wall {
  Eigen::Vector3d normal;
  double d = 0.0;
  double support = 0.0;
};

// The walls of a plane list (planes.json) with at least `min_support` points.
inline std::vector<Wall> walls_of(const std::filesystem::path& planes_json,
                                  double min_support = 0.0) {
  std::vector<Wall> walls;
  const nlohmann::json list = nlohmann::json::parse(read_file(planes_json));
  for (const nlohmann::json& plane : list["planes"]) {
    if (plane["kind"] == "wall" && plane["support"].get<double>() >= min_support) {
      walls.push_back({Eigen::Vector3d(plane["normal"][0], plane["normal"][1], plane["normal"][2]),
                       plane["d"].get<double>(), plane["support"].get<double>()});
    }
  }
  return walls;
}

// Whether `wall` is among `walls` within `max_angle_deg` and 3 m (either side of the plane).
inline bool within_spread(const Wall& wall, const std::vector<Wall>& walls,
                          double max_angle_deg = 8.0) {
  return std::any_of(walls.begin(), walls.end(), [&](const Wall& other) {
    const double cos_angle = wall.normal.dot(other.normal);
    const double sign = cos_angle < 0.0 ? -1.0 : 1.0;
    return std::abs(cos_angle) > std::cos(max_angle_deg * std::numbers::pi / 180.0) &&
           std::abs(wall.d - sign * other.d) < 3.0;
  });
}

}  // namespace blockmap::cli::testing
