// The planes of a point cloud file, as `planes` and `buildings` detect them: capacities sized
// to the cloud, one arena, the detector's statistics and warnings on `err`.
#pragma once

#include <ostream>
#include <string>
#include <vector>

#include "blockmap/hal/cloud/point_cloud_file.hpp"
#include "blockmap/msg/plane_patch.hpp"
#include "blockmap/planes/planes_config.hpp"
#include "commands/memory_budget.hpp"

namespace blockmap::cli {

struct CloudPlanes {
  std::vector<msg::PlanePatch> planes;  // in the file's frame
  double seconds = 0.0;                 // detection alone, without reading the file
};

// A point cloud file no bigger than the budget. Throws CloudFileError or hal::FileError.
[[nodiscard]] hal::cloud::PointCloud read_cloud_within(const std::string& path, double budget_mib);

// `name` labels the statistics line ("planes: NAME (format): N points, ..."). Throws
// hal::ConfigError when the detector's capacities do not fit the budget.
[[nodiscard]] CloudPlanes detect_cloud_planes(const hal::cloud::PointCloud& cloud,
                                              planes::PlanesConfig config, const std::string& name,
                                              double budget_mib, std::ostream& err);

}  // namespace blockmap::cli
