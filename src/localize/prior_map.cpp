#include "blockmap/localize/prior_map.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "bilinear.hpp"

namespace blockmap::localize {
namespace {

constexpr const char* kOwner = "prior map";

double distance_to_segment_m(const Eigen::Vector2d& p, const MapWall& wall) noexcept {
  const Eigen::Vector2d along = wall.to_m - wall.from_m;
  const double length2 = along.squaredNorm();
  const double t =
      length2 > 0.0 ? std::clamp((p - wall.from_m).dot(along) / length2, 0.0, 1.0) : 0.0;
  return (wall.from_m + t * along - p).norm();
}

}  // namespace

std::string validate(const PriorMapConfig& config) {
  if (!config.enabled) {
    return {};
  }
  if (!(config.cell_m >= 0.05 && config.cell_m <= 1.0) || config.max_cells < 64 ||
      config.max_cells > (std::size_t{1} << 26U) || !(config.margin_m >= 0.0)) {
    return "prior_map: cell_m must be 0.05 to 1 m, max_cells 64 to 2^26, margin_m not "
           "negative";
  }
  if (config.particles < 16 || config.particles > 100000 || config.max_points < 4 ||
      config.max_points > 4096) {
    return "prior_map: particles must be 16 to 100000, max_points 4 to 4096";
  }
  if (!(config.hit_sigma_m > 0.0) || !(config.unmapped_share > 0.0) ||
      !(config.unmapped_share < 1.0) || !(config.inside_share > 0.0) ||
      !(config.inside_share <= 1.0) || !(config.independent_points > 0.0)) {
    return "prior_map: hit_sigma_m and independent_points must be positive, unmapped_share "
           "between 0 and 1, inside_share from 0 to 1 (of unmapped_share)";
  }
  if (!(config.update_spacing_m > 0.0) || !(config.update_turn_deg > 0.0) ||
      !(config.motion_sigma_m >= 0.0) || !(config.motion_sigma_per_m >= 0.0) ||
      !(config.turn_sigma_deg >= 0.0) || !(config.turn_sigma_deg_per_m >= 0.0) ||
      !(config.start_sigma_m >= 0.0) || !(config.start_after_m >= 0.0) ||
      !(config.start_yaw_sigma_deg >= 0.0)) {
    return "prior_map: update spacings must be positive, the motion's and start's sigmas and "
           "start_after_m not negative";
  }
  if (!(config.frame_sigma_m >= 0.0) || !std::isfinite(config.frame_sigma_m) ||
      !(config.frame_time_s > 0.0)) {
    return "prior_map: frame_sigma_m must not be negative and frame_time_s must be positive";
  }
  if (!(config.placing_gate_m > 0.0) || config.restart_after < 1 || config.lost_after < 1) {
    return "prior_map: placing_gate_m must be positive, restart_after and lost_after at least 1";
  }
  if (!(config.max_spread_m > 0.0) || !(config.max_placing_sigma_m > 0.0) ||
      !(config.min_hit_share >= 0.0) || !(config.min_hit_share <= 1.0) ||
      !(config.place_spacing_m >= 0.0) || !(config.min_sigma_m > 0.0)) {
    return "prior_map: max_spread_m, max_placing_sigma_m and min_sigma_m must be positive, "
           "min_hit_share 0 to 1, "
           "place_spacing_m not negative";
  }
  return {};
}

std::size_t PriorMap::arena_bytes(const PriorMapConfig& config) noexcept {
  return config.enabled ? Arena::array_bytes<std::uint8_t>(config.max_cells) : 0;
}

void PriorMap::init(Arena& arena, const PriorMapConfig& config) {
  config_ = config;
  if (config.enabled) {
    cells_ = arena.allocate_array<std::uint8_t>(config.max_cells, kOwner);
  }
}

std::string PriorMap::build(std::span<const MapWall> walls) {
  if (walls.empty()) {
    return "the prior map has no walls";
  }
  Eigen::Vector2d low = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector2d high = -low;
  for (const MapWall& wall : walls) {
    if (!wall.from_m.allFinite() || !wall.to_m.allFinite()) {
      return "the prior map has a wall whose corners are not finite";
    }
    low = low.cwiseMin(wall.from_m).cwiseMin(wall.to_m);
    high = high.cwiseMax(wall.from_m).cwiseMax(wall.to_m);
  }
  low.array() -= config_.margin_m;
  high.array() += config_.margin_m;
  const double across = std::ceil((high.x() - low.x()) / config_.cell_m);
  const double up = std::ceil((high.y() - low.y()) / config_.cell_m);
  if (across * up > static_cast<double>(cells_.size())) {
    char text[200];
    std::snprintf(text, sizeof text,
                  "the prior map spans %.0f by %.0f m: %.0f cells at %.2f m, over "
                  "prior_map.max_cells (%zu)",
                  high.x() - low.x(), high.y() - low.y(), across * up, config_.cell_m,
                  cells_.size());
    return text;
  }
  corner_m_ = low;
  across_ = static_cast<std::int64_t>(across);
  up_ = static_cast<std::int64_t>(up);
  std::fill(cells_.begin(), cells_.end(), kFarthest);
  for (const MapWall& wall : walls) {
    draw_wall(wall);
  }
  fill_inside(walls);
  wall_count_ = walls.size();
  return {};
}

void PriorMap::draw_wall(const MapWall& wall) noexcept {
  // Only the cells within kMaxDistanceM of the wall can come nearer than the cap.
  const double inverse_cell = 1.0 / config_.cell_m;
  const Eigen::Vector2d low =
      (wall.from_m.cwiseMin(wall.to_m).array() - kMaxDistanceM).matrix() - corner_m_;
  const Eigen::Vector2d high =
      (wall.from_m.cwiseMax(wall.to_m).array() + kMaxDistanceM).matrix() - corner_m_;
  const auto x0 = std::max<std::int64_t>(0, static_cast<std::int64_t>(low.x() * inverse_cell));
  const auto y0 = std::max<std::int64_t>(0, static_cast<std::int64_t>(low.y() * inverse_cell));
  const std::int64_t x1 = std::min(across_ - 1, static_cast<std::int64_t>(high.x() * inverse_cell));
  const std::int64_t y1 = std::min(up_ - 1, static_cast<std::int64_t>(high.y() * inverse_cell));
  for (std::int64_t y = y0; y <= y1; ++y) {
    for (std::int64_t x = x0; x <= x1; ++x) {
      const Eigen::Vector2d centre =
          corner_m_ + Eigen::Vector2d((static_cast<double>(x) + 0.5) * config_.cell_m,
                                      (static_cast<double>(y) + 0.5) * config_.cell_m);
      const double steps = std::round(distance_to_segment_m(centre, wall) / kStepM);
      std::uint8_t& cell = cells_[static_cast<std::size_t>(y * across_ + x)];
      cell = static_cast<std::uint8_t>(std::min<double>(cell, std::min<double>(steps, kFarthest)));
    }
  }
}

void PriorMap::fill_inside(std::span<const MapWall> walls) {
  std::vector<double> crossings_m;  // at start-up
  for (std::int64_t y = 0; y < up_; ++y) {
    const double row_m = corner_m_.y() + (static_cast<double>(y) + 0.5) * config_.cell_m;
    crossings_m.clear();
    for (const MapWall& wall : walls) {
      const Eigen::Vector2d& a = wall.from_m;
      const Eigen::Vector2d& b = wall.to_m;
      if (wall.encloses && (a.y() <= row_m) != (b.y() <= row_m)) {
        crossings_m.push_back(a.x() + (row_m - a.y()) * (b.x() - a.x()) / (b.y() - a.y()));
      }
    }
    std::sort(crossings_m.begin(), crossings_m.end());
    for (std::size_t k = 0; k + 1 < crossings_m.size(); k += 2) {
      const double from = (crossings_m[k] - corner_m_.x()) / config_.cell_m - 0.5;
      const double to = (crossings_m[k + 1] - corner_m_.x()) / config_.cell_m - 0.5;
      for (auto x = std::max<std::int64_t>(0, static_cast<std::int64_t>(std::ceil(from)));
           x <= std::min(across_ - 1, static_cast<std::int64_t>(std::floor(to))); ++x) {
        cells_[static_cast<std::size_t>(y * across_ + x)] |= kInside;
      }
    }
  }
}

double PriorMap::distance_m(const Eigen::Vector2d& point_m) const noexcept {
  const auto cell = [this](std::int64_t x, std::int64_t y) -> double {
    if (x < 0 || y < 0 || x >= across_ || y >= up_) {
      return double{kFarthest};
    }
    return cells_[static_cast<std::size_t>(y * across_ + x)] & kFarthest;
  };
  const Eigen::Vector2d from_corner = point_m - corner_m_;
  return bilinear::sample(from_corner.x(), from_corner.y(), 1.0 / config_.cell_m, cell).value *
         kStepM;
}

bool PriorMap::inside(const Eigen::Vector2d& point_m) const noexcept {
  const Eigen::Vector2d cell = (point_m - corner_m_) / config_.cell_m;
  const auto x = static_cast<std::int64_t>(std::floor(cell.x()));
  const auto y = static_cast<std::int64_t>(std::floor(cell.y()));
  if (x < 0 || y < 0 || x >= across_ || y >= up_) {
    return false;
  }
  return (cells_[static_cast<std::size_t>(y * across_ + x)] & kInside) != 0;
}

Eigen::Matrix2d PriorMap::normal_outer(const Eigen::Vector2d& point_m) const noexcept {
  // Second differences of d^2 two cells either way (x, y and the diagonals): one cell's
  // 2 h^2 would drown in the distances' steps.
  const double h = 2.0 * config_.cell_m;
  const auto squared = [&](double dx, double dy) {
    const double d = distance_m(point_m + Eigen::Vector2d(dx, dy));
    return d * d;
  };
  const double centre = squared(0.0, 0.0);
  const double xx = squared(h, 0.0) + squared(-h, 0.0) - 2.0 * centre;
  const double yy = squared(0.0, h) + squared(0.0, -h) - 2.0 * centre;
  const double xy = (squared(h, h) + squared(-h, -h) - squared(h, -h) - squared(-h, h)) / 4.0;
  Eigen::Matrix2d curvature{{xx, xy}, {xy, yy}};
  const double trace = xx + yy;
  if (!(trace > 0.0)) {
    return Eigen::Matrix2d::Zero();
  }
  return curvature / trace;
}

}  // namespace blockmap::localize
