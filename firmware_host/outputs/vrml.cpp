#include "outputs/vrml.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <ostream>
#include <string>

#include <Eigen/Geometry>

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

// One flat polygon with its material line.
void write_face(std::ostream& out, std::span<const Eigen::Vector3d> corners,
                const std::string& material, const std::string& comment) {
  out << "    # " << comment << "\n    Shape {\n"
      << material << "      geometry IndexedFaceSet {\n        solid FALSE\n"
      << "        coord Coordinate { point [";
  for (std::size_t i = 0; i < corners.size(); ++i) {
    const Eigen::Vector3d& p = corners[i];
    out << (i > 0 ? ", " : " ") << point_text(p.x(), p.y(), p.z());
  }
  out << " ] }\n        coordIndex [";
  for (std::size_t i = 0; i < corners.size(); ++i) {
    out << ' ' << i;
  }
  out << " -1 ]\n      }\n    }\n";
}

std::string material_text(const std::array<double, 3>& colour, double transparency) {
  char material[200];
  std::snprintf(material, sizeof material,
                "      appearance Appearance { material Material { diffuseColor %.2f %.2f %.2f "
                "transparency %.2f } }\n",
                colour[0], colour[1], colour[2], transparency);
  return material;
}

bool drawn_by_a_building(std::uint32_t plane_id, std::span<const buildings::Building> buildings) {
  for (const buildings::Building& building : buildings) {
    for (std::size_t w = 0; w < building.wall_count; ++w) {
      if (!building.walls[w].is_virtual && building.walls[w].plane_id == plane_id) {
        return true;
      }
    }
  }
  return false;
}

// The map's extent in the local frame: what the viewpoints frame.
Eigen::AlignedBox3d map_bounds(std::span<const msg::PlanePatch> planes,
                               std::span<const localize::Pose3> path,
                               std::span<const buildings::Building> buildings) {
  Eigen::AlignedBox3d bounds;
  for (const msg::PlanePatch& plane : planes) {
    for (std::size_t i = 0; i < plane.polygon_size; ++i) {
      bounds.extend(plane.polygon_m[i]);
    }
  }
  for (const localize::Pose3& pose : path) {
    bounds.extend(Eigen::Vector3d(pose.x_m, pose.y_m, pose.z_m));
  }
  for (const buildings::Building& building : buildings) {
    for (std::size_t w = 0; w < building.wall_count; ++w) {
      const buildings::BuildingWall& wall = building.walls[w];
      bounds.extend(Eigen::Vector3d(wall.p0_m.x(), wall.p0_m.y(), wall.z0_m));
      bounds.extend(Eigen::Vector3d(wall.p1_m.x(), wall.p1_m.y(), wall.z1_m));
    }
  }
  if (bounds.isEmpty()) {
    bounds.extend(Eigen::Vector3d::Zero());
  }
  return bounds;
}

// Two named viewpoints that frame the whole map (a viewer's default camera sits at the origin,
// inside the block): "overview", looking north and 50 deg down, the view of the paper's
// figures; "top", straight down with north up, as the SVG pictures. They are written in
// VRML's own frame (y up, north is -z), outside the turn of the map: a viewpoint's default
// direction (-z) is then north, and a turn about x by -angle tilts it down.
void write_viewpoints(std::ostream& out, const Eigen::AlignedBox3d& bounds) {
  constexpr double kFieldOfViewRad = 0.785398;
  constexpr double kHalfPi = 1.5707963;
  constexpr double kOverviewDownRad = 0.872665;  // 50 deg below the horizon
  const Eigen::Vector3d centre = bounds.center();
  const Eigen::Vector3d size = bounds.sizes();
  // The field of view spans the window's shorter side, its height in a landscape window
  // (4:3 assumed): the map's east-west extent may take 4/3 of it.
  constexpr double kAspect = 4.0 / 3.0;
  const double radius_m = std::max(2.0, 0.5 * std::max(size.x() / kAspect, size.y()));
  const double distance_m = radius_m / std::tan(0.5 * kFieldOfViewRad);
  const auto write = [&](const char* name, double down_rad, double distance) {
    // ENU (e, n, u) is VRML (e, u, -n); the camera looks at the centre from `distance` back.
    const std::string position = point_text(centre.x(), centre.z() + distance * std::sin(down_rad),
                                            -centre.y() + distance * std::cos(down_rad));
    char text[256];
    std::snprintf(text, sizeof text,
                  "Viewpoint { description \"%s\" fieldOfView %.6f position %s "
                  "orientation 1 0 0 %.6f }\n",
                  name, kFieldOfViewRad, position.c_str(), -down_rad);
    out << text;
  };
  write("overview", kOverviewDownRad, distance_m);
  write("top", kHalfPi, distance_m + 0.5 * size.z());
}

}  // namespace

void write_vrml(std::ostream& out, std::span<const msg::PlanePatch> planes,
                std::span<const localize::Pose3> path,
                std::span<const buildings::Building> buildings) {
  out << "#VRML V2.0 utf8\n"
         "# blockmap: the map's planes (walls grey, roofs red, ground green, other blue) and the\n"
         "# robot's path (yellow), in the local ENU frame, metres; +z is up. Building walls:\n"
         "# seen dark, virtual (estimated, never seen) light.\n"
         "WorldInfo { title \"blockmap map\" }\n";
  // The viewpoints before the NavigationInfo: view3dscene (4.2) starts from "view all" instead
  // of the first viewpoint when a NavigationInfo comes first.
  write_viewpoints(out, map_bounds(planes, path, buildings));
  out << "NavigationInfo { type [\"EXAMINE\", \"ANY\"] }\n";
  // VRML's y is up: turn the ENU frame so that z points up in the viewer.
  out << "Transform {\n  rotation 1 0 0 -1.5707963\n  children [\n";
  for (const msg::PlanePatch& plane : planes) {
    if (plane.polygon_size < 3 ||
        (plane.kind == msg::PlaneKind::kWall && drawn_by_a_building(plane.id, buildings))) {
      continue;
    }
    write_face(out, std::span<const Eigen::Vector3d>(plane.polygon_m.data(), plane.polygon_size),
               material_text(colour_of(plane.kind), 0.0),
               "plane " + std::to_string(plane.id) + ' ' + std::string(msg::to_string(plane.kind)));
  }
  const std::string observed = material_text({0.32, 0.34, 0.42}, 0.0);
  const std::string estimated = material_text({0.80, 0.84, 0.95}, 0.35);
  for (const buildings::Building& building : buildings) {
    for (std::size_t w = 0; w < building.wall_count; ++w) {
      const buildings::BuildingWall& wall = building.walls[w];
      const std::array<Eigen::Vector3d, 4> corners{
          Eigen::Vector3d(wall.p0_m.x(), wall.p0_m.y(), wall.z0_m),
          Eigen::Vector3d(wall.p1_m.x(), wall.p1_m.y(), wall.z0_m),
          Eigen::Vector3d(wall.p1_m.x(), wall.p1_m.y(), wall.z1_m),
          Eigen::Vector3d(wall.p0_m.x(), wall.p0_m.y(), wall.z1_m)};
      write_face(out, corners, wall.is_virtual ? estimated : observed,
                 "building " + std::to_string(building.id) +
                     (wall.is_virtual ? " virtual wall" : " wall"));
    }
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
