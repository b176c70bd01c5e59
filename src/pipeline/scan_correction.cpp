#include "blockmap/pipeline/scan_correction.hpp"

namespace blockmap::pipeline {

void ScanCorrection::init(Arena& arena, const localize::ScanMatchConfig& config,
                          const std::array<bool, kMaxLasers>& matched) {
  matcher_.init(arena, config);
  for (std::size_t laser = 0; laser < kMaxLasers; ++laser) {
    matched_[laser] = matcher_.enabled() && matched[laser];
  }
}

ScanCorrection::Outcome ScanCorrection::correct(std::size_t laser,
                                                const localize::Localizer& localizer,
                                                RigidPathSolver* path, localize::Pose3& first,
                                                localize::Pose3& last,
                                                std::span<Eigen::Vector3f> points_m) noexcept {
  if (!matcher_.enabled()) {
    return Outcome::kUnchanged;
  }
  if (localizer.carrier_phase_holds(first.stamp_ns)) {
    // Centimetre fixes hold the poses tighter than a scan matcher's own drift: the scans are
    // drawn as the filter puts them. The matcher's grid starts over when they stop.
    const bool pausing = !paused_;
    paused_ = true;
    return pausing ? Outcome::kPaused : Outcome::kUnchanged;
  }
  localize::PlanarCorrection correction;
  localize::Pose3 drawn;
  localize::Pose2 odometry;
  if (matched_[laser] && localizer.map_pose_at(first.stamp_ns, drawn, &odometry)) {
    // An anchored matcher whose filter's poses jumped to its estimate (its start, a recovery)
    // since the last matched scan: the grid drawn with the poses before is of another frame.
    // By the snap's stamp, not by when the localizer made it: it runs ahead of the scans by
    // however the messages came. (Unanchored, the frame is the matcher's and goes on.)
    if (paused_ || (matcher_.anchored() &&
                    localizer.map_pose_snapped_between(last_matched_scan_ns_, first.stamp_ns))) {
      paused_ = false;
      matcher_.reset();
      if (path != nullptr) {
        path->rebase();
      }
    }
    last_matched_scan_ns_ = first.stamp_ns;
    const localize::Pose2 raw{first.stamp_ns, first.x_m, first.y_m, first.yaw_rad};
    correction = matcher_.add_scan(raw, odometry, first.z_m, points_m);
    if (path != nullptr) {
      path->add_matched_scan(first.stamp_ns, matcher_.matched(), correction.apply(raw), odometry,
                             matcher_.last_scan_matched(), matcher_.match_points());
    }
    corrections_.push_overwrite({first.stamp_ns, correction});
  } else {
    correction = kept_before(first.stamp_ns);
  }
  correction.apply(points_m);
  for (localize::Pose3* pose : {&first, &last}) {
    const localize::Pose2 moved =
        correction.apply(localize::Pose2{pose->stamp_ns, pose->x_m, pose->y_m, pose->yaw_rad});
    pose->x_m = moved.x_m;
    pose->y_m = moved.y_m;
    pose->yaw_rad = moved.yaw_rad;
  }
  return Outcome::kCorrected;
}

localize::PlanarCorrection ScanCorrection::kept_before(TimestampNs stamp_ns) const noexcept {
  // By stamp: a later scan of the matched laser may have been drawn first (it ended sooner).
  localize::PlanarCorrection correction;
  TimestampNs best_ns = 0;
  bool found = false;
  for (std::size_t i = 0; i < corrections_.size(); ++i) {
    const StampedCorrection& kept = corrections_[i];
    if (kept.stamp_ns <= stamp_ns && (!found || kept.stamp_ns > best_ns)) {
      best_ns = kept.stamp_ns;
      correction = kept.correction;
      found = true;
    }
  }
  return correction;
}

}  // namespace blockmap::pipeline
