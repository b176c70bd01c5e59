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

}  // namespace

void write_vrml(std::ostream& out, std::span<const msg::PlanePatch> planes,
                std::span<const localize::Pose3> path,
                std::span<const buildings::Building> buildings) {
  out << "#VRML V2.0 utf8\n"
         "# blockmap: the map's planes (walls grey, roofs red, ground green, other blue) and the\n"
         "# robot's path (yellow), in the local ENU frame, metres; +z is up. Building walls:\n"
         "# seen dark, virtual (estimated, never seen) light.\n"
         "WorldInfo { title \"blockmap map\" }\n"
         "NavigationInfo { type [\"EXAMINE\", \"ANY\"] }\n"
         // VRML's y is up: turn the ENU frame so that z points up in the viewer.
         "Transform {\n  rotation 1 0 0 -1.5707963\n  children [\n";
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
