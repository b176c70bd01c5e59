// Geodetic coordinates <-> the local East-North-Up frame the mapper works in (docs/formats.md,
// frames: metres, anchored at the first good GPS fix or a configured origin). The
// conversions are GeographicLib's (WGS-84 ellipsoid), not hand-written.
#pragma once

#include <GeographicLib/LocalCartesian.hpp>

#include <Eigen/Core>

namespace blockmap::hal {

struct GeodeticPoint {
  double latitude_deg = 0.0;   // WGS-84, north positive
  double longitude_deg = 0.0;  // WGS-84, east positive
  double height_m = 0.0;       // above the WGS-84 ellipsoid
};

class LocalEnuFrame {
 public:
  // `origin` must be a real place: |latitude| <= 90 and |longitude| <= 180 (CHECK).
  explicit LocalEnuFrame(const GeodeticPoint& origin);

  [[nodiscard]] const GeodeticPoint& origin() const noexcept { return origin_; }
  [[nodiscard]] Eigen::Vector3d to_enu_m(const GeodeticPoint& point) const;
  [[nodiscard]] GeodeticPoint to_geodetic(const Eigen::Vector3d& enu_m) const;

 private:
  GeodeticPoint origin_;
  GeographicLib::LocalCartesian projection_;
};

}  // namespace blockmap::hal
