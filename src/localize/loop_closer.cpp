#include "blockmap/localize/loop_closer.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include "bilinear.hpp"
#include "blockmap/core/angles.hpp"
#include "blockmap/core/check.hpp"

namespace blockmap::localize {
namespace {

// The coarse search's steps: half the coarse level's cell, and the turn that moves a cell at
// the kept range by about that much.
constexpr double kYawStepRad = 0.0087;  // 0.5 deg
constexpr std::uint32_t kIterations = 5;
// The Gauss-Newton steps' hold at where they started, per point, as a share of a surface's
// pull: enough to keep a bare street's length where the search put it.
constexpr double kHoldPerPoint = 0.01;
constexpr double kScoreGainPerM = 0.1;
constexpr double kMaxShifts = 16.0;

std::int64_t cell_of(double coordinate_m, double inverse_cell_m) noexcept {
  return static_cast<std::int64_t>(std::floor(coordinate_m * inverse_cell_m));
}

}  // namespace

std::string validate(const LoopClosureConfig& config) {
  if (!config.enabled) {
    return {};
  }
  if (!(config.cell_m >= 0.02 && config.cell_m <= 1.0)) {
    return "loop_closure: cell_m must be 0.02 to 1 m";
  }
  if (!(config.submap_length_m > 0.0) || !(config.scan_spacing_m >= 0.0) ||
      !(config.max_range_m > 0.0) || !(config.join_gap_m >= 0.0)) {
    return "loop_closure: submap_length_m and max_range_m must be positive, scan_spacing_m and "
           "join_gap_m not negative";
  }
  // Cells are kept as 16-bit offsets from the submap's first pose.
  if ((config.submap_length_m + config.max_range_m) / config.cell_m > 30000.0) {
    return "loop_closure: submap_length_m + max_range_m must be under 30000 cells";
  }
  if (config.max_submaps < 4 || config.max_cells_per_submap < 16 || config.max_query_points < 16) {
    return "loop_closure: max_submaps at least 4, max_cells_per_submap and max_query_points at "
           "least 16";
  }
  // A multiple of 64, so that every level's centre is the finest one's.
  if (config.levels < 1 || config.levels > 5 || config.grid_across < 64 ||
      config.grid_across > 4096 || config.grid_across % 64 != 0) {
    return "loop_closure: grid_across must be a multiple of 64 from 64 to 4096, and levels 1 "
           "to 5";
  }
  if (config.max_candidates < 1 || config.max_candidates > kMaxClosureCandidates) {
    return "loop_closure: max_candidates must be 1 to 4";
  }
  if (!(config.candidate_distance_m > 0.0) || !(config.min_travel_apart_m >= 0.0) ||
      !(config.search_radius_m > 0.0) || !(config.search_yaw_deg >= 0.0) ||
      config.search_yaw_deg > 45.0) {
    return "loop_closure: candidate_distance_m and search_radius_m must be positive, "
           "min_travel_apart_m not negative, search_yaw_deg 0 to 45";
  }
  if (!(config.search_radius_per_m >= 0.0) || !(config.search_yaw_deg_per_m >= 0.0) ||
      !(config.max_search_radius_m >= config.search_radius_m) ||
      !(config.max_search_yaw_deg >= config.search_yaw_deg) || config.max_search_yaw_deg > 45.0) {
    return "loop_closure: search_radius_per_m and search_yaw_deg_per_m must not be negative, "
           "max_search_radius_m and max_search_yaw_deg (at most 45) not below the fixed ones";
  }
  if (!(config.last_submap_min_m >= 0.0)) {
    return "loop_closure: last_submap_min_m must not be negative";
  }
  if (!(config.wide_search_radius_m >= 0.0) || !(config.wide_search_yaw_deg >= 0.0) ||
      config.wide_search_yaw_deg > 45.0 ||
      !(config.wide_min_score > 0.0 && config.wide_min_score <= 1.0)) {
    return "loop_closure: wide_search_radius_m must not be negative, wide_search_yaw_deg 0 to "
           "45 and wide_min_score in (0, 1]";
  }
  if (!(config.min_score > 0.0 && config.min_score <= 1.0) || !(config.point_sigma_m > 0.0) ||
      !(config.floor_sigma_m > 0.0) || !(config.floor_sigma_deg > 0.0)) {
    return "loop_closure: min_score must be in (0, 1], point_sigma_m, floor_sigma_m and "
           "floor_sigma_deg positive";
  }
  return {};
}

// --- Memory --------------------------------------------------------------------------------

std::size_t LoopCloser::arena_bytes(const LoopClosureConfig& config) noexcept {
  if (!config.enabled) {
    return 0;
  }
  std::size_t bytes = Arena::array_bytes<Cell>(config.max_submaps * config.max_cells_per_submap) +
                      Arena::array_bytes<Submap>(config.max_submaps) +
                      Arena::array_bytes<std::uint32_t>(config.max_submaps) +
                      Arena::array_bytes<Cell>(4 * config.max_cells_per_submap) +
                      Arena::array_bytes<Level>(config.levels) +
                      Arena::array_bytes<Eigen::Vector2d>(config.max_query_points);
  for (std::uint32_t l = 0; l < config.levels; ++l) {
    const std::size_t across = config.grid_across >> l;
    bytes += Arena::array_bytes<std::uint8_t>(across * across);
  }
  return bytes;
}

void LoopCloser::init(Arena& arena, const LoopClosureConfig& config) {
  const std::string problem = validate(config);
  BLOCKMAP_CHECK_MSG(problem.empty(), problem.c_str());
  config_ = config;
  if (!config.enabled) {
    return;
  }
  constexpr const char* kOwner = "localize.loop_closer";
  cells_ = arena.allocate_array<Cell>(config.max_submaps * config.max_cells_per_submap, kOwner);
  submaps_ = arena.allocate_array<Submap>(config.max_submaps, kOwner);
  free_slots_ = arena.allocate_array<std::uint32_t>(config.max_submaps, kOwner);
  for (std::size_t i = 0; i < free_slots_.size(); ++i) {
    free_slots_[i] = static_cast<std::uint32_t>(free_slots_.size() - 1 - i);
  }
  free_count_ = free_slots_.size();
  staging_ = arena.allocate_array<Cell>(4 * config.max_cells_per_submap, kOwner);
  levels_ = arena.allocate_array<Level>(config.levels, kOwner);
  for (std::size_t l = 0; l < levels_.size(); ++l) {
    Level& level = levels_[l];
    level.across = std::int64_t{config.grid_across} >> l;
    level.cell_m = config.cell_m * static_cast<double>(std::int64_t{1} << l);
    level.cells = arena.allocate_array<std::uint8_t>(
        static_cast<std::size_t>(level.across * level.across), kOwner);
  }
  query_m_ = arena.allocate_array<Eigen::Vector2d>(config.max_query_points, kOwner);
}

std::size_t LoopCloser::memory_bytes() const noexcept {
  std::size_t bytes = cells_.size_bytes() + submaps_.size_bytes() + free_slots_.size_bytes() +
                      staging_.size_bytes() + levels_.size_bytes() + query_m_.size_bytes();
  for (const Level& level : levels_) {
    bytes += level.cells.size_bytes();
  }
  return bytes;
}

// --- Submaps -------------------------------------------------------------------------------

bool LoopCloser::add_scan(const Pose2& pose,
                          std::span<const Eigen::Vector2d> robot_points_m) noexcept {
  if (!config_.enabled) {
    return false;
  }
  if (have_last_) {
    travel_m_ += std::hypot(pose.x_m - last_pose_.x_m, pose.y_m - last_pose_.y_m);
  }
  have_last_ = true;
  last_pose_ = pose;
  if (!open_) {
    open_ = true;
    open_origin_ = pose;
    open_from_m_ = travel_m_;
    staging_count_ = 0;
    add_cells(pose, robot_points_m);
    return false;
  }
  if (std::hypot(pose.x_m - last_added_.x_m, pose.y_m - last_added_.y_m) >=
      config_.scan_spacing_m) {
    add_cells(pose, robot_points_m);
  }
  if (travel_m_ - open_from_m_ < config_.submap_length_m) {
    return false;
  }
  finish_submap();
  return true;
}

bool LoopCloser::finish_last_submap() noexcept {
  if (!open_ || travel_m_ - open_from_m_ < config_.last_submap_min_m) {
    return false;
  }
  finish_submap();
  return true;
}

void LoopCloser::add_cells(const Pose2& pose,
                           std::span<const Eigen::Vector2d> robot_points_m) noexcept {
  last_added_ = pose;
  // The robot frame into the submap's: the pose relative to the submap's first one.
  const Eigen::Vector3d in_submap = pose_in_frame_of(open_origin_, pose);
  const Eigen::Rotation2Dd turn(in_submap.z());
  const Eigen::Vector2d shift_m = in_submap.head<2>();
  const double range_sq = config_.max_range_m * config_.max_range_m;
  const double join_sq = config_.join_gap_m * config_.join_gap_m;
  bool have_previous = false;
  Eigen::Vector2d previous_m = Eigen::Vector2d::Zero();
  for (const Eigen::Vector2d& point : robot_points_m) {
    if (point.squaredNorm() > range_sq) {
      have_previous = false;
      continue;
    }
    const Eigen::Vector2d local_m = turn * point + shift_m;
    if (have_previous && (local_m - previous_m).squaredNorm() <= join_sq) {
      // The cells between neighbouring returns of one surface (a wall met at a grazing angle
      // is hit a metre apart).
      const auto steps =
          static_cast<int>(std::ceil((local_m - previous_m).norm() / config_.cell_m));
      for (int k = 1; k < steps; ++k) {
        add_cell(previous_m + (local_m - previous_m) * (static_cast<double>(k) / steps));
      }
    }
    add_cell(local_m);
    have_previous = true;
    previous_m = local_m;
  }
}

void LoopCloser::add_cell(const Eigen::Vector2d& local_m) noexcept {
  if (staging_count_ == staging_.size()) {
    compact_staging();
    if (staging_count_ == staging_.size()) {
      return;
    }
  }
  const double inverse_cell_m = 1.0 / config_.cell_m;
  staging_[staging_count_++] = {static_cast<std::int16_t>(cell_of(local_m.x(), inverse_cell_m)),
                                static_cast<std::int16_t>(cell_of(local_m.y(), inverse_cell_m))};
}

void LoopCloser::compact_staging() noexcept {
  const auto first = staging_.begin();
  const auto last = first + static_cast<std::ptrdiff_t>(staging_count_);
  const auto before = [](const Cell& a, const Cell& b) {
    return a.y != b.y ? a.y < b.y : a.x < b.x;
  };
  const auto same = [](const Cell& a, const Cell& b) { return a.x == b.x && a.y == b.y; };
  std::sort(first, last, before);
  staging_count_ = static_cast<std::size_t>(std::unique(first, last, same) - first);
}

void LoopCloser::finish_submap() noexcept {
  compact_staging();
  if (free_count_ == 0) {
    thin_submaps();
  }
  Submap& submap = submaps_[submap_count_++];
  submap.origin = open_origin_;
  submap.from_m = open_from_m_;
  submap.to_m = travel_m_;
  submap.slot = free_slots_[--free_count_];
  // Thinned evenly when there are more cells than a submap holds.
  const std::size_t keep = std::min(staging_count_, config_.max_cells_per_submap);
  const std::span<Cell> into = cells_.subspan(submap.slot * config_.max_cells_per_submap, keep);
  Eigen::Vector2d sum_m = Eigen::Vector2d::Zero();
  for (std::size_t i = 0; i < keep; ++i) {
    into[i] = staging_[i * staging_count_ / keep];
    sum_m += Eigen::Vector2d(into[i].x + 0.5, into[i].y + 0.5) * config_.cell_m;
  }
  submap.seen_m =
      keep == 0 ? Eigen::Vector2d::Zero() : Eigen::Vector2d(sum_m / static_cast<double>(keep));
  submap.count = static_cast<std::uint32_t>(keep);
  ++counters_.submaps;
  open_ = false;
}

void LoopCloser::thin_submaps() noexcept {
  // Every other one goes, the newest stays: the run at half the resolution.
  std::size_t kept = 0;
  for (std::size_t i = 0; i < submap_count_; ++i) {
    if (i % 2 == 0 && i + 1 < submap_count_) {
      free_slots_[free_count_++] = submaps_[i].slot;
      continue;
    }
    submaps_[kept++] = submaps_[i];
  }
  submap_count_ = kept;
  ++counters_.thinnings;
}

std::span<const LoopCloser::Cell> LoopCloser::cells_of(const Submap& submap) const noexcept {
  return std::span<const Cell>(cells_).subspan(submap.slot * config_.max_cells_per_submap,
                                               submap.count);
}

// --- Closures ------------------------------------------------------------------------------

std::size_t LoopCloser::find_closures(
    const PathSmoother& path, std::span<LoopClosure, kMaxClosureCandidates> found) noexcept {
  if (submap_count_ < 2 || path.keyframe_count() == 0) {
    return 0;
  }
  const Submap& query = submaps_[submap_count_ - 1];
  const Pose2 query_solved = path.solved_pose(query.origin);
  // The nearest earlier submaps by the solved path, far enough back along it.
  struct Candidate {
    std::size_t index = 0;
    double distance_m = std::numeric_limits<double>::infinity();
    Eigen::Vector3d guess = Eigen::Vector3d::Zero();
  };
  std::array<Candidate, kMaxClosureCandidates> nearest{};
  std::size_t nearest_count = 0;
  for (std::size_t i = 0; i + 1 < submap_count_; ++i) {
    const Submap& target = submaps_[i];
    if (target.to_m > query.from_m - config_.min_travel_apart_m) {
      continue;
    }
    const Eigen::Vector3d guess = pose_in_frame_of(path.solved_pose(target.origin), query_solved);
    const double distance_m =
        (Eigen::Rotation2Dd(guess.z()) * query.seen_m + guess.head<2>() - target.seen_m).norm();
    if (distance_m > config_.candidate_distance_m) {
      continue;
    }
    // Kept nearest first: the new one goes in where it belongs, the farthest falls off.
    std::size_t at = std::min(nearest_count, config_.max_candidates - 1);
    if (nearest_count == config_.max_candidates && distance_m >= nearest[at].distance_m) {
      continue;
    }
    for (; at > 0 && nearest[at - 1].distance_m > distance_m; --at) {
      nearest[at] = nearest[at - 1];
    }
    nearest[at] = {i, distance_m, guess};
    nearest_count = std::min(nearest_count + 1, config_.max_candidates);
  }
  load_query(query);
  std::size_t count = 0;
  for (std::size_t k = 0; k < nearest_count; ++k) {
    const Submap& target = submaps_[nearest[k].index];
    const Window window =
        window_between(target, query, path.counters().fixes + path.counters().placings > 0);
    if (match(target, query, nearest[k].guess, window, found[count])) {
      ++count;
      continue;
    }
    const Window wide = widened(window);
    if (wide.radius_m > 0.0 && match(target, query, nearest[k].guess, wide, found[count])) {
      ++count;
      ++counters_.wide_closures;
    }
  }
  return count;
}

void LoopCloser::load_query(const Submap& query) noexcept {
  // The query's cells as points at their centres, thinned evenly to max_query_points.
  const std::span<const Cell> cells = cells_of(query);
  query_count_ = std::min(cells.size(), query_m_.size());
  for (std::size_t i = 0; i < query_count_; ++i) {
    const Cell& cell = cells[i * cells.size() / query_count_];
    query_m_[i] = Eigen::Vector2d((cell.x + 0.5) * config_.cell_m, (cell.y + 0.5) * config_.cell_m);
  }
}

void LoopCloser::rasterize(const Submap& target) noexcept {
  // The target's cells about the grid's centre; each coarser level's cell is occupied when
  // any of the four under it is.
  Level& finest = levels_[0];
  std::fill(finest.cells.begin(), finest.cells.end(), std::uint8_t{0});
  const std::int64_t half = finest.across / 2;
  for (const Cell& cell : cells_of(target)) {
    const std::int64_t x = cell.x + half;
    const std::int64_t y = cell.y + half;
    if (x >= 0 && y >= 0 && x < finest.across && y < finest.across) {
      finest.cells[static_cast<std::size_t>(y * finest.across + x)] = 1;
    }
  }
  for (std::size_t l = 1; l < levels_.size(); ++l) {
    const Level& fine = levels_[l - 1];
    Level& coarse = levels_[l];
    for (std::int64_t y = 0; y < coarse.across; ++y) {
      for (std::int64_t x = 0; x < coarse.across; ++x) {
        const auto at = [&fine](std::int64_t fx, std::int64_t fy) {
          return fine.cells[static_cast<std::size_t>(fy * fine.across + fx)];
        };
        coarse.cells[static_cast<std::size_t>(y * coarse.across + x)] =
            std::max({at(2 * x, 2 * y), at(2 * x + 1, 2 * y), at(2 * x, 2 * y + 1),
                      at(2 * x + 1, 2 * y + 1)});
      }
    }
  }
}

double LoopCloser::value(const Level& level, std::int64_t x, std::int64_t y) const noexcept {
  if (x < 0 || y < 0 || x >= level.across || y >= level.across) {
    return 0.0;
  }
  return level.cells[static_cast<std::size_t>(y * level.across + x)];
}

LoopCloser::Window LoopCloser::window_between(const Submap& target, const Submap& query,
                                              bool placed_by_fixes) const noexcept {
  // With fixes the receiver bounds how far apart two passes can be drawn, whatever was
  // driven between them; without, the odometry's drift grows with it.
  const double apart_m = placed_by_fixes ? 0.0 : std::max(0.0, query.from_m - target.to_m);
  Window window;
  window.radius_m = std::min(config_.search_radius_m + config_.search_radius_per_m * apart_m,
                             config_.max_search_radius_m);
  window.yaw_rad = radians_from_degrees(std::min(
      config_.search_yaw_deg + config_.search_yaw_deg_per_m * apart_m, config_.max_search_yaw_deg));
  window.level = level_spanning(window.radius_m);
  window.min_score = config_.min_score;
  return window;
}

LoopCloser::Window LoopCloser::widened(const Window& window) const noexcept {
  Window wide;
  const double yaw_rad = radians_from_degrees(config_.wide_search_yaw_deg);
  if (config_.wide_search_radius_m <= window.radius_m && yaw_rad <= window.yaw_rad) {
    return wide;
  }
  wide.radius_m = std::max(config_.wide_search_radius_m, window.radius_m);
  wide.yaw_rad = std::max(yaw_rad, window.yaw_rad);
  wide.level = level_spanning(wide.radius_m);
  wide.min_score = std::max(config_.wide_min_score, window.min_score);
  return wide;
}

std::size_t LoopCloser::level_spanning(double radius_m) const noexcept {
  // The search runs on the finest level that spans the window in kMaxShifts half-cells
  // either way: a wider window on a coarser level, at about the same cost.
  std::size_t level = 0;
  while (level + 1 < levels_.size() && radius_m > kMaxShifts * 0.5 * levels_[level].cell_m) {
    ++level;
  }
  return level;
}

Eigen::Vector3d LoopCloser::coarse_search(const Eigen::Vector3d& guess,
                                          const Window& window) const noexcept {
  // Every pose of the window on the coarsest level, by the count of points on its cells.
  const Level& coarse = levels_[window.level];
  const double inverse_cell_m = 1.0 / coarse.cell_m;
  const double centre_m = 0.5 * static_cast<double>(coarse.across) * coarse.cell_m;
  const double step_m = coarse.cell_m / 2.0;
  const auto shifts = static_cast<int>(std::ceil(window.radius_m / step_m));
  const auto turns = static_cast<int>(std::ceil(window.yaw_rad / kYawStepRad));
  Eigen::Vector3d best = guess;
  double best_count = -1.0;
  for (int turn = -turns; turn <= turns; ++turn) {
    const double yaw = guess.z() + turn * kYawStepRad;
    const Eigen::Rotation2Dd rotation(yaw);
    for (int sy = -shifts; sy <= shifts; ++sy) {
      for (int sx = -shifts; sx <= shifts; ++sx) {
        const Eigen::Vector2d shift_m(guess.x() + sx * step_m, guess.y() + sy * step_m);
        double count = 0.0;
        for (const Eigen::Vector2d& point : query_m_.first(query_count_)) {
          const Eigen::Vector2d at_m = rotation * point + shift_m;
          count += value(coarse, cell_of(at_m.x() + centre_m, inverse_cell_m),
                         cell_of(at_m.y() + centre_m, inverse_cell_m));
        }
        // Ties go to the pose nearest the guess (the search's order: outward is later).
        if (count > best_count ||
            (count == best_count &&
             Eigen::Vector2d(sx, sy).squaredNorm() <
                 ((best.head<2>() - guess.head<2>()) / step_m).squaredNorm())) {
          best_count = count;
          best = Eigen::Vector3d(shift_m.x(), shift_m.y(), yaw);
        }
      }
    }
  }
  return best;
}

void LoopCloser::refine(const Level& level, const Eigen::Vector3d& start,
                        Match& match) const noexcept {
  // Gauss-Newton on the bilinearly interpolated level (Hector's (1 - M(S(xi)))^2), held
  // weakly where it started.
  const double inverse_cell_m = 1.0 / level.cell_m;
  const double centre_m = 0.5 * static_cast<double>(level.across) * level.cell_m;
  const double hold =
      kHoldPerPoint * static_cast<double>(query_count_) * inverse_cell_m * inverse_cell_m;
  Eigen::Vector3d& pose = match.pose;
  pose = start;
  for (std::uint32_t iteration = 0; iteration < kIterations; ++iteration) {
    const Eigen::Rotation2Dd rotation(pose.z());
    Eigen::Matrix3d hessian = Eigen::Matrix3d::Zero();
    Eigen::Vector3d gradient = Eigen::Vector3d::Zero();
    for (const Eigen::Vector2d& point : query_m_.first(query_count_)) {
      const Eigen::Vector2d turned_m = rotation * point;
      const bilinear::Sample at = bilinear::sample(
          turned_m.x() + pose.x() + centre_m, turned_m.y() + pose.y() + centre_m, inverse_cell_m,
          [this, &level](std::int64_t x, std::int64_t y) { return value(level, x, y); });
      const Eigen::Vector3d jacobian(at.d_dx, at.d_dy,
                                     -at.d_dx * turned_m.y() + at.d_dy * turned_m.x());
      hessian.noalias() += jacobian * jacobian.transpose();
      gradient += jacobian * (1.0 - at.value);
    }
    match.hessian = hessian;
    Eigen::Matrix3d held = hessian;
    held.diagonal() +=
        Eigen::Vector3d(hold, hold, hold * config_.max_range_m * config_.max_range_m);
    gradient += Eigen::Vector3d(
        hold * (start.x() - pose.x()), hold * (start.y() - pose.y()),
        hold * config_.max_range_m * config_.max_range_m * wrap_angle(start.z() - pose.z()));
    const Eigen::Vector3d step = held.ldlt().solve(gradient);
    if (!step.allFinite()) {
      return;
    }
    pose += step;
  }
}

double LoopCloser::score(const Eigen::Vector3d& pose) const noexcept {
  // The share of the query's points within a cell of the target's surfaces (on an occupied
  // cell of the next coarser level).
  const Level& level = levels_.size() > 1 ? levels_[1] : levels_[0];
  const double inverse_cell_m = 1.0 / level.cell_m;
  const double centre_m = 0.5 * static_cast<double>(level.across) * level.cell_m;
  const Eigen::Rotation2Dd rotation(pose.z());
  double on = 0.0;
  for (const Eigen::Vector2d& point : query_m_.first(query_count_)) {
    const Eigen::Vector2d at_m = rotation * point + pose.head<2>();
    on += value(level, cell_of(at_m.x() + centre_m, inverse_cell_m),
                cell_of(at_m.y() + centre_m, inverse_cell_m));
  }
  return query_count_ == 0 ? 0.0 : on / static_cast<double>(query_count_);
}

bool LoopCloser::match(const Submap& target, const Submap& query, const Eigen::Vector3d& guess,
                       const Window& window, LoopClosure& closure) noexcept {
  ++counters_.searches;
  rasterize(target);
  // 2-3. The window's best on the coarse level, then Gauss-Newton coarse to fine.
  //    The search's best replaces the guess only when it scores higher by kScoreGainPerM
  //    for each metre it lies from it: along a street whose facades repeat, another bay a
  //    few metres on scores nearly as well, and the receiver's slow error is seldom that
  //    large between passes.
  const auto refined = [this, &window](const Eigen::Vector3d& start) {
    Match match;
    match.pose = start;
    for (std::size_t l = window.level + 1; l-- > 0;) {
      refine(levels_[l], match.pose, match);
    }
    match.score = score(match.pose);
    return match;
  };
  Match found = refined(guess);
  const Match searched = refined(coarse_search(guess, window));
  if (searched.score - found.score >
      kScoreGainPerM * (searched.pose.head<2>() - found.pose.head<2>()).norm()) {
    found = searched;
  }
  // 4. Verified: mostly on the earlier submap's surfaces, and inside the window.
  if (found.score < window.min_score) {
    ++counters_.low_score;
    return false;
  }
  const double slack_m = levels_[window.level].cell_m;
  if ((found.pose.head<2>() - guess.head<2>()).norm() > window.radius_m + slack_m ||
      std::abs(wrap_angle(found.pose.z() - guess.z())) > window.yaw_rad + kYawStepRad) {
    ++counters_.off_window;
    return false;
  }
  // 5. The information: the finest level's Hessian in the units of a surface's offset
  //    (its gradient is about one per cell across a surface), over a point's sigma; then
  //    the floor added to the covariance (what the surfaces do not say stays unsaid).
  const double cell_m = levels_[0].cell_m;
  Eigen::Matrix3d information =
      found.hessian * (cell_m * cell_m / (config_.point_sigma_m * config_.point_sigma_m));
  information.diagonal() += Eigen::Vector3d(1e-6, 1e-6, 1e-4);
  const double floor_rad = radians_from_degrees(config_.floor_sigma_deg);
  Eigen::Matrix3d covariance = information.ldlt().solve(Eigen::Matrix3d::Identity());
  covariance.diagonal() +=
      Eigen::Vector3d(config_.floor_sigma_m * config_.floor_sigma_m,
                      config_.floor_sigma_m * config_.floor_sigma_m, floor_rad * floor_rad);
  closure.earlier = target.origin;
  closure.later = query.origin;
  closure.measured = found.pose;
  closure.information = covariance.ldlt().solve(Eigen::Matrix3d::Identity());
  if (!closure.information.allFinite()) {
    return false;
  }
  ++counters_.closures;
  return true;
}

}  // namespace blockmap::localize
