#include "outputs/plane_picture.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "blockmap/core/angles.hpp"

namespace blockmap::cli {
namespace {

// Screen axes of an orthographic camera: right, up (on screen) and towards the viewer.
struct Camera {
  Eigen::Vector3d right;
  Eigen::Vector3d up;
  Eigen::Vector3d towards_viewer;
};

Camera camera_for(const PictureView& view) {
  const double azimuth = view.azimuth_deg * kRadiansPerDegree;
  const double elevation = view.elevation_deg * kRadiansPerDegree;
  const Eigen::Vector3d towards(std::cos(elevation) * std::cos(azimuth),
                                std::cos(elevation) * std::sin(azimuth), std::sin(elevation));
  // Horizontal, to the viewer's right (also when looking straight down).
  const Eigen::Vector3d right(-std::sin(azimuth), std::cos(azimuth), 0.0);
  return {right, towards.cross(right), towards};
}

// Screen coordinates in pixels: the projected bounding box of the points scaled into the
// picture with a margin, y downwards as SVG has it.
class Projection {
 public:
  Projection(Camera camera, std::span<const Eigen::Vector3f> points_m, int width_px)
      : camera_(std::move(camera)) {
    Eigen::Vector2d low = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
    Eigen::Vector2d high = -low;
    for (const Eigen::Vector3f& p : points_m) {
      const Eigen::Vector2d s = plane_coordinates(p.cast<double>());
      low = low.cwiseMin(s);
      high = high.cwiseMax(s);
    }
    if (points_m.empty()) {
      low.setZero();
      high.setOnes();
    }
    low_ = low;
    const Eigen::Vector2d extent = (high - low).cwiseMax(1e-3);
    scale_ = (width_px - 2.0 * kMarginPx) / extent.x();
    height_px_ = static_cast<int>(std::ceil(extent.y() * scale_ + 2.0 * kMarginPx));
    high_y_ = high.y();
  }
  [[nodiscard]] Eigen::Vector2d to_screen(const Eigen::Vector3d& p) const {
    const Eigen::Vector2d s = plane_coordinates(p);
    return {kMarginPx + (s.x() - low_.x()) * scale_, kMarginPx + (high_y_ - s.y()) * scale_};
  }
  [[nodiscard]] double depth(const Eigen::Vector3d& p) const {
    return p.dot(camera_.towards_viewer);
  }
  [[nodiscard]] int height_px() const { return height_px_; }

 private:
  static constexpr double kMarginPx = 20.0;
  [[nodiscard]] Eigen::Vector2d plane_coordinates(const Eigen::Vector3d& p) const {
    return {p.dot(camera_.right), p.dot(camera_.up)};
  }
  Camera camera_;
  Eigen::Vector2d low_ = Eigen::Vector2d::Zero();
  double high_y_ = 0.0;
  double scale_ = 1.0;
  int height_px_ = 0;
};

const char* fill_of(msg::PlaneKind kind) {
  switch (kind) {
    case msg::PlaneKind::kWall:
      return "#d0452f";
    case msg::PlaneKind::kRoof:
      return "#2f6fd0";
    case msg::PlaneKind::kGround:
      return "#3a9a48";
    case msg::PlaneKind::kOther:
      return "#8a8a8a";
  }
  return "#8a8a8a";
}

std::string number(double value) {
  std::array<char, 32> text{};
  const int length = std::snprintf(text.data(), text.size(), "%.1f", value);
  return {text.data(), static_cast<std::size_t>(std::max(length, 0))};
}

// The points, thinned to the budget, in a few shades of grey by height (darker low): one path
// per shade, each dot a one-pixel stroke.
void write_points(std::ostream& out, std::span<const Eigen::Vector3f> points_m,
                  const Projection& projection, std::size_t max_points) {
  constexpr std::size_t kShades = 6;
  if (points_m.empty()) {
    return;
  }
  float z_low = std::numeric_limits<float>::infinity();
  float z_high = -z_low;
  for (const Eigen::Vector3f& p : points_m) {
    z_low = std::min(z_low, p.z());
    z_high = std::max(z_high, p.z());
  }
  const std::size_t stride =
      std::max<std::size_t>(1, (points_m.size() + max_points - 1) / max_points);
  const float span = std::max(z_high - z_low, 1e-3f);
  std::array<std::string, kShades> paths;
  for (std::size_t i = 0; i < points_m.size(); i += stride) {
    const Eigen::Vector3f& p = points_m[i];
    const auto shade = std::min<std::size_t>(
        kShades - 1,
        static_cast<std::size_t>((p.z() - z_low) / span * static_cast<float>(kShades)));
    const Eigen::Vector2d s = projection.to_screen(p.cast<double>());
    paths[shade] += 'M' + number(s.x()) + ' ' + number(s.y()) + "h1";
  }
  for (std::size_t shade = 0; shade < kShades; ++shade) {
    if (paths[shade].empty()) {
      continue;
    }
    const int grey = 40 + static_cast<int>(shade) * 150 / static_cast<int>(kShades - 1);
    out << "<path stroke='rgb(" << grey << ',' << grey << ',' << grey
        << ")' stroke-width='1.4' stroke-linecap='square' d='" << paths[shade] << "'/>\n";
  }
}

void write_planes(std::ostream& out, std::span<const msg::PlanePatch> planes,
                  const Projection& projection) {
  // Far planes first, so that near ones are drawn over them.
  std::vector<const msg::PlanePatch*> order;
  for (const msg::PlanePatch& plane : planes) {
    order.push_back(&plane);
  }
  std::stable_sort(order.begin(), order.end(),
                   [&](const msg::PlanePatch* a, const msg::PlanePatch* b) {
                     return projection.depth(a->centroid_m) < projection.depth(b->centroid_m);
                   });
  for (const msg::PlanePatch* plane : order) {
    out << "<polygon class='" << msg::to_string(plane->kind) << "' fill='" << fill_of(plane->kind)
        << "' fill-opacity='0.45' stroke='" << fill_of(plane->kind)
        << "' stroke-width='1.5' points='";
    for (std::size_t i = 0; i < plane->polygon_size; ++i) {
      const Eigen::Vector2d s = projection.to_screen(plane->polygon_m[i]);
      out << (i == 0 ? "" : " ") << number(s.x()) << ',' << number(s.y());
    }
    out << "'><title>plane " << plane->id << ": " << msg::to_string(plane->kind) << ", "
        << static_cast<long long>(plane->support) << " points</title></polygon>\n";
  }
}

}  // namespace

void write_plane_picture(std::ostream& out, std::span<const Eigen::Vector3f> points_m,
                         std::span<const msg::PlanePatch> planes, const PictureView& view) {
  const Projection projection(camera_for(view), points_m, view.width_px);
  out << "<svg xmlns='http://www.w3.org/2000/svg' width='" << view.width_px << "' height='"
      << projection.height_px() << "' viewBox='0 0 " << view.width_px << ' '
      << projection.height_px() << "'>\n<rect width='100%' height='100%' fill='white'/>\n";
  write_points(out, points_m, projection, view.max_points);
  write_planes(out, planes, projection);
  out << "<text x='20' y='16' font-family='sans-serif' font-size='13'>" << planes.size()
      << " planes over " << points_m.size()
      << " points: walls red, roofs blue, ground green, other grey</text>\n</svg>\n";
}

}  // namespace blockmap::cli
