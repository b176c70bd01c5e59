// The prior 2D map `replay --prior-map FILE` localizes against (docs/localize.md, A prior
// map): building footprints as GeoJSON in WGS-84 (RFC 7946: Polygon, MultiPolygon,
// LineString and MultiLineString geometries, in a FeatureCollection, a Feature or bare), such
// as an earlier run's footprints.geojson or a GIS layer; or an earlier run's buildings.json
// (docs/formats.md, buildings: its footprints, in the local frame of that run's origin); or an
// earlier run's planes.json (its vertical planes seen from above, in that frame too).
// Polygons' rings enclose solid ground (MapWall::encloses); lines and planes are walls alone.
#pragma once

#include <string>
#include <vector>

#include "blockmap/hal/geodesy.hpp"
#include "blockmap/localize/prior_map.hpp"

namespace blockmap::cli {

// The map's walls in `frame`; empty with `error` set when the file cannot be read, is not one
// of the formats above, or holds no wall.
[[nodiscard]] std::vector<localize::MapWall> read_prior_map(const std::string& path,
                                                            const hal::LocalEnuFrame& frame,
                                                            std::string& error);

}  // namespace blockmap::cli
