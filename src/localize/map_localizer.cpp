#include "blockmap/localize/map_localizer.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>

#include "blockmap/core/angles.hpp"
#include "blockmap/localize/scan_matcher.hpp"

namespace blockmap::localize {
namespace {

constexpr const char* kOwner = "map localizer";
// n n' has determinant 0; the curvature beyond a wall's end, I / 2, has 1/4.
constexpr double kMaxOuterDeterminant = 0.1;

}  // namespace

std::size_t MapLocalizer::arena_bytes(const PriorMapConfig& config) noexcept {
  if (!config.enabled) {
    return 0;
  }
  return PriorMap::arena_bytes(config) + 2 * Arena::array_bytes<Particle>(config.particles) +
         Arena::array_bytes<Eigen::Vector2d>(config.max_points);
}

void MapLocalizer::init(Arena& arena, const PriorMapConfig& config) {
  config_ = config;
  random_ = Random(config.seed, "localize.prior_map");
  map_.init(arena, config);
  if (!config.enabled) {
    return;
  }
  particles_ = arena.allocate_array<Particle>(config.particles, kOwner);
  scratch_ = arena.allocate_array<Particle>(config.particles, kOwner);
  points_m_ = arena.allocate_array<Eigen::Vector2d>(config.max_points, kOwner);
}

std::size_t MapLocalizer::memory_bytes() const noexcept {
  return map_.memory_bytes() + particles_.size_bytes() + scratch_.size_bytes() +
         points_m_.size_bytes();
}

bool MapLocalizer::add_scan(const Pose2& path_pose, std::span<const Eigen::Vector2d> points_m,
                            MapPlacing& placing) noexcept {
  if (!ready() || !started_) {
    return false;
  }
  since_placing_m_ += std::hypot(path_pose.x_m - last_pose_.x_m, path_pose.y_m - last_pose_.y_m);
  last_pose_ = path_pose;
  const Eigen::Vector3d moved = pose_in_frame_of(last_update_, path_pose);
  if (std::hypot(moved.x(), moved.y()) < config_.update_spacing_m &&
      std::abs(moved.z()) < config_.update_turn_deg * kRadiansPerDegree) {
    return false;
  }
  move(last_update_, path_pose);
  last_update_ = path_pose;
  const std::size_t point_count = pick_points(points_m);
  if (point_count == 0) {
    return false;
  }
  weigh(point_count);
  ++counters_.updates;
  if (effective_particles() < 0.5 * static_cast<double>(particles_.size())) {
    resample();
  }
  const Pose2 mean = estimate();
  double hits = 0.0;
  const Eigen::Matrix2d walls = wall_information(mean, point_count, hits);
  if (hits < config_.min_hit_share) {
    ++counters_.off_the_map;
    ++off_the_map_in_a_row_;
    return false;
  }
  off_the_map_in_a_row_ = 0;
  if (since_placing_m_ < config_.place_spacing_m ||
      !placing_information(walls, spread(mean), placing.information)) {
    return false;
  }
  since_placing_m_ = 0.0;
  placing.pose = mean;
  placing.pose.stamp_ns = path_pose.stamp_ns;
  ++counters_.placings;
  return true;
}

void MapLocalizer::start(const Pose2& local_pose, const Pose2& path_pose, double sigma_m,
                         double yaw_sigma_rad) noexcept {
  for (Particle& p : particles_) {
    p.x_m = local_pose.x_m + random_.gaussian(sigma_m);
    p.y_m = local_pose.y_m + random_.gaussian(sigma_m);
    p.yaw_rad = wrap_angle(local_pose.yaw_rad + random_.gaussian(yaw_sigma_rad));
    p.log_weight = 0.0;
  }
  started_ = true;
  off_the_map_in_a_row_ = 0;
  last_pose_ = path_pose;
  last_update_ = path_pose;
  since_placing_m_ = 0.0;
}

void MapLocalizer::move(const Pose2& from, const Pose2& to) noexcept {
  // The path's motion in its own frame at `from`, applied in each particle's frame.
  const Eigen::Vector3d motion = pose_in_frame_of(from, to);
  const double distance_m = std::hypot(motion.x(), motion.y());
  const double sigma_m = config_.motion_sigma_m + config_.motion_sigma_per_m * distance_m;
  const double turn_sigma_rad =
      (config_.turn_sigma_deg + config_.turn_sigma_deg_per_m * distance_m) * kRadiansPerDegree;
  for (Particle& p : particles_) {
    const double ahead_m = motion.x() + random_.gaussian(sigma_m);
    const double left_m = motion.y() + random_.gaussian(sigma_m);
    const double c = std::cos(p.yaw_rad);
    const double s = std::sin(p.yaw_rad);
    p.x_m += c * ahead_m - s * left_m;
    p.y_m += s * ahead_m + c * left_m;
    p.yaw_rad = wrap_angle(p.yaw_rad + motion.z() + random_.gaussian(turn_sigma_rad));
  }
}

std::size_t MapLocalizer::pick_points(std::span<const Eigen::Vector2d> points_m) noexcept {
  const std::size_t count = std::min(points_m.size(), points_m_.size());
  for (std::size_t k = 0; k < count; ++k) {
    points_m_[k] = points_m[k * points_m.size() / count];
  }
  return count;
}

void MapLocalizer::weigh(std::size_t point_count) noexcept {
  const double inverse_variance = 1.0 / (config_.hit_sigma_m * config_.hit_sigma_m);
  const double unmapped = config_.unmapped_share / (1.0 - config_.unmapped_share);
  const double unmapped_inside = unmapped * config_.inside_share;
  const double per_point = config_.independent_points / static_cast<double>(point_count);
  double best = -std::numeric_limits<double>::infinity();
  for (Particle& p : particles_) {
    const double c = std::cos(p.yaw_rad);
    const double s = std::sin(p.yaw_rad);
    double log_likelihood = 0.0;
    for (std::size_t k = 0; k < point_count; ++k) {
      const Eigen::Vector2d& q = points_m_[k];
      const Eigen::Vector2d at(p.x_m + c * q.x() - s * q.y(), p.y_m + s * q.x() + c * q.y());
      const double d = map_.distance_m(at);
      log_likelihood += std::log(std::exp(-0.5 * d * d * inverse_variance) +
                                 (map_.inside(at) ? unmapped_inside : unmapped));
    }
    p.log_weight += per_point * log_likelihood;
    best = std::max(best, p.log_weight);
  }
  for (Particle& p : particles_) {
    p.log_weight -= best;  // the best at 0: no underflow of the weights that matter
  }
}

double MapLocalizer::effective_particles() const noexcept {
  double sum = 0.0;
  double sum2 = 0.0;
  for (const Particle& p : particles_) {
    const double w = std::exp(p.log_weight);
    sum += w;
    sum2 += w * w;
  }
  return sum * sum / sum2;
}

void MapLocalizer::resample() noexcept {
  // Low variance (systematic): one random offset, evenly spaced pointers.
  double total = 0.0;
  for (const Particle& p : particles_) {
    total += std::exp(p.log_weight);
  }
  const double step = total / static_cast<double>(particles_.size());
  double pointer = random_.uniform() * step;
  double cumulative = 0.0;
  std::size_t i = 0;
  for (Particle& out : scratch_) {
    while (i + 1 < particles_.size() && cumulative + std::exp(particles_[i].log_weight) < pointer) {
      cumulative += std::exp(particles_[i].log_weight);
      ++i;
    }
    out = particles_[i];
    out.log_weight = 0.0;
    pointer += step;
  }
  std::copy(scratch_.begin(), scratch_.end(), particles_.begin());
  ++counters_.resamplings;
}

Pose2 MapLocalizer::estimate() const noexcept {
  double total = 0.0;
  double x = 0.0;
  double y = 0.0;
  double c = 0.0;
  double s = 0.0;
  for (const Particle& p : particles_) {
    const double w = std::exp(p.log_weight);
    total += w;
    x += w * p.x_m;
    y += w * p.y_m;
    c += w * std::cos(p.yaw_rad);
    s += w * std::sin(p.yaw_rad);
  }
  // The best particle's weight is 1 after every weighing (weigh()): total is never 0.
  return {last_pose_.stamp_ns, x / total, y / total, std::atan2(s, c)};
}

Eigen::Matrix2d MapLocalizer::spread(const Pose2& mean) const noexcept {
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Zero();
  double total = 0.0;
  for (const Particle& p : particles_) {
    const double w = std::exp(p.log_weight);
    const Eigen::Vector2d d(p.x_m - mean.x_m, p.y_m - mean.y_m);
    covariance += w * d * d.transpose();
    total += w;
  }
  return covariance / total;
}

Eigen::Matrix2d MapLocalizer::wall_information(const Pose2& pose, std::size_t point_count,
                                               double& hit_share) const noexcept {
  const double c = std::cos(pose.yaw_rad);
  const double s = std::sin(pose.yaw_rad);
  Eigen::Matrix2d sum = Eigen::Matrix2d::Zero();
  std::size_t hits = 0;
  std::size_t pinning = 0;
  for (std::size_t k = 0; k < point_count; ++k) {
    const Eigen::Vector2d& q = points_m_[k];
    const Eigen::Vector2d at(pose.x_m + c * q.x() - s * q.y(), pose.y_m + s * q.x() + c * q.y());
    if (map_.distance_m(at) > 2.0 * config_.hit_sigma_m) {
      continue;
    }
    ++hits;
    // Beyond a wall's end a return is a distance from a point, which pins no one direction
    // (n n' of no single n: its determinant is far from 0). It counts as a hit only.
    const Eigen::Matrix2d outer = map_.normal_outer(at);
    if (outer.determinant() < kMaxOuterDeterminant) {
      sum += outer;
      ++pinning;
    }
  }
  hit_share = static_cast<double>(hits) / static_cast<double>(point_count);
  if (pinning == 0) {
    return sum;
  }
  return sum * (config_.independent_points /
                (static_cast<double>(pinning) * config_.hit_sigma_m * config_.hit_sigma_m));
}

bool MapLocalizer::placing_information(const Eigen::Matrix2d& walls, const Eigen::Matrix2d& spread,
                                       Eigen::Matrix2d& information) noexcept {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> directions(walls);
  const double least_information =
      1.0 / (config_.max_placing_sigma_m * config_.max_placing_sigma_m);
  information.setZero();
  bool pinned = false;
  for (int k = 0; k < 2; ++k) {
    const double walls_information = directions.eigenvalues()(k);
    if (walls_information < least_information) {
      continue;  // a bare street's length: the particles' guess, not the map's
    }
    const Eigen::Vector2d direction = directions.eigenvectors().col(k);
    const double spread_m2 = direction.dot(spread * direction);
    if (spread_m2 > config_.max_spread_m * config_.max_spread_m) {
      ++counters_.spread_too_wide;
      return false;
    }
    const double variance_m2 =
        std::max(1.0 / walls_information + spread_m2, config_.min_sigma_m * config_.min_sigma_m);
    information += direction * direction.transpose() / variance_m2;
    pinned = true;
  }
  if (!pinned) {
    ++counters_.unpinned;
  }
  return pinned;
}

}  // namespace blockmap::localize
