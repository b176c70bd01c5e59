#include "outputs/vrml.hpp"

#include <array>
#include <cstdio>
#include <ostream>
#include <string>

namespace blockmap::cli {
namespace {

std::array<double, 3> colour_of(msg::PlaneKind kind) noexcept {
  switch (kind) {
    case msg::PlaneKind::kWall:
      return {0.75, 0.75, 0.72};
    case msg::PlaneKind::kRoof:
      return {0.70, 0.25, 0.20};
    case msg::PlaneKind::kGround:
      return {0.35, 0.55, 0.30};
    case msg::PlaneKind::kOther:
      return {0.30, 0.45, 0.75};
  }
  return {0.5, 0.5, 0.5};
}

std::string point_text(double x, double y, double z) {
  char text[96];
  const int n = std::snprintf(text, sizeof text, "%.3f %.3f %.3f", x, y, z);
  return {text, static_cast<std::size_t>(n)};
}

}  // namespace

void write_vrml(std::ostream& out, std::span<const msg::PlanePatch> planes,
                std::span<const localize::Pose3> path) {
  out << "#VRML V2.0 utf8\n"
         "# blockmap: the map's planes (walls grey, roofs red, ground green, other blue) and the\n"
         "# robot's path (yellow), in the local ENU frame, metres; +z is up.\n"
         "WorldInfo { title \"blockmap map\" }\n"
         "NavigationInfo { type [\"EXAMINE\", \"ANY\"] }\n"
         // VRML's y is up: turn the ENU frame so that z points up in the viewer.
         "Transform {\n  rotation 1 0 0 -1.5707963\n  children [\n";
  for (const msg::PlanePatch& plane : planes) {
    if (plane.polygon_size < 3) {
      continue;
    }
    const auto [r, g, b] = colour_of(plane.kind);
    char material[160];
    std::snprintf(material, sizeof material,
                  "      appearance Appearance { material Material { diffuseColor %.2f %.2f %.2f } "
                  "}\n",
                  r, g, b);
    out << "    # plane " << plane.id << ' ' << msg::to_string(plane.kind) << "\n    Shape {\n"
        << material << "      geometry IndexedFaceSet {\n        solid FALSE\n"
        << "        coord Coordinate { point [";
    for (std::size_t i = 0; i < plane.polygon_size; ++i) {
      const Eigen::Vector3d& p = plane.polygon_m[i];
      out << (i > 0 ? ", " : " ") << point_text(p.x(), p.y(), p.z());
    }
    out << " ] }\n        coordIndex [";
    for (std::size_t i = 0; i < plane.polygon_size; ++i) {
      out << ' ' << i;
    }
    out << " -1 ]\n      }\n    }\n";
  }
  if (path.size() >= 2) {
    out << "    Shape {\n      appearance Appearance { material Material { emissiveColor 1 0.85 0 "
           "} }\n      geometry IndexedLineSet {\n        coord Coordinate { point [";
    for (std::size_t i = 0; i < path.size(); ++i) {
      out << (i > 0 ? ", " : " ") << point_text(path[i].x_m, path[i].y_m, path[i].z_m);
    }
    out << " ] }\n        coordIndex [";
    for (std::size_t i = 0; i < path.size(); ++i) {
      out << ' ' << i;
    }
    out << " -1 ]\n      }\n    }\n";
  }
  out << "  ]\n}\n";
}

}  // namespace blockmap::cli
