// Monte Carlo localization against a prior 2D map (the seed's section II, its USC run): where
// on a map made before the robot is, from what its level lasers see, beside or instead of the
// receiver (docs/localize.md, A prior map).
//
// Particles over (x, y, yaw) in the local frame, moved by the matched path's motion between
// updates (with noise growing with it), weighed by the returns of a level scan against the
// map's likelihood field (PriorMap), resampled when their effective number falls below half.
// When they agree and the estimate's returns land on the map's walls, the estimate is a
// placing of the robot: an absolute position the rigid path holds its keyframe to, with no
// slow error of a receiver's kind.
//
// Fixed size: the particles and the scan's points are taken from the arena at init; nothing
// is allocated after.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "blockmap/core/arena.hpp"
#include "blockmap/core/random.hpp"
#include "blockmap/localize/particle_filter.hpp"
#include "blockmap/localize/prior_map.hpp"

namespace blockmap::localize {

// Where the map puts the robot at a scan: the pose, and the information on its position (per
// square metre, east and north; zero along what the walls leave free).
struct MapPlacing {
  Pose2 pose;
  Eigen::Matrix2d information = Eigen::Matrix2d::Zero();
};

struct MapLocalizerCounters {
  std::uint64_t updates = 0;  // scans that weighed the particles
  std::uint64_t resamplings = 0;
  std::uint64_t placings = 0;         // positions handed to the path
  std::uint64_t spread_too_wide = 0;  // updates whose particles disagreed
  std::uint64_t off_the_map = 0;      // updates whose returns missed the map's walls
  std::uint64_t unpinned = 0;         // updates whose walls pinned no direction
};

class MapLocalizer {
 public:
  void init(Arena& arena, const PriorMapConfig& config);
  [[nodiscard]] static std::size_t arena_bytes(const PriorMapConfig& config) noexcept;
  [[nodiscard]] std::size_t memory_bytes() const noexcept;

  // The map, at start-up: empty when it worked, else why not (PriorMap::build).
  [[nodiscard]] std::string set_map(std::span<const MapWall> walls) { return map_.build(walls); }
  [[nodiscard]] bool ready() const noexcept { return config_.enabled && map_.built(); }
  [[nodiscard]] const PriorMap& map() const noexcept { return map_; }
  [[nodiscard]] const PriorMapConfig& config() const noexcept { return config_; }

  // The particles drawn around `local_pose` by these sigmas: the robot's pose in the local
  // frame as the path has it now, at the path's pose `path_pose`.
  void start(const Pose2& local_pose, const Pose2& path_pose, double sigma_m,
             double yaw_sigma_rad) noexcept;
  // A level scan once started: `path_pose` in the path's own frame (its motion since the last
  // scan moves the particles), the returns in the robot frame. True when `placing` was
  // written: where the map puts the robot in the local frame at this scan.
  bool add_scan(const Pose2& path_pose, std::span<const Eigen::Vector2d> points_m,
                MapPlacing& placing) noexcept;

  // The particles' weighted mean (valid once started).
  [[nodiscard]] Pose2 estimate() const noexcept;
  [[nodiscard]] bool started() const noexcept { return started_; }
  // Whether the estimate's returns have missed the map's walls for lost_after updates in a
  // row: the particles are somewhere else (or the map holds nothing here).
  [[nodiscard]] bool lost() const noexcept { return off_the_map_in_a_row_ >= config_.lost_after; }
  [[nodiscard]] const MapLocalizerCounters& counters() const noexcept { return counters_; }

 private:
  struct Particle {
    double x_m = 0.0;
    double y_m = 0.0;
    double yaw_rad = 0.0;
    double log_weight = 0.0;
  };
  void move(const Pose2& from, const Pose2& to) noexcept;
  // The scan's returns (at most max_points, evenly spread) into points_m_; how many.
  std::size_t pick_points(std::span<const Eigen::Vector2d> points_m) noexcept;
  void weigh(std::size_t point_count) noexcept;
  [[nodiscard]] double effective_particles() const noexcept;
  void resample() noexcept;
  // The covariance of the particles' positions about `mean`.
  [[nodiscard]] Eigen::Matrix2d spread(const Pose2& mean) const noexcept;
  // What the walls say of the position, seen from `pose`: the points within two hit sigmas of
  // a wall (their share of point_count in `hit_share`), each pinning it along its wall's
  // normal, weighed as independent_points together.
  [[nodiscard]] Eigen::Matrix2d wall_information(const Pose2& pose, std::size_t point_count,
                                                 double& hit_share) const noexcept;
  // The placing's information: the walls' in the directions they pin down, widened by the
  // particles' spread there; false when the particles disagree in one of them, or none is.
  bool placing_information(const Eigen::Matrix2d& walls, const Eigen::Matrix2d& spread,
                           Eigen::Matrix2d& information) noexcept;

  PriorMapConfig config_;
  PriorMap map_;
  Random random_{1, "localize.prior_map"};
  std::span<Particle> particles_;
  std::span<Particle> scratch_;
  std::span<Eigen::Vector2d> points_m_;
  bool started_ = false;
  Pose2 last_pose_;    // the path's pose at the last scan
  Pose2 last_update_;  // ... and at the last update
  double since_placing_m_ = 0.0;
  std::uint32_t off_the_map_in_a_row_ = 0;
  MapLocalizerCounters counters_;
};

}  // namespace blockmap::localize
