// Scan projection, the mapper's first step (the paper: "laser scans become a point cloud"):
// each valid beam of a 2D scan becomes a 3D point in the local frame, through the laser's
// mount on the robot and the robot's pose when the beam was taken, pitch and roll included
// (the Segway pitches by degrees when it accelerates, which moves a point 20 m away by tens of
// centimetres).
//
// A scan takes time (13 ms for an LMS2xx turn), and the robot moves and turns meanwhile: the
// pose is interpolated between the poses at the first and the last beam, beam by beam, as the
// simulator moves its beams. Beams without a return, flagged by the device, or outside the
// configured range band are dropped and counted; so are, for the map, returns from the ground
// far from the laser (ScanProjectorConfig::far_ground_range_m). Nothing here allocates.
#pragma once

#include <array>
#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "blockmap/core/time.hpp"
#include "blockmap/localize/localizer.hpp"
#include "blockmap/msg/laser_scan.hpp"

namespace blockmap::map {

// A sensor's pose on the robot, in the robot frame (origin at the middle of the wheel axle, x
// forward, y left, z up): its position, then roll, pitch and yaw applied in that order
// (R = Rz(yaw) Ry(pitch) Rx(roll)), as the robot files give it.
struct SensorMount {
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();
  double roll_rad = 0.0;
  double pitch_rad = 0.0;
  double yaw_rad = 0.0;
};

// The mount's rotation from the sensor's frame to the robot's (roll, then pitch, then yaw).
[[nodiscard]] Eigen::Matrix3d mount_rotation(const SensorMount& mount) noexcept;

struct ScanProjectorConfig {
  // The band of ranges kept: nearer returns are the robot itself or its rider, farther ones
  // carry too much of the pose's angular error (0.5 deg is 0.35 m at 40 m).
  double min_range_m = 0.3;
  double max_range_m = 40.0;
  // Ground returns farther than this from the laser (horizontally) stay out of the map
  // (drop_far_ground); 0 keeps them.
  // A level laser on the RMP, which rocks by degrees as it accelerates, sweeps the ground in
  // grazing arcs out to its range: at 2 deg nose down the beams meet the ground 23 m ahead. Such
  // arcs put a few points in each of many samples all over the window, never make a plane, and
  // on benning were half of the window's samples (docs/mapper.md, Speed); the ground near the
  // robot is dense and keeps its plane. 0 in this struct; the mapper's configuration from a
  // robot file (hal::sim::mapper_config_for) sets 8 m, and `[projection] far_ground_range_m
  // = 0` turns it off (docs/mapper.md, Speed). mapper_config_for also sets the
  // axle's height from the robot file's wheel radius.
  double far_ground_range_m = 0.0;
  // A return is ground when it lies less than this above the ground under the robot...
  double ground_band_m = 0.4;
  // ...which is this far below the robot frame's origin (the wheel axle: the wheel radius).
  double axle_height_m = 0.0;
};

struct ProjectionCounters {
  std::uint64_t scans = 0;
  std::uint64_t points = 0;            // projected
  std::uint64_t no_return = 0;         // the device saw nothing within its range
  std::uint64_t flagged = 0;           // dazzled, too close or a device error
  std::uint64_t below_min_range = 0;   // valid, but nearer than min_range_m
  std::uint64_t beyond_max_range = 0;  // valid, but farther than max_range_m
  std::uint64_t non_finite = 0;        // a NaN or infinite range marked valid
  std::uint64_t far_ground = 0;        // the ground, farther than far_ground_range_m
  std::uint64_t output_full = 0;       // beams beyond the caller's output span
};

class ScanProjector {
 public:
  ScanProjector(const SensorMount& mount, const ScanProjectorConfig& config) noexcept;

  // When beam `beam` of `scan` was taken: the scan's stamp plus the beam's index times the
  // time between beams (all at the stamp when the device does not say).
  [[nodiscard]] static TimestampNs beam_stamp_ns(const msg::LaserScan& scan,
                                                 std::uint32_t beam) noexcept;
  [[nodiscard]] static TimestampNs last_beam_stamp_ns(const msg::LaserScan& scan) noexcept;

  // Writes the scan's points (local frame) into `out` and returns how many. `first` and
  // `last` are the robot's poses at beam_stamp_ns(scan, 0) and last_beam_stamp_ns(scan) (the
  // same pose twice for a robot standing still or a scan without beam timing).
  std::size_t project(const msg::LaserScan& scan, const localize::Pose3& first,
                      const localize::Pose3& last, std::span<Eigen::Vector3f> out) noexcept;

  // Of the points of a scan drawn with the robot at `pose` (its first beam's), drops the ground
  // farther than far_ground_range_m from the laser, keeping the others' order in the front of
  // `points_m`, and returns how many are kept. The scan matcher and the free-space raster take
  // every point first: a far ground return is still a beam that saw through, and the bottom of
  // a far wall that the matcher can use.
  std::size_t drop_far_ground(const localize::Pose3& pose,
                              std::span<Eigen::Vector3f> points_m) noexcept;

  // The laser's scan plane in the local frame at `pose`: its origin and unit normal.
  void scan_plane(const localize::Pose3& pose, Eigen::Vector3d& origin_m,
                  Eigen::Vector3d& normal) const noexcept;

  [[nodiscard]] const ProjectionCounters& counters() const noexcept { return counters_; }
  // What this object holds (the beam directions table lives inside it).
  [[nodiscard]] static constexpr std::size_t memory_bytes() noexcept {
    return sizeof(ScanProjector);
  }

 private:
  // The beams' unit directions in the robot frame (the mount's rotation applied), computed
  // again only when a scan's angles differ from the last one's.
  void update_beam_directions(const msg::LaserScan& scan) noexcept;

  SensorMount mount_;
  ScanProjectorConfig config_;
  Eigen::Matrix3d mount_rotation_ = Eigen::Matrix3d::Identity();
  std::array<Eigen::Vector3d, msg::kMaxLaserBeams> beam_directions_{};
  double table_start_rad_ = 0.0;
  double table_increment_rad_ = 0.0;
  std::uint16_t table_beams_ = 0;
  ProjectionCounters counters_;
};

// The rotation of the robot frame into the local frame at a pose: Rz(yaw) Ry(pitch) Rx(roll),
// positive pitch nose down (the RMP's sign).
[[nodiscard]] Eigen::Matrix3d robot_rotation(const localize::Pose3& pose) noexcept;

}  // namespace blockmap::map
