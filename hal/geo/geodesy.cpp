#include "blockmap/hal/geodesy.hpp"

#include <cmath>

#include "blockmap/core/check.hpp"

namespace blockmap::hal {
namespace {

const GeodeticPoint& checked(const GeodeticPoint& origin) {
  BLOCKMAP_CHECK_MSG(
      std::abs(origin.latitude_deg) <= 90.0 && std::abs(origin.longitude_deg) <= 180.0,
      "geodetic origin out of range");
  return origin;
}

}  // namespace

LocalEnuFrame::LocalEnuFrame(const GeodeticPoint& origin)
    : origin_(checked(origin)),
      projection_(origin.latitude_deg, origin.longitude_deg, origin.height_m) {}

Eigen::Vector3d LocalEnuFrame::to_enu_m(const GeodeticPoint& point) const {
  Eigen::Vector3d enu;
  projection_.Forward(point.latitude_deg, point.longitude_deg, point.height_m, enu.x(), enu.y(),
                      enu.z());
  return enu;
}

GeodeticPoint LocalEnuFrame::to_geodetic(const Eigen::Vector3d& enu_m) const {
  GeodeticPoint point;
  projection_.Reverse(enu_m.x(), enu_m.y(), enu_m.z(), point.latitude_deg, point.longitude_deg,
                      point.height_m);
  return point;
}

}  // namespace blockmap::hal
