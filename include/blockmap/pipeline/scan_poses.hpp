// Where the poses that draw the scans come from: the particle filter (localize::Localizer, fed
// the base's odometry and IMU and the GPS fixes), or poses given from outside (a simulation's
// truth, a survey), interpolated between the two around a scan's time.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include "blockmap/core/arena.hpp"
#include "blockmap/core/ring_buffer.hpp"
#include "blockmap/localize/localizer.hpp"
#include "blockmap/msg/odometry.hpp"

namespace blockmap::pipeline {

enum class PoseSource : std::uint8_t {
  kLocalizer,  // the particle filter, fed by on_base() and on_fix() (on the robot)
  kExternal,   // on_pose(): a reference trajectory (a simulation's truth, a survey)
};

class ScanPoses {
 public:
  // `max_external_poses`: the newest given poses kept to interpolate (kExternal).
  void init(Arena& arena, PoseSource source, const localize::LocalizerConfig& localizer,
            std::size_t max_external_poses);
  [[nodiscard]] static std::size_t arena_bytes(PoseSource source,
                                               const localize::LocalizerConfig& localizer,
                                               std::size_t max_external_poses) noexcept;

  // The messages, in time order.
  void on_base(const msg::OdometrySample& odometry, const msg::ImuSample& imu) noexcept;
  localize::GpsOutcome on_fix(const localize::GpsObservation& fix, double up_m) noexcept;
  void on_pose(const localize::Pose3& pose) noexcept;
  // kExternal: the given poses not drained yet, each once, oldest first (what the filter's
  // final poses are to trajectory.csv).
  std::size_t drain_given(std::span<localize::Pose3> out) noexcept;

  // The newest time the poses cover; false before the first pose.
  [[nodiscard]] bool horizon(TimestampNs& out) const noexcept;
  [[nodiscard]] bool at(TimestampNs stamp_ns, localize::Pose3& out) const noexcept;
  // Before the first pose: no pose will be older than this, with the base samples released so
  // far (the filter starts at a fix not yet released, drawn at the base sample before it, and
  // lagged poses reach back by the lag). False when nothing says yet.
  [[nodiscard]] bool first_pose_bound(TimestampNs& bound_ns) const noexcept;

  [[nodiscard]] PoseSource source() const noexcept { return source_; }
  [[nodiscard]] const localize::Localizer& localizer() const noexcept { return localizer_; }
  [[nodiscard]] localize::Localizer& localizer() noexcept { return localizer_; }

 private:
  PoseSource source_ = PoseSource::kLocalizer;
  localize::Localizer localizer_;
  double lag_s_ = 0.0;
  TimestampNs last_in_ns_ = 0;  // the last message in, of any kind
  bool any_in_ = false;
  TimestampNs last_base_ns_ = 0;  // the last base sample in
  bool any_base_ = false;
  RingBufferRef<localize::Pose3> given_;  // kExternal: the newest given poses
  std::size_t undrained_ = 0;             // of those, the newest not drained yet
};

}  // namespace blockmap::pipeline
