// Scan-to-map matching for the mapper's poses (docs/localize.md, Scan matching).
//
// The particle filter's pose is GPS-grade: it follows the receiver's slow error, which
// wanders by a metre over a minute, and its heading by a degree or two between fixes. Scans
// drawn with it bend a wall seen over half a minute and set two passes of one street apart
// (docs/mapper.md, Accuracy). A level laser sees the same walls, trunks and kerbs scan after
// scan, 75 times a second: matched against what the scans before it hit, each scan says
// where the robot is relative to the map far better than GPS can (Hector SLAM's scan-to-map
// matching: Kohlbrecher et al., 2011).
//
// What it keeps: a grid of where the level lasers hit, at `levels` resolutions (cell_m,
// 2 cell_m, ...), each a ring of cells_across x cells_across cells indexed by the cell's
// coordinates modulo its size, that scrolls with the robot without copying (as the voxel
// window does), and forgets what no scan has hit over the last forget_after_m of travel. A
// cell holds a hit count that saturates; hits only, no ray casting: the matcher needs where
// the surfaces are, and a moving person leaves a few hits that the surfaces around outvote.
//
// What it does with a scan (add_scan):
//  1. The prediction, in the matcher's own frame: the matched pose of the scan before, moved
//     by the odometry since (the wheels and gyroscope as they report, less the gyroscope bias
//     the matches have shown; not the filter's pose, which is drawn toward GPS fixes and
//     turns with them). Between two scans of a 75 Hz laser that is millimetres off.
//  2. Gauss-Newton on the bilinearly interpolated grid, coarse to fine (Hector's
//     (1 - M(S(xi)))^2). Each point moves only across its own surface (its normal from its
//     neighbours in the scan), and a prior at the prediction holds what the scan does not
//     say: weakly across the way and in heading, strongly along it, where the odometry's
//     distance is better than a street's walls and a cell's steps.
//  3. Refusal: too few points, too few of them on the map (new ground), or a step from the
//     prediction larger than a scan's worth of error: the prediction stands.
//  4. Every map_update_m of motion the scan's points go into the grid at the matched pose,
//     neighbouring returns joined (a wall met at a grazing angle is hit a metre apart). The
//     grid and the matched poses are in the matcher's own frame, which nothing moves: the
//     frame the first scan set.
//  5. Anchoring: that frame is laid onto the local frame by the rigid motion that best lays
//     the matched path onto the filter's (Procrustes over an exponential memory of
//     anchor_time_s). Every scan is drawn with both: rigid over the minutes the grid holds,
//     where GPS puts it over those minutes. The anchor moves by the GPS's slow error
//     averaged over that memory, not by each fix. A caller that places the matched path
//     itself (the mapper's rigid path) turns the anchor off (anchor_time_s 0): the frame
//     is then the first scan's for the whole run, and a wall seen while an anchor moved
//     would have bent with it.
//
// Fixed size: the grid and the scan's points are taken from the arena at init; add_scan
// allocates nothing.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

#include <Eigen/Core>

#include "blockmap/core/arena.hpp"
#include "blockmap/localize/particle_filter.hpp"

namespace blockmap::localize {

struct ScanMatchConfig {
  bool enabled = true;
  double cell_m = 0.1;                // the finest level's cell
  std::uint32_t cells_across = 1024;  // per level 0 side (a power of two): 102.4 m at 0.1 m
  std::uint32_t levels = 4;           // 0.1, 0.2, 0.4, 0.8 m: a capture range of about 1 m
  std::uint32_t iterations = 3;       // Gauss-Newton steps per level
  // The points a match uses: returns this high above the robot frame's origin (the ground a
  // pitching robot's level laser meets is not a landmark), at most max_points of them, each
  // at least point_spacing_m from the one kept before it in the scan.
  double min_height_m = 0.0;
  double max_height_m = 3.0;
  double point_spacing_m = 0.05;
  // Only returns this near the robot are matched, though all go into the grid: the grid's
  // edge, where the lasers' range ended for the scans before, lies beyond them. (Matched
  // there, a return just past the edge is pulled back into what is known, and every scan
  // drags the pose back along a street.)
  double max_match_range_m = 40.0;
  // A scan goes into the grid only once the robot has moved this far or turned this much
  // since the last one that did (Hector's map update thresholds). Every scan matched against
  // a grid it drew itself a centimetre back is held there by the cells' steps: the pose
  // sticks, the next scan draws the street where it stuck, and the street smears along
  // itself. Matched against a grid that holds still, a scan's small errors do not add up.
  double map_update_m = 0.25;
  // Neighbouring returns closer than this mark the cells between them (one surface).
  double join_gap_m = 1.0;
  // A point's surface normal is taken from its neighbours in the scan this near to it.
  double normal_neighbour_m = 2.0;
  double map_update_rad = 0.035;
  // The grid forgets a cell that no scan has hit over this much of the robot's travel (0:
  // never): the scans are matched against what the robot saw lately, as Cartographer's local
  // SLAM matches against its newest submaps. Come back to a street it saw long ago, it would
  // otherwise match against that pass's cells and turn at once by the drift of the whole
  // loop, which the path would take as motion; revisits are the loop closer's.
  double forget_after_m = 120.0;
  std::uint32_t max_points = 512;
  std::uint32_t min_points = 30;
  // A match counts when at least this share of its points lies on the map, and moves the
  // pose from the prediction by no more than these.
  double min_overlap = 0.3;
  double max_step_m = 0.3;
  double max_step_rad = 0.035;  // 2 deg
  // The matcher's own frame is laid onto the local frame by the rigid motion that best lays
  // its path onto the filter's, over the last anchor_time_s or so (an exponential memory; 0:
  // the frame stays where the first scan put it). Each sample's heading difference counts as
  // much as a pair of positions anchor_heading_lever_m apart.
  double anchor_time_s = 120.0;
  double anchor_heading_lever_m = 5.0;
  // The odometry's gyroscope bias, learnt from the matches: each matched scan's turn away from
  // its prediction moves the estimate by itself over this time (an integral controller; 0:
  // the odometry's turn is taken as it comes).
  double yaw_rate_bias_time_s = 20.0;
  // The prior at the prediction, per point and per unit of the data's own weight: small
  // against what a seen surface says, large enough to hold what nothing says.
  double prior_weight = 0.05;
  // ... and this many times as strong along the robot's heading (the odometry's distance).
  double prior_along_ratio = 100.0;
};

// Empty when usable, otherwise what is wrong.
[[nodiscard]] std::string validate(const ScanMatchConfig& config);

struct ScanMatchCounters {
  std::uint64_t scans = 0;
  std::uint64_t matched = 0;
  std::uint64_t few_points = 0;  // too few points in the height band
  std::uint64_t off_map = 0;     // too few of its points on the map (new ground, the start)
  std::uint64_t too_far = 0;     // the match moved the pose further than a scan's error
  std::uint64_t resets = 0;      // the filter's pose jumped: the grid started over
};

// A planar rigid motion of the local frame: corrected = R(yaw) raw + shift.
struct PlanarCorrection {
  double yaw_rad = 0.0;
  double cos_yaw = 1.0;
  double sin_yaw = 0.0;
  double x_m = 0.0;
  double y_m = 0.0;

  [[nodiscard]] Eigen::Vector2d apply(const Eigen::Vector2d& raw_m) const noexcept {
    return {cos_yaw * raw_m.x() - sin_yaw * raw_m.y() + x_m,
            sin_yaw * raw_m.x() + cos_yaw * raw_m.y() + y_m};
  }
  [[nodiscard]] Pose2 apply(const Pose2& raw) const noexcept;
  // Moves points in place (their heights as they are).
  void apply(std::span<Eigen::Vector3f> points_m) const noexcept;
  [[nodiscard]] bool identity() const noexcept {
    return yaw_rad == 0.0 && x_m == 0.0 && y_m == 0.0;
  }
};

// The motion that takes `from` to `to`, and `first` followed by `second`.
[[nodiscard]] PlanarCorrection motion_between(const Pose2& from, const Pose2& to) noexcept;
// `to` in the frame of `from`: (ahead, to the left, turn).
[[nodiscard]] Eigen::Vector3d pose_in_frame_of(const Pose2& from, const Pose2& to) noexcept;
[[nodiscard]] PlanarCorrection compose(const PlanarCorrection& second,
                                       const PlanarCorrection& first) noexcept;

class ScanMatcher {
 public:
  void init(Arena& arena, const ScanMatchConfig& config);
  [[nodiscard]] static std::size_t arena_bytes(const ScanMatchConfig& config) noexcept;

  // One level laser's scan, its points in the local frame as drawn with raw_pose (the
  // filter's pose at the scan's first beam; robot_z_m its height), and the odometry's own
  // pose at that time (Localizer::map_pose_at). Matches the points, corrects the pose and
  // adds the points to the grid where the corrected pose puts them. Returns the correction
  // for this scan's points, which also holds for other lasers' scans until the next one.
  const PlanarCorrection& add_scan(const Pose2& raw_pose, const Pose2& odometry_pose,
                                   double robot_z_m,
                                   std::span<const Eigen::Vector3f> points_m) noexcept;
  // The filter's poses jumped (a snap to the estimate): the grid is of another frame.
  void reset() noexcept;

  [[nodiscard]] bool enabled() const noexcept { return config_.enabled; }
  // Whether its frame is laid onto the filter's path (anchor_time_s > 0): a snap of the
  // filter's poses then moves the grid's place, and the grid starts over. Unanchored, the
  // frame is the matcher's alone, and a snap changes nothing in it.
  [[nodiscard]] bool anchored() const noexcept { return config_.anchor_time_s > 0.0; }
  [[nodiscard]] const PlanarCorrection& correction() const noexcept { return correction_; }
  // The last scan's pose in the matcher's own frame (the grid's).
  [[nodiscard]] const Pose2& matched() const noexcept { return last_matched_; }
  // Whether the last scan was matched (or its prediction stood: refused, too few points).
  [[nodiscard]] bool last_scan_matched() const noexcept { return tracking_; }
  // The last scan's points that took part in its match.
  [[nodiscard]] std::size_t points_used() const noexcept { return scan_count_; }
  // Those points, in the robot frame.
  [[nodiscard]] std::span<const Eigen::Vector2d> match_points() const noexcept {
    return scan_m_.first(scan_count_);
  }
  [[nodiscard]] const ScanMatchCounters& counters() const noexcept { return counters_; }
  // The gyroscope bias the matches say the odometry's turn has (rad/s).
  [[nodiscard]] double yaw_rate_bias_radps() const noexcept { return yaw_rate_bias_radps_; }
  [[nodiscard]] std::size_t memory_bytes() const noexcept;
  // The finest level's hit count at a point (0 outside the grid): for tests.
  [[nodiscard]] std::uint8_t hits_at(const Eigen::Vector2d& point_m) const noexcept;

 private:
  struct Level {
    std::span<std::uint8_t> cells;
    double cell_m = 0.0;
    double inverse_cell_m = 0.0;
    std::int64_t across = 0;    // a power of two
    std::int64_t origin_x = 0;  // the cell index of the window's lower left corner
    std::int64_t origin_y = 0;
  };
  // The grid's value at a point and its gradient (per metre), bilinear between cell centres.
  struct Sample {
    double value = 0.0;
    double d_dx = 0.0;
    double d_dy = 0.0;
  };
  // The anchor's sums: an exponentially weighted Procrustes of matched onto filter poses.
  struct Anchor {
    double weight = 0.0;
    double matched_x_m = 0.0;
    double matched_y_m = 0.0;
    double raw_x_m = 0.0;
    double raw_y_m = 0.0;
    double dot_m2 = 0.0;
    double cross_m2 = 0.0;
    double heading_cos = 0.0;
    double heading_sin = 0.0;
    void add(const Pose2& matched, const Pose2& raw, double since_last_s,
             const ScanMatchConfig& config) noexcept;
    [[nodiscard]] PlanarCorrection fit(const ScanMatchConfig& config) const noexcept;
  };
  // Steps 2 and 3: the pose in the matcher's frame, or the prediction when refused.
  [[nodiscard]] Eigen::Vector3d matched_pose(const Pose2& predicted, const Pose2& raw_pose,
                                             double robot_z_m,
                                             std::span<const Eigen::Vector3f> points_m) noexcept;
  // After a match that followed a match: the turn it took from the prediction.
  void learn_yaw_rate_bias(double turn_from_prediction_rad) noexcept;
  [[nodiscard]] std::size_t select_points(const Pose2& raw_pose, double robot_z_m,
                                          std::span<const Eigen::Vector3f> points_m) noexcept;
  void recentre(const Eigen::Vector2d& robot_m) noexcept;
  void scroll(Level& level, std::int64_t origin_x, std::int64_t origin_y) noexcept;
  [[nodiscard]] double cell_value(const Level& level, std::int64_t x,
                                  std::int64_t y) const noexcept;
  [[nodiscard]] Sample sample(const Level& level, double x_m, double y_m) const noexcept;
  // Gauss-Newton steps at one level from `pose`, held at `prior` (x, y, yaw).
  void refine(const Level& level, const Eigen::Vector3d& prior,
              Eigen::Vector3d& pose) const noexcept;
  [[nodiscard]] double overlap(const Eigen::Vector3d& pose) const noexcept;
  void insert(std::span<const Eigen::Vector3f> points_m, double robot_z_m) noexcept;
  void mark(Level& level, std::int64_t x, std::int64_t y) noexcept;
  // The robot moved `step_m`: past an epoch's end, the cells last hit kEpochsKept epochs ago
  // are cleared.
  void age(double step_m) noexcept;

  ScanMatchConfig config_;
  std::span<Level> levels_;
  std::span<Eigen::Vector2d> scan_m_;        // the match's points in the robot frame
  std::span<Eigen::Vector2d> scan_normals_;  // each one's surface normal (zero: none known)
  std::size_t scan_count_ = 0;
  bool placed_ = false;  // the grid has a window (after the first scan)
  bool have_last_ = false;
  TimestampNs last_stamp_ns_ = 0;
  bool have_update_ = false;
  bool tracking_ = false;  // the last scan was matched
  Pose2 last_update_;      // the pose, in the matcher's frame, of the last scan that went in
  Pose2 last_matched_;     // the scan before's pose in the matcher's frame, and its odometry
  Pose2 last_odometry_;
  double yaw_rate_bias_radps_ = 0.0;  // kept across resets: the gyroscope's, not the grid's
  std::uint32_t epoch_ = 0;           // of the cells' last hits (forget_after_m), mod 64
  double epoch_travel_m_ = 0.0;       // the robot's travel since this epoch began
  PlanarCorrection to_grid_;          // the filter's frame to the matcher's, at the last scan
  Anchor anchor_;
  PlanarCorrection correction_;  // the filter's frame to the local frame: anchor after to_grid
  ScanMatchCounters counters_;
};

}  // namespace blockmap::localize
