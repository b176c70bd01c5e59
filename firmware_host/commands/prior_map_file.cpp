#include "commands/prior_map_file.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>

#include <nlohmann/json.hpp>

#include "outputs/plane_json.hpp"

namespace blockmap::cli {
namespace {

using JsonValue = nlohmann::json;

// A plane list's planes within 10 degrees of vertical, 1 m wide or more and seen well are
// walls seen. A stray piece of a few hundred returns far off the route would stretch the
// map's grid over nothing.
constexpr double kMaxWallTiltDeg = 10.0;
constexpr double kMinSeenWallM = 1.0;
constexpr double kMinSeenReturns = 1000.0;

// A position [longitude, latitude(, height)] in the local frame.
Eigen::Vector2d local_of(const JsonValue& position, const hal::LocalEnuFrame& frame) {
  if (!position.is_array() || position.size() < 2 || !position[0].is_number() ||
      !position[1].is_number()) {
    throw std::runtime_error("a position is not [longitude, latitude]");
  }
  const double longitude = position[0].get<double>();
  const double latitude = position[1].get<double>();
  if (!(std::abs(latitude) <= 90.0) || !(std::abs(longitude) <= 180.0)) {
    throw std::runtime_error("a position is not on Earth");
  }
  const Eigen::Vector3d enu =
      frame.to_enu_m(hal::GeodeticPoint{latitude, longitude, frame.origin().height_m});
  return enu.head<2>();
}

// Each consecutive pair of a line's positions is a wall; a polygon's rings enclose.
void add_line(const JsonValue& positions, const hal::LocalEnuFrame& frame, bool ring,
              std::vector<localize::MapWall>& walls) {
  if (!positions.is_array()) {
    throw std::runtime_error("a line's coordinates are not an array");
  }
  for (std::size_t k = 1; k < positions.size(); ++k) {
    walls.push_back({local_of(positions[k - 1], frame), local_of(positions[k], frame), ring});
  }
}

void add_geometry(const JsonValue& geometry, const hal::LocalEnuFrame& frame,
                  std::vector<localize::MapWall>& walls) {
  const std::string type = geometry.value("type", "");
  if (type == "GeometryCollection") {
    for (const JsonValue& part : geometry.at("geometries")) {
      add_geometry(part, frame, walls);
    }
    return;
  }
  const JsonValue& coordinates = geometry.at("coordinates");
  if (type == "LineString") {
    add_line(coordinates, frame, false, walls);
  } else if (type == "MultiLineString" || type == "Polygon") {
    for (const JsonValue& line : coordinates) {
      add_line(line, frame, type == "Polygon", walls);
    }
  } else if (type == "MultiPolygon") {
    for (const JsonValue& polygon : coordinates) {
      for (const JsonValue& ring : polygon) {
        add_line(ring, frame, true, walls);
      }
    }
  }  // points have no walls
}

void add_geojson(const JsonValue& document, const hal::LocalEnuFrame& frame,
                 std::vector<localize::MapWall>& walls) {
  const std::string type = document.value("type", "");
  if (type == "FeatureCollection") {
    for (const JsonValue& feature : document.at("features")) {
      add_geojson(feature, frame, walls);
    }
  } else if (type == "Feature") {
    if (!document.at("geometry").is_null()) {
      add_geometry(document.at("geometry"), frame, walls);
    }
  } else {
    add_geometry(document, frame, walls);
  }
}

Eigen::Vector2d point_of(const JsonValue& xy) {
  if (!xy.is_array() || xy.size() < 2 || !xy[0].is_number() || !xy[1].is_number()) {
    throw std::runtime_error("a footprint's corner is not [x, y]");
  }
  return {xy[0].get<double>(), xy[1].get<double>()};
}

// buildings.json: the footprints a run fitted (closed: their unseen walls are the fitter's
// guess, but what they enclose is a building).
void add_buildings(const JsonValue& document, std::vector<localize::MapWall>& walls) {
  for (const JsonValue& building : document.at("buildings")) {
    const JsonValue& footprint = building.at("footprint");
    for (std::size_t k = 0; footprint.size() >= 3 && k < footprint.size(); ++k) {
      walls.push_back(
          {point_of(footprint[k]), point_of(footprint[(k + 1) % footprint.size()]), true});
    }
  }
}

// planes.json: the vertical planes a run saw (walls, and what stands in front of them: a
// hedge, a fence), each its extent seen from above. They enclose nothing; a run's
// footprints, given beside them, say what is solid.
void add_planes_seen(const JsonValue& document, std::vector<localize::MapWall>& walls) {
  const double min_horizontal_normal = std::cos(kMaxWallTiltDeg * std::numbers::pi / 180.0);
  for (const msg::PlanePatch& plane : planes_from_json(document)) {
    const Eigen::Vector2d across = plane.normal.head<2>();
    if (across.norm() < min_horizontal_normal || plane.support < kMinSeenReturns) {
      continue;
    }
    const Eigen::Vector2d normal = across.normalized();
    const Eigen::Vector2d along(-normal.y(), normal.x());
    // Where the plane crosses its points' mean height: a tilted plane moves with height.
    const double offset_m = (plane.d_m - plane.normal.z() * plane.centroid_m.z()) / across.norm();
    const Eigen::Vector2d on_plane = normal * offset_m;
    double first_m = std::numeric_limits<double>::infinity();
    double last_m = -first_m;
    for (std::size_t k = 0; k < plane.polygon_size; ++k) {
      const double at_m = along.dot(plane.polygon_m[k].head<2>());
      first_m = std::min(first_m, at_m);
      last_m = std::max(last_m, at_m);
    }
    if (last_m - first_m >= kMinSeenWallM) {
      walls.push_back({on_plane + along * first_m, on_plane + along * last_m, false});
    }
  }
}

}  // namespace

std::vector<localize::MapWall> read_prior_map(const std::string& path,
                                              const hal::LocalEnuFrame& frame, std::string& error) {
  std::vector<localize::MapWall> walls;
  std::error_code code;
  if (!std::filesystem::is_regular_file(path, code)) {
    error = path + " is not a file";
    return walls;
  }
  std::ifstream in(path);
  const JsonValue document = JsonValue::parse(in, nullptr, false);
  if (document.is_discarded() || !document.is_object()) {
    error = path + " is not a JSON object (GeoJSON, buildings.json or planes.json)";
    return walls;
  }
  try {
    if (document.contains("buildings")) {
      add_buildings(document, walls);
    } else if (document.contains("planes")) {
      add_planes_seen(document, walls);
    } else {
      add_geojson(document, frame, walls);
    }
  } catch (const std::exception& e) {
    error = path + ": not a prior map: " + e.what();
    walls.clear();
    return walls;
  }
  if (walls.empty()) {
    error = path + " holds no wall (no line or polygon)";
  }
  return walls;
}

}  // namespace blockmap::cli
