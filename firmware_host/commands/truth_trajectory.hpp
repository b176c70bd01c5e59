// truth.json's trajectory (docs/formats.md, truth.json): a simulated run's true poses, as
// `score` lays a map's path onto them and `replay --poses truth` draws the logs with them.
#pragma once

#include <vector>

#include <nlohmann/json.hpp>

#include "blockmap/core/time.hpp"
#include "blockmap/localize/localizer.hpp"

namespace blockmap::cli {

// The poses of truth.json's "trajectory", in its order; throws nlohmann::json::exception when
// a pose lacks a field.
[[nodiscard]] inline std::vector<localize::Pose3> true_poses_of(const nlohmann::json& truth) {
  std::vector<localize::Pose3> poses;
  for (const nlohmann::json& pose : truth.at("trajectory")) {
    poses.push_back({ns_from_seconds(pose.at("t_s").get<double>()), pose.at("x_m").get<double>(),
                     pose.at("y_m").get<double>(), pose.at("z_m").get<double>(),
                     pose.at("roll_rad").get<double>(), pose.at("pitch_rad").get<double>(),
                     pose.at("yaw_rad").get<double>()});
  }
  return poses;
}

}  // namespace blockmap::cli
