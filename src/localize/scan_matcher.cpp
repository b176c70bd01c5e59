#include "blockmap/localize/scan_matcher.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <numbers>

#include <Eigen/Cholesky>

#include "bilinear.hpp"
#include "blockmap/core/angles.hpp"
#include "blockmap/core/check.hpp"
#include "blockmap/core/floor_div.hpp"

namespace blockmap::localize {
namespace {

// A cell holds its hits (two at most: two make it fully occupied, one half so, so a single
// stray return, a person or a leaf, weighs half a surface) in its low bits, and the epoch of
// its last hit above them (ScanMatchConfig::forget_after_m).
constexpr std::uint8_t kHitsMask = 0x3;
constexpr int kEpochShift = 2;
constexpr std::uint32_t kEpochMask = 0x3F;
constexpr std::array<double, 3> kValueOfHits = {0.0, 128.0 / 255.0, 1.0};
// A cell lives this many epochs after its last hit: forget_after_m is this many epochs long.
constexpr std::uint32_t kEpochsKept = 4;
// The value from which a point counts as on the map (between two half-occupied cells).
constexpr double kOnMapValue = 0.25;
// The prior's weight on yaw is its weight on position times this lever squared: a turn of a
// radian moves a return this far from the robot by as many metres.
constexpr double kPriorLeverM = 10.0;

std::int64_t cell_of(double coordinate_m, double inverse_cell_m) noexcept {
  return static_cast<std::int64_t>(std::floor(coordinate_m * inverse_cell_m));
}

// `from` moved by the motion from `odometry_before` to `odometry_now`, taken in the robot's
// own frame (so that a corrected heading carries the motion along it).
Pose2 moved_by(const Pose2& from, const Pose2& odometry_before,
               const Pose2& odometry_now) noexcept {
  const double dx = odometry_now.x_m - odometry_before.x_m;
  const double dy = odometry_now.y_m - odometry_before.y_m;
  const double c = std::cos(odometry_before.yaw_rad);
  const double s = std::sin(odometry_before.yaw_rad);
  const double forward_m = c * dx + s * dy;
  const double left_m = -s * dx + c * dy;
  const double fc = std::cos(from.yaw_rad);
  const double fs = std::sin(from.yaw_rad);
  return {odometry_now.stamp_ns, from.x_m + fc * forward_m - fs * left_m,
          from.y_m + fs * forward_m + fc * left_m,
          wrap_angle(from.yaw_rad + wrap_angle(odometry_now.yaw_rad - odometry_before.yaw_rad))};
}

}  // namespace

std::string validate(const ScanMatchConfig& config) {
  if (!config.enabled) {
    return {};
  }
  if (!(config.cell_m >= 0.01 && config.cell_m <= 1.0)) {
    return "scan_matching: cell_m must be 0.01 to 1 m";
  }
  if (!std::has_single_bit(config.cells_across) || config.cells_across < 64 ||
      config.cells_across > 8192) {
    return "scan_matching: cells_across must be a power of two from 64 to 8192";
  }
  if (config.levels < 1 || config.levels > 6 || (config.cells_across >> (config.levels - 1)) < 16) {
    return "scan_matching: levels must be 1 to 6, the coarsest at least 16 cells across";
  }
  if (config.iterations < 1 || config.iterations > 20) {
    return "scan_matching: iterations must be 1 to 20";
  }
  if (!(config.max_height_m > config.min_height_m) || !(config.point_spacing_m >= 0.0) ||
      !(config.max_match_range_m > 0.0)) {
    return "scan_matching: min_height_m must be below max_height_m, point_spacing_m not "
           "negative, max_match_range_m positive";
  }
  if (config.max_points < 3 || config.min_points < 3 || config.min_points > config.max_points) {
    return "scan_matching: need 3 <= min_points <= max_points";
  }
  if (!(config.min_overlap >= 0.0 && config.min_overlap <= 1.0) || !(config.max_step_m > 0.0) ||
      !(config.max_step_rad > 0.0)) {
    return "scan_matching: min_overlap must be in [0, 1], max_step_m and max_step_rad positive";
  }
  if (!(config.forget_after_m >= 0.0)) {
    return "scan_matching: forget_after_m must not be negative (0: never forget)";
  }
  if (!(config.map_update_m >= 0.0) || !(config.map_update_rad >= 0.0)) {
    return "scan_matching: map_update_m and map_update_rad must not be negative";
  }
  if (!(config.anchor_time_s >= 0.0) || !(config.anchor_heading_lever_m >= 0.0) ||
      !(config.prior_weight > 0.0)) {
    return "scan_matching: anchor_time_s and anchor_heading_lever_m must not be negative, "
           "prior_weight positive";
  }
  if (!(config.yaw_rate_bias_time_s >= 0.0)) {
    return "scan_matching: yaw_rate_bias_time_s must not be negative";
  }
  return {};
}

PlanarCorrection motion_between(const Pose2& from, const Pose2& to) noexcept {
  PlanarCorrection out;
  out.yaw_rad = wrap_angle(to.yaw_rad - from.yaw_rad);
  out.cos_yaw = std::cos(out.yaw_rad);
  out.sin_yaw = std::sin(out.yaw_rad);
  out.x_m = to.x_m - (out.cos_yaw * from.x_m - out.sin_yaw * from.y_m);
  out.y_m = to.y_m - (out.sin_yaw * from.x_m + out.cos_yaw * from.y_m);
  return out;
}

Eigen::Vector3d pose_in_frame_of(const Pose2& from, const Pose2& to) noexcept {
  const double c = std::cos(from.yaw_rad);
  const double s = std::sin(from.yaw_rad);
  const double dx = to.x_m - from.x_m;
  const double dy = to.y_m - from.y_m;
  return {c * dx + s * dy, -s * dx + c * dy, wrap_angle(to.yaw_rad - from.yaw_rad)};
}

PlanarCorrection compose(const PlanarCorrection& second, const PlanarCorrection& first) noexcept {
  PlanarCorrection out;
  out.yaw_rad = wrap_angle(second.yaw_rad + first.yaw_rad);
  out.cos_yaw = std::cos(out.yaw_rad);
  out.sin_yaw = std::sin(out.yaw_rad);
  const Eigen::Vector2d shift_m = second.apply(Eigen::Vector2d(first.x_m, first.y_m));
  out.x_m = shift_m.x();
  out.y_m = shift_m.y();
  return out;
}

Pose2 PlanarCorrection::apply(const Pose2& raw) const noexcept {
  const Eigen::Vector2d position_m = apply(Eigen::Vector2d(raw.x_m, raw.y_m));
  return {raw.stamp_ns, position_m.x(), position_m.y(), wrap_angle(raw.yaw_rad + yaw_rad)};
}

void PlanarCorrection::apply(std::span<Eigen::Vector3f> points_m) const noexcept {
  if (identity()) {
    return;
  }
  for (Eigen::Vector3f& point : points_m) {
    const Eigen::Vector2d moved_m = apply(Eigen::Vector2d(point.x(), point.y()));
    point.x() = static_cast<float>(moved_m.x());
    point.y() = static_cast<float>(moved_m.y());
  }
}

void ScanMatcher::init(Arena& arena, const ScanMatchConfig& config) {
  BLOCKMAP_CHECK_MSG(validate(config).empty(), "an invalid scan matching configuration");
  config_ = config;
  if (!config.enabled) {
    return;
  }
  levels_ = arena.allocate_array<Level>(config.levels, "localize.scan_matcher");
  for (std::size_t l = 0; l < levels_.size(); ++l) {
    Level& level = levels_[l];
    level.across = std::int64_t{config.cells_across} >> l;
    level.cell_m = config.cell_m * static_cast<double>(std::int64_t{1} << l);
    level.inverse_cell_m = 1.0 / level.cell_m;
    level.cells = arena.allocate_array<std::uint8_t>(
        static_cast<std::size_t>(level.across * level.across), "localize.scan_matcher");
  }
  scan_m_ = arena.allocate_array<Eigen::Vector2d>(config.max_points, "localize.scan_matcher");
  scan_normals_ = arena.allocate_array<Eigen::Vector2d>(config.max_points, "localize.scan_matcher");
}

std::size_t ScanMatcher::arena_bytes(const ScanMatchConfig& config) noexcept {
  if (!config.enabled) {
    return 0;
  }
  constexpr std::size_t kSlack = 64;
  std::size_t bytes = std::size_t{config.levels} * sizeof(Level) +
                      2 * std::size_t{config.max_points} * sizeof(Eigen::Vector2d);
  for (std::uint32_t l = 0; l < config.levels; ++l) {
    const std::size_t across = config.cells_across >> l;
    bytes += across * across + kSlack;
  }
  return bytes + 2 * kSlack;
}

std::size_t ScanMatcher::memory_bytes() const noexcept {
  std::size_t bytes = levels_.size_bytes() + scan_m_.size_bytes() + scan_normals_.size_bytes();
  for (const Level& level : levels_) {
    bytes += level.cells.size_bytes();
  }
  return bytes;
}

void ScanMatcher::reset() noexcept {
  placed_ = false;
  have_last_ = false;
  have_update_ = false;
  tracking_ = false;
  correction_ = {};
  to_grid_ = {};
  anchor_ = {};
  ++counters_.resets;
}

// --- The grid ------------------------------------------------------------------------------

void ScanMatcher::recentre(const Eigen::Vector2d& robot_m) noexcept {
  const Level& finest = levels_[0];
  const std::int64_t robot_x = cell_of(robot_m.x(), finest.inverse_cell_m);
  const std::int64_t robot_y = cell_of(robot_m.y(), finest.inverse_cell_m);
  const std::int64_t half = finest.across / 2;
  // The window moves in steps of a quarter of it, not with every cell the robot crosses: each
  // move clears the strips that leave.
  const std::int64_t slack = finest.across / 4;
  if (placed_ && std::abs(robot_x - (finest.origin_x + half)) <= slack &&
      std::abs(robot_y - (finest.origin_y + half)) <= slack) {
    return;
  }
  // Aligned to the coarsest cell, so that every level's window covers the same ground.
  const std::int64_t coarsest = std::int64_t{1} << (levels_.size() - 1);
  const std::int64_t origin_x = floor_div(robot_x - half, coarsest) * coarsest;
  const std::int64_t origin_y = floor_div(robot_y - half, coarsest) * coarsest;
  for (std::size_t l = 0; l < levels_.size(); ++l) {
    const std::int64_t scale = std::int64_t{1} << l;
    scroll(levels_[l], origin_x / scale, origin_y / scale);
  }
  placed_ = true;
}

void ScanMatcher::scroll(Level& level, std::int64_t origin_x, std::int64_t origin_y) noexcept {
  const std::int64_t across = level.across;
  const std::int64_t mask = across - 1;
  const std::int64_t dx = origin_x - level.origin_x;
  const std::int64_t dy = origin_y - level.origin_y;
  if (!placed_ || std::abs(dx) >= across || std::abs(dy) >= across) {
    std::fill(level.cells.begin(), level.cells.end(), std::uint8_t{0});
  } else {
    // The columns and rows that leave are the slots of those that come in: cleared.
    const std::int64_t x_from = dx > 0 ? level.origin_x : origin_x + across;
    const std::int64_t x_to = dx > 0 ? origin_x : level.origin_x + across;
    for (std::int64_t x = x_from; x < x_to; ++x) {
      for (std::int64_t row = 0; row < across; ++row) {
        level.cells[static_cast<std::size_t>(row * across + (x & mask))] = 0;
      }
    }
    const std::int64_t y_from = dy > 0 ? level.origin_y : origin_y + across;
    const std::int64_t y_to = dy > 0 ? origin_y : level.origin_y + across;
    for (std::int64_t y = y_from; y < y_to; ++y) {
      const auto row = level.cells.subspan(static_cast<std::size_t>((y & mask) * across),
                                           static_cast<std::size_t>(across));
      std::fill(row.begin(), row.end(), std::uint8_t{0});
    }
  }
  level.origin_x = origin_x;
  level.origin_y = origin_y;
}

double ScanMatcher::cell_value(const Level& level, std::int64_t x, std::int64_t y) const noexcept {
  const auto across = static_cast<std::uint64_t>(level.across);
  if (static_cast<std::uint64_t>(x - level.origin_x) >= across ||
      static_cast<std::uint64_t>(y - level.origin_y) >= across) {
    return 0.0;
  }
  const std::int64_t mask = level.across - 1;
  return kValueOfHits
      [level.cells[static_cast<std::size_t>((y & mask) * level.across + (x & mask))] & kHitsMask];
}

ScanMatcher::Sample ScanMatcher::sample(const Level& level, double x_m, double y_m) const noexcept {
  const bilinear::Sample at = bilinear::sample(
      x_m, y_m, level.inverse_cell_m,
      [this, &level](std::int64_t x, std::int64_t y) { return cell_value(level, x, y); });
  return {at.value, at.d_dx, at.d_dy};
}

std::uint8_t ScanMatcher::hits_at(const Eigen::Vector2d& point_m) const noexcept {
  if (levels_.empty() || !placed_) {
    return 0;
  }
  const Level& level = levels_[0];
  return static_cast<std::uint8_t>(
      std::lround(255.0 * cell_value(level, cell_of(point_m.x(), level.inverse_cell_m),
                                     cell_of(point_m.y(), level.inverse_cell_m))));
}

void ScanMatcher::mark(Level& level, std::int64_t x, std::int64_t y) noexcept {
  const auto across = static_cast<std::uint64_t>(level.across);
  if (static_cast<std::uint64_t>(x - level.origin_x) >= across ||
      static_cast<std::uint64_t>(y - level.origin_y) >= across) {
    return;
  }
  const std::int64_t mask = level.across - 1;
  std::uint8_t& cell =
      level.cells[static_cast<std::size_t>((y & mask) * level.across + (x & mask))];
  const int hits = std::min(2, (cell & kHitsMask) + 1);
  cell = static_cast<std::uint8_t>((epoch_ << kEpochShift) | static_cast<std::uint32_t>(hits));
}

void ScanMatcher::age(double step_m) noexcept {
  if (!(config_.forget_after_m > 0.0) || !placed_) {
    return;
  }
  epoch_travel_m_ += step_m;
  if (epoch_travel_m_ < config_.forget_after_m / kEpochsKept) {
    return;
  }
  epoch_travel_m_ = 0.0;
  epoch_ = (epoch_ + 1) & kEpochMask;
  for (Level& level : levels_) {
    for (std::uint8_t& cell : level.cells) {
      const std::uint32_t last_hit = static_cast<std::uint32_t>(cell) >> kEpochShift;
      if (((epoch_ - last_hit) & kEpochMask) >= kEpochsKept) {
        cell = 0;
      }
    }
  }
}

void ScanMatcher::insert(std::span<const Eigen::Vector3f> points_m, double robot_z_m) noexcept {
  bool have_previous = false;
  Eigen::Vector2d previous_m = Eigen::Vector2d::Zero();
  const double join_sq = config_.join_gap_m * config_.join_gap_m;
  for (const Eigen::Vector3f& point : points_m) {
    const double height_m = static_cast<double>(point.z()) - robot_z_m;
    if (height_m < config_.min_height_m || height_m > config_.max_height_m) {
      have_previous = false;
      continue;
    }
    const Eigen::Vector2d at_m = to_grid_.apply(Eigen::Vector2d(point.x(), point.y()));
    // Neighbouring beams that met one surface mark the cells between them too: a wall met at
    // a grazing angle is hit a metre apart, and a scan matched against such dots is pulled
    // along the wall to where the last scan's beams happened to land.
    const bool join = have_previous && (at_m - previous_m).squaredNorm() <= join_sq;
    for (Level& level : levels_) {
      const std::int64_t x = cell_of(at_m.x(), level.inverse_cell_m);
      const std::int64_t y = cell_of(at_m.y(), level.inverse_cell_m);
      if (join) {
        const Eigen::Vector2d step_m = previous_m - at_m;
        const auto steps = static_cast<int>(std::ceil(2.0 * step_m.norm() * level.inverse_cell_m));
        std::int64_t last_x = x;
        std::int64_t last_y = y;
        for (int k = 1; k < steps; ++k) {  // the cells strictly between the two hits
          const Eigen::Vector2d along_m = at_m + step_m * (static_cast<double>(k) / steps);
          const std::int64_t cx = cell_of(along_m.x(), level.inverse_cell_m);
          const std::int64_t cy = cell_of(along_m.y(), level.inverse_cell_m);
          if ((cx != last_x || cy != last_y) &&
              (cx != cell_of(previous_m.x(), level.inverse_cell_m) ||
               cy != cell_of(previous_m.y(), level.inverse_cell_m))) {
            mark(level, cx, cy);
          }
          last_x = cx;
          last_y = cy;
        }
      }
      mark(level, x, y);
    }
    have_previous = true;
    previous_m = at_m;
  }
}

// --- The match -----------------------------------------------------------------------------

std::size_t ScanMatcher::select_points(const Pose2& raw_pose, double robot_z_m,
                                       std::span<const Eigen::Vector3f> points_m) noexcept {
  const double c = std::cos(raw_pose.yaw_rad);
  const double s = std::sin(raw_pose.yaw_rad);
  const double spacing_sq = config_.point_spacing_m * config_.point_spacing_m;
  const double max_range_sq = config_.max_match_range_m * config_.max_match_range_m;
  std::size_t count = 0;
  for (const Eigen::Vector3f& point : points_m) {
    const double height_m = static_cast<double>(point.z()) - robot_z_m;
    if (height_m < config_.min_height_m || height_m > config_.max_height_m) {
      continue;
    }
    const double dx = static_cast<double>(point.x()) - raw_pose.x_m;
    const double dy = static_cast<double>(point.y()) - raw_pose.y_m;
    if (dx * dx + dy * dy > max_range_sq) {
      continue;
    }
    const Eigen::Vector2d in_robot_m(c * dx + s * dy, -s * dx + c * dy);
    if (count > 0 && (in_robot_m - scan_m_[count - 1]).squaredNorm() < spacing_sq) {
      continue;
    }
    scan_m_[count++] = in_robot_m;
    if (count == scan_m_.size()) {
      break;
    }
  }
  // Each point's surface normal, from its neighbours in the scan: the match moves a point
  // only across the surface it lies on. Along a wall the grid says nothing true (its cells
  // are where earlier beams happened to land, a metre apart at a grazing angle), and a
  // point pulled along it to the nearest of them holds the pose back.
  const double neighbour_sq = config_.normal_neighbour_m * config_.normal_neighbour_m;
  for (std::size_t i = 0; i < count; ++i) {
    const bool before = i > 0 && (scan_m_[i] - scan_m_[i - 1]).squaredNorm() <= neighbour_sq;
    const bool after = i + 1 < count && (scan_m_[i + 1] - scan_m_[i]).squaredNorm() <= neighbour_sq;
    const Eigen::Vector2d tangent =
        (after ? scan_m_[i + 1] : scan_m_[i]) - (before ? scan_m_[i - 1] : scan_m_[i]);
    const double length = tangent.norm();
    scan_normals_[i] = Eigen::Vector2d::Zero();
    if (length > 0.0) {
      scan_normals_[i] = Eigen::Vector2d(-tangent.y(), tangent.x()) / length;
    }
  }
  return count;
}

void ScanMatcher::refine(const Level& level, const Eigen::Vector3d& prior,
                         Eigen::Vector3d& pose) const noexcept {
  const std::span<const Eigen::Vector2d> scan = scan_m_.first(scan_count_);
  // The prior, in the data's units: a point's value changes by a whole cell's worth across
  // a cell, so its gradient is about 1/cell where it meets a surface.
  const double per_point = config_.prior_weight * static_cast<double>(scan.size()) *
                           level.inverse_cell_m * level.inverse_cell_m;
  // Along the way the odometry's distance (a per cent or two off) is believed more than the
  // grid: a street's walls say nothing along it, and what does (a doorway, a post, the dots
  // of a hedge) is as often a cell's step that holds the pose back. Across the way and in
  // heading, where walls bend when the pose is wrong, the grid has its say.
  const double ca = std::cos(prior.z());
  const double sa = std::sin(prior.z());
  const double along = per_point * config_.prior_along_ratio;
  Eigen::Matrix3d prior_weights = Eigen::Matrix3d::Zero();
  prior_weights(0, 0) = along * ca * ca + per_point * sa * sa;
  prior_weights(1, 1) = along * sa * sa + per_point * ca * ca;
  prior_weights(0, 1) = (along - per_point) * ca * sa;
  prior_weights(1, 0) = prior_weights(0, 1);
  prior_weights(2, 2) = per_point * kPriorLeverM * kPriorLeverM;
  for (std::uint32_t iteration = 0; iteration < config_.iterations; ++iteration) {
    const double c = std::cos(pose.z());
    const double s = std::sin(pose.z());
    Eigen::Matrix3d hessian = prior_weights;
    Eigen::Vector3d gradient =
        prior_weights * Eigen::Vector3d(prior.x() - pose.x(), prior.y() - pose.y(),
                                        wrap_angle(prior.z() - pose.z()));
    for (const Eigen::Vector2d& point : scan) {
      const double rx = c * point.x() - s * point.y();
      const double ry = s * point.x() + c * point.y();
      const Sample at = sample(level, rx + pose.x(), ry + pose.y());
      double d_dx = at.d_dx;
      double d_dy = at.d_dy;
      const Eigen::Vector2d& normal = scan_normals_[static_cast<std::size_t>(&point - scan.data())];
      if (normal.x() != 0.0 || normal.y() != 0.0) {
        // Across the point's surface only (its normal turned into the local frame).
        const double nx = c * normal.x() - s * normal.y();
        const double ny = s * normal.x() + c * normal.y();
        const double across = nx * d_dx + ny * d_dy;
        d_dx = across * nx;
        d_dy = across * ny;
      }
      // d(world point)/d(yaw) = (-ry, rx).
      const Eigen::Vector3d jacobian(d_dx, d_dy, -d_dx * ry + d_dy * rx);
      hessian.noalias() += jacobian * jacobian.transpose();
      gradient += jacobian * (1.0 - at.value);
    }
    const Eigen::Vector3d step = hessian.ldlt().solve(gradient);
    if (!step.allFinite()) {
      return;
    }
    pose += step;
    if (step.head<2>().squaredNorm() < 1e-6 && std::abs(step.z()) < 1e-4) {  // 1 mm, 0.006 deg
      return;
    }
  }
}

double ScanMatcher::overlap(const Eigen::Vector3d& pose) const noexcept {
  const Level& finest = levels_[0];
  const double c = std::cos(pose.z());
  const double s = std::sin(pose.z());
  std::size_t on_map = 0;
  for (const Eigen::Vector2d& point : scan_m_.first(scan_count_)) {
    const double x_m = c * point.x() - s * point.y() + pose.x();
    const double y_m = s * point.x() + c * point.y() + pose.y();
    on_map += sample(finest, x_m, y_m).value >= kOnMapValue ? 1U : 0U;
  }
  return scan_count_ == 0 ? 0.0 : static_cast<double>(on_map) / static_cast<double>(scan_count_);
}

const PlanarCorrection& ScanMatcher::add_scan(const Pose2& raw_pose, const Pose2& odometry_pose,
                                              double robot_z_m,
                                              std::span<const Eigen::Vector3f> points_m) noexcept {
  if (!config_.enabled) {
    return correction_;
  }
  ++counters_.scans;
  const double since_last_s =
      have_last_ ? std::max(0.0, seconds_from_ns(raw_pose.stamp_ns - last_stamp_ns_)) : 0.0;
  // 1. The prediction, in the matcher's own frame: the scan before's pose there, moved as the
  //    odometry moved since. The first scan sets that frame: where the filter put it.
  Pose2 predicted = raw_pose;
  const bool had_last = have_last_;
  if (had_last) {
    predicted = moved_by(last_matched_, last_odometry_, odometry_pose);
    predicted.yaw_rad = wrap_angle(predicted.yaw_rad - yaw_rate_bias_radps_ * since_last_s);
  }
  const bool was_tracking = tracking_;
  have_last_ = true;
  last_stamp_ns_ = raw_pose.stamp_ns;
  last_odometry_ = odometry_pose;
  const Eigen::Vector3d pose = matched_pose(predicted, raw_pose, robot_z_m, points_m);
  if (had_last) {
    age(std::hypot(pose.x() - last_matched_.x_m, pose.y() - last_matched_.y_m));
  }
  last_matched_ = {raw_pose.stamp_ns, pose.x(), pose.y(), wrap_angle(pose.z())};
  if (was_tracking && tracking_) {
    learn_yaw_rate_bias(wrap_angle(pose.z() - predicted.yaw_rad));
  }
  // 4. The scan's points into the grid, where the matched pose puts them, once the robot
  //    has moved on from the last scan that went in.
  to_grid_ = motion_between(raw_pose, last_matched_);
  if (!have_update_ ||
      std::hypot(last_matched_.x_m - last_update_.x_m, last_matched_.y_m - last_update_.y_m) >=
          config_.map_update_m ||
      std::abs(wrap_angle(last_matched_.yaw_rad - last_update_.yaw_rad)) >=
          config_.map_update_rad) {
    insert(points_m, robot_z_m);
    have_update_ = true;
    last_update_ = last_matched_;
  }
  // 5. The GPS's place for the matcher's frame: the rigid motion that lays its path onto the
  //    filter's.
  anchor_.add(last_matched_, raw_pose, since_last_s, config_);
  correction_ = compose(anchor_.fit(config_), to_grid_);
  return correction_;
}

void ScanMatcher::learn_yaw_rate_bias(double turn_from_prediction_rad) noexcept {
  // A prediction that turns too far by b dt each scan is matched back by about that much:
  // the bias estimate moves by the match's turn over the controller's time.
  if (config_.yaw_rate_bias_time_s > 0.0) {
    yaw_rate_bias_radps_ -= turn_from_prediction_rad / config_.yaw_rate_bias_time_s;
  }
}

Eigen::Vector3d ScanMatcher::matched_pose(const Pose2& predicted, const Pose2& raw_pose,
                                          double robot_z_m,
                                          std::span<const Eigen::Vector3f> points_m) noexcept {
  const bool had_map = placed_;
  const bool was_tracking = tracking_;
  tracking_ = false;  // until this scan is matched
  recentre(Eigen::Vector2d(predicted.x_m, predicted.y_m));
  Eigen::Vector3d prior(predicted.x_m, predicted.y_m, predicted.yaw_rad);
  scan_count_ = select_points(raw_pose, robot_z_m, points_m);
  if (scan_count_ < config_.min_points) {
    ++counters_.few_points;
    return prior;
  }
  if (!had_map) {
    ++counters_.off_map;
    return prior;
  }
  // 2. Coarse to fine, each level held at the prediction where its scan says nothing. While
  //    the scans before were matched the prediction is millimetres off, and the two finest
  //    levels are enough; after a refusal (or a start) every level looks.
  Eigen::Vector3d pose = prior;
  const std::size_t from_level =
      was_tracking ? std::min<std::size_t>(2, levels_.size()) : levels_.size();
  for (std::size_t l = from_level; l-- > 0;) {
    refine(levels_[l], prior, pose);
  }
  // 3. A step beyond a scan's worth of error, or a scan mostly off the map, is refused.
  if ((pose.head<2>() - prior.head<2>()).norm() > config_.max_step_m ||
      std::abs(wrap_angle(pose.z() - prior.z())) > config_.max_step_rad) {
    ++counters_.too_far;
    return prior;
  }
  if (overlap(pose) < config_.min_overlap) {
    ++counters_.off_map;
    return prior;
  }
  ++counters_.matched;
  tracking_ = true;
  return pose;
}

// --- The anchor ----------------------------------------------------------------------------

void ScanMatcher::Anchor::add(const Pose2& matched, const Pose2& raw, double since_last_s,
                              const ScanMatchConfig& config) noexcept {
  if (!(config.anchor_time_s > 0.0)) {
    return;
  }
  const double keep = std::exp(-since_last_s / config.anchor_time_s);
  weight = weight * keep + 1.0;
  matched_x_m = matched_x_m * keep + matched.x_m;
  matched_y_m = matched_y_m * keep + matched.y_m;
  raw_x_m = raw_x_m * keep + raw.x_m;
  raw_y_m = raw_y_m * keep + raw.y_m;
  dot_m2 = dot_m2 * keep + matched.x_m * raw.x_m + matched.y_m * raw.y_m;
  cross_m2 = cross_m2 * keep + matched.x_m * raw.y_m - matched.y_m * raw.x_m;
  const double turn_rad = wrap_angle(raw.yaw_rad - matched.yaw_rad);
  heading_cos = heading_cos * keep + std::cos(turn_rad);
  heading_sin = heading_sin * keep + std::sin(turn_rad);
}

PlanarCorrection ScanMatcher::Anchor::fit(const ScanMatchConfig& config) const noexcept {
  if (!(weight > 0.0)) {
    return {};
  }
  // Procrustes in the plane: the turn that best lays the matched positions (about their
  // mean) onto the filter's, with each sample's heading difference counted as a pair of
  // points heading_lever_m apart; then the shift that lays the means onto each other.
  const double mx = matched_x_m / weight;
  const double my = matched_y_m / weight;
  const double rx = raw_x_m / weight;
  const double ry = raw_y_m / weight;
  const double lever_sq = config.anchor_heading_lever_m * config.anchor_heading_lever_m;
  const double dot = dot_m2 - weight * (mx * rx + my * ry) + lever_sq * heading_cos;
  const double cross = cross_m2 - weight * (mx * ry - my * rx) + lever_sq * heading_sin;
  PlanarCorrection out;
  out.yaw_rad = std::atan2(cross, dot);
  out.cos_yaw = std::cos(out.yaw_rad);
  out.sin_yaw = std::sin(out.yaw_rad);
  out.x_m = rx - (out.cos_yaw * mx - out.sin_yaw * my);
  out.y_m = ry - (out.sin_yaw * mx + out.cos_yaw * my);
  return out;
}

}  // namespace blockmap::localize
