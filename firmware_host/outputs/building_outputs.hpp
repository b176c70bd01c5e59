// Buildings out: the buildings JSON (docs/formats.md, buildings), GeoJSON footprints in WGS-84 that
// GIS tools open (RFC 7946), and a top-view picture (SVG) of points, walls and footprints with
// the observed walls dark and the virtual ones light and dashed, as the paper draws them.
#pragma once

#include <ostream>
#include <span>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "blockmap/buildings/building.hpp"
#include "blockmap/hal/geodesy.hpp"
#include "blockmap/localize/localizer.hpp"
#include "blockmap/msg/plane_patch.hpp"

namespace blockmap::cli {

// {"buildings": [{"id", "shape", "height", "ground_z", "confidence", "height_from": "roof" |
// "walls", "footprint": [[x, y], ...], "walls": [{"p0", "p1", "z0", "z1", "virtual",
// "plane"}]}]}; "plane" is null for a virtual wall.
[[nodiscard]] nlohmann::json buildings_json(std::span<const buildings::Building> buildings);

// A GeoJSON Feature: the footprint (counter-clockwise, in the local frame) as a closed
// Polygon in WGS-84 ([longitude, latitude]), with `properties`.
[[nodiscard]] nlohmann::json footprint_feature(std::span<const Eigen::Vector2d> footprint_m,
                                               double ground_z_m, const hal::LocalEnuFrame& frame,
                                               nlohmann::json properties);

// A FeatureCollection: one Polygon per building with a footprint (closed, counter-clockwise,
// [longitude, latitude]) and its id, shape, height and confidence as properties.
[[nodiscard]] nlohmann::json footprints_geojson(std::span<const buildings::Building> buildings,
                                                const hal::LocalEnuFrame& frame);

// The picture from above; points may be empty (a plane list has none), and so may the path
// the robot took (a green line).
void write_buildings_picture(std::ostream& out, std::span<const Eigen::Vector3f> points_m,
                             std::span<const msg::PlanePatch> planes,
                             std::span<const buildings::Building> buildings,
                             std::span<const localize::Pose3> path = {});

}  // namespace blockmap::cli
