// A picture of planes over their points, as SVG: an orthographic view from above at an angle,
// the points as dots shaded by height, each plane's extent filled by its kind (walls red,
// roofs blue, ground green, other grey), far planes first. SVG because any browser opens it
// and it needs no image library; the points are thinned to a budget to keep it small.
#pragma once

#include <cstddef>
#include <ostream>
#include <span>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "blockmap/msg/plane_patch.hpp"

namespace blockmap::cli {

struct PictureView {
  double azimuth_deg = -60.0;   // where the viewer stands, counter-clockwise from +x
  double elevation_deg = 35.0;  // 90: straight down
  int width_px = 1200;
  std::size_t max_points = 30000;  // every k-th point beyond this many
};

// Writes the picture; points and planes in the same frame.
void write_plane_picture(std::ostream& out, std::span<const Eigen::Vector3f> points_m,
                         std::span<const msg::PlanePatch> planes, const PictureView& view);

}  // namespace blockmap::cli
