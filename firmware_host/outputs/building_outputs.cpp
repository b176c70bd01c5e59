#include "outputs/building_outputs.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include "blockmap/buildings/building_fitter.hpp"
#include "outputs/plane_json.hpp"

namespace blockmap::cli {
namespace {

nlohmann::json xy_json(const Eigen::Vector2d& p) {
  return nlohmann::json::array({rounded_to(p.x(), 1e-4), rounded_to(p.y(), 1e-4)});
}

nlohmann::json wall_json(const buildings::BuildingWall& wall) {
  return {{"p0", xy_json(wall.p0_m)},
          {"p1", xy_json(wall.p1_m)},
          {"z0", rounded_to(wall.z0_m, 1e-4)},
          {"z1", rounded_to(wall.z1_m, 1e-4)},
          {"virtual", wall.is_virtual},
          {"plane", wall.is_virtual ? nlohmann::json(nullptr) : nlohmann::json(wall.plane_id)}};
}

// Screen coordinates of the top view: x east, y north up the picture.
class TopView {
 public:
  TopView(const Eigen::Vector2d& low_m, const Eigen::Vector2d& high_m, double width_px)
      : low_(low_m), high_y_(high_m.y()) {
    const Eigen::Vector2d extent = (high_m - low_m).cwiseMax(1.0);
    scale_ = (width_px - 2.0 * kMarginPx) / extent.x();
    width_px_ = width_px;
    height_px_ = extent.y() * scale_ + 2.0 * kMarginPx;
  }
  [[nodiscard]] Eigen::Vector2d to_screen(const Eigen::Vector2d& p) const {
    return {kMarginPx + (p.x() - low_.x()) * scale_, kMarginPx + (high_y_ - p.y()) * scale_};
  }
  [[nodiscard]] double width_px() const { return width_px_; }
  [[nodiscard]] double height_px() const { return height_px_; }
  [[nodiscard]] double scale() const { return scale_; }

 private:
  static constexpr double kMarginPx = 20.0;
  Eigen::Vector2d low_;
  double high_y_ = 0.0;
  double scale_ = 1.0;
  double width_px_ = 0.0;
  double height_px_ = 0.0;
};

void line(std::ostream& out, const TopView& view, const Eigen::Vector2d& a,
          const Eigen::Vector2d& b, const char* style) {
  const Eigen::Vector2d s = view.to_screen(a);
  const Eigen::Vector2d e = view.to_screen(b);
  char text[256];
  std::snprintf(text, sizeof text, "<line x1=\"%.1f\" y1=\"%.1f\" x2=\"%.1f\" y2=\"%.1f\" %s/>\n",
                s.x(), s.y(), e.x(), e.y(), style);
  out << text;
}

}  // namespace

nlohmann::json buildings_json(std::span<const buildings::Building> buildings) {
  nlohmann::json list = nlohmann::json::array();
  for (const buildings::Building& building : buildings) {
    nlohmann::json footprint = nlohmann::json::array();
    for (std::size_t k = 0; k < building.footprint_size; ++k) {
      footprint.push_back(xy_json(building.footprint_m[k]));
    }
    nlohmann::json walls = nlohmann::json::array();
    for (std::size_t w = 0; w < building.wall_count; ++w) {
      walls.push_back(wall_json(building.walls[w]));
    }
    list.push_back({{"id", building.id},
                    {"shape", std::string(buildings::to_string(building.shape))},
                    {"height", rounded_to(building.height_m, 1e-3)},
                    {"ground_z", rounded_to(building.ground_z_m, 1e-3)},
                    {"height_from", building.height_from_roof ? "roof" : "walls"},
                    {"confidence", rounded_to(building.confidence, 1e-3)},
                    {"footprint", footprint},
                    {"walls", walls}});
  }
  return {{"buildings", list}};
}

nlohmann::json footprint_feature(std::span<const Eigen::Vector2d> footprint_m, double ground_z_m,
                                 const hal::LocalEnuFrame& frame, nlohmann::json properties) {
  nlohmann::json ring = nlohmann::json::array();
  for (std::size_t k = 0; k <= footprint_m.size(); ++k) {
    const Eigen::Vector2d& p = footprint_m[k % footprint_m.size()];
    const hal::GeodeticPoint g = frame.to_geodetic(Eigen::Vector3d(p.x(), p.y(), ground_z_m));
    // RFC 7946: longitude first; 1e-8 degrees is a millimetre.
    ring.push_back({rounded_to(g.longitude_deg, 1e-8), rounded_to(g.latitude_deg, 1e-8)});
  }
  return {{"type", "Feature"},
          {"geometry", {{"type", "Polygon"}, {"coordinates", nlohmann::json::array({ring})}}},
          {"properties", std::move(properties)}};
}

nlohmann::json footprints_geojson(std::span<const buildings::Building> buildings,
                                  const hal::LocalEnuFrame& frame) {
  nlohmann::json features = nlohmann::json::array();
  for (const buildings::Building& building : buildings) {
    if (building.footprint_size < 3) {
      continue;  // unknown: no footprint to draw
    }
    features.push_back(footprint_feature(
        std::span(building.footprint_m).first(building.footprint_size), building.ground_z_m, frame,
        {{"id", building.id},
         {"shape", std::string(buildings::to_string(building.shape))},
         {"height_m", rounded_to(building.height_m, 1e-3)},
         {"confidence", rounded_to(building.confidence, 1e-3)}}));
  }
  return {{"type", "FeatureCollection"}, {"features", features}};
}

void write_buildings_picture(std::ostream& out, std::span<const Eigen::Vector3f> points_m,
                             std::span<const msg::PlanePatch> planes,
                             std::span<const buildings::Building> buildings,
                             std::span<const localize::Pose3> path) {
  Eigen::Vector2d low = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector2d high = -low;
  const auto grow = [&](const Eigen::Vector2d& p) {
    low = low.cwiseMin(p);
    high = high.cwiseMax(p);
  };
  for (const Eigen::Vector3f& p : points_m) {
    grow(p.head<2>().cast<double>());
  }
  for (const msg::PlanePatch& plane : planes) {
    for (std::size_t i = 0; i < plane.polygon_size; ++i) {
      grow(plane.polygon_m[i].head<2>());
    }
  }
  for (const localize::Pose3& pose : path) {
    grow(Eigen::Vector2d(pose.x_m, pose.y_m));
  }
  for (const buildings::Building& building : buildings) {
    for (std::size_t w = 0; w < building.wall_count; ++w) {
      grow(building.walls[w].p0_m);
      grow(building.walls[w].p1_m);
    }
  }
  if (!std::isfinite(low.x())) {
    low.setZero();
    high.setOnes();
  }
  const TopView view(low, high, 1400.0);
  char header[256];
  std::snprintf(header, sizeof header,
                "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"%.0f\" height=\"%.0f\">\n"
                "<rect width=\"100%%\" height=\"100%%\" fill=\"white\"/>\n",
                view.width_px(), view.height_px());
  out << header;
  // Points, thinned to about 40,000 dots.
  const std::size_t stride = std::max<std::size_t>(1, points_m.size() / 40000);
  out << "<g fill=\"#9a9a9a\">\n";
  for (std::size_t i = 0; i < points_m.size(); i += stride) {
    const Eigen::Vector2d s = view.to_screen(points_m[i].head<2>().cast<double>());
    char dot[96];
    std::snprintf(dot, sizeof dot, "<rect x=\"%.1f\" y=\"%.1f\" width=\"1\" height=\"1\"/>\n",
                  s.x(), s.y());
    out << dot;
  }
  out << "</g>\n";
  if (path.size() >= 2) {
    out << R"(<polyline fill="none" stroke="#2a9d3a" stroke-width="1.5" points=")";
    for (std::size_t k = 0; k < path.size(); ++k) {
      const Eigen::Vector2d s = view.to_screen(Eigen::Vector2d(path[k].x_m, path[k].y_m));
      char point[48];
      std::snprintf(point, sizeof point, "%s%.1f,%.1f", k == 0 ? "" : " ", s.x(), s.y());
      out << point;
    }
    out << "\"/>\n";
  }
  // The vertical planes, thin red: what the buildings were made from.
  for (const msg::PlanePatch& plane : planes) {
    buildings::WallSegment segment;
    if (plane.kind != msg::PlaneKind::kGround && plane.kind != msg::PlaneKind::kRoof &&
        buildings::wall_segment_of(plane, segment)) {
      line(out, view, segment.p0_m, segment.p1_m,
           plane.kind == msg::PlaneKind::kWall ? R"(stroke="#d03030" stroke-width="1.5")"
                                               : R"(stroke="#e09090" stroke-width="1")");
    }
  }
  // Footprints, filled light; then walls: observed dark and solid, virtual light and dashed.
  for (const buildings::Building& building : buildings) {
    if (building.footprint_size < 3) {
      continue;
    }
    out << R"(<polygon fill="#e8d9b0" fill-opacity="0.6" stroke="none" points=")";
    for (std::size_t k = 0; k < building.footprint_size; ++k) {
      const Eigen::Vector2d s = view.to_screen(building.footprint_m[k]);
      char point[48];
      std::snprintf(point, sizeof point, "%s%.1f,%.1f", k == 0 ? "" : " ", s.x(), s.y());
      out << point;
    }
    out << "\"/>\n";
  }
  for (const buildings::Building& building : buildings) {
    for (std::size_t w = 0; w < building.wall_count; ++w) {
      const buildings::BuildingWall& wall = building.walls[w];
      line(out, view, wall.p0_m, wall.p1_m,
           wall.is_virtual ? R"(stroke="#7fa7d9" stroke-width="3" stroke-dasharray="8,5")"
                           : R"(stroke="#1f3b73" stroke-width="4")");
    }
    if (building.footprint_size >= 3) {
      Eigen::Vector2d centre = Eigen::Vector2d::Zero();
      for (std::size_t k = 0; k < building.footprint_size; ++k) {
        centre += building.footprint_m[k];
      }
      const Eigen::Vector2d s = view.to_screen(centre / building.footprint_size);
      char label[160];
      std::snprintf(label, sizeof label,
                    "<text x=\"%.1f\" y=\"%.1f\" font-family=\"sans-serif\" font-size=\"14\" "
                    "text-anchor=\"middle\">%u %s</text>\n",
                    s.x(), s.y(), building.id,
                    std::string(buildings::to_string(building.shape)).c_str());
      out << label;
    }
  }
  out << "</svg>\n";
}

}  // namespace blockmap::cli
