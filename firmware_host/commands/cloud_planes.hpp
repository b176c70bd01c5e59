// The planes of a point cloud file, as `planes` and `buildings` detect them: capacities sized
// to the cloud, one arena, the detector's statistics and warnings on `err`.
#pragma once

#include <ostream>
#include <string>
#include <vector>

#include "blockmap/hal/cloud/point_cloud_file.hpp"
#include "blockmap/msg/plane_patch.hpp"
#include "blockmap/planes/planes_config.hpp"

namespace blockmap::cli {

struct CloudPlanes {
  std::vector<msg::PlanePatch> planes;  // in the file's frame
  double seconds = 0.0;                 // detection alone, without reading the file
};

// `name` labels the statistics line ("planes: NAME (format): N points, ...").
[[nodiscard]] CloudPlanes detect_cloud_planes(const hal::cloud::PointCloud& cloud,
                                              planes::PlanesConfig config, const std::string& name,
                                              std::ostream& err);

}  // namespace blockmap::cli
