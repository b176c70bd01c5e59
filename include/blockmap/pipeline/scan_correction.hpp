// The mapper's scan matching: each level laser's scan matched against the grid of what the
// scans before it hit (localize::ScanMatcher, docs/localize.md), and every scan, of any laser,
// drawn with the corrected pose. The matched poses are the rigid path's odometry.
#pragma once

#include <array>
#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "blockmap/core/arena.hpp"
#include "blockmap/core/ring_buffer.hpp"
#include "blockmap/localize/localizer.hpp"
#include "blockmap/localize/scan_matcher.hpp"
#include "blockmap/pipeline/lasers.hpp"
#include "blockmap/pipeline/rigid_path_solver.hpp"

namespace blockmap::pipeline {

class ScanCorrection {
 public:
  // `matched`: which lasers' scans are matched (the level ones); the others take the
  // correction of the last matched scan before them.
  void init(Arena& arena, const localize::ScanMatchConfig& config,
            const std::array<bool, kMaxLasers>& matched);
  [[nodiscard]] static std::size_t arena_bytes(const localize::ScanMatchConfig& config) noexcept {
    return localize::ScanMatcher::arena_bytes(config);
  }
  [[nodiscard]] bool enabled() const noexcept { return matcher_.enabled(); }

  enum class Outcome : std::uint8_t {
    kCorrected,
    kPaused,     // carrier-phase fixes began to hold the poses: drawn as the filter puts them
    kUnchanged,  // matching is off, or still paused
  };
  // Moves the scan's points and its first and last beams' poses by the correction. A matched
  // laser's scan is matched first, and its pose goes to `path` when there is one.
  Outcome correct(std::size_t laser, const localize::Localizer& localizer, RigidPathSolver* path,
                  localize::Pose3& first, localize::Pose3& last,
                  std::span<Eigen::Vector3f> points_m) noexcept;

  [[nodiscard]] const localize::ScanMatcher& matcher() const noexcept { return matcher_; }

 private:
  // The correction of the last matched scan at or before `stamp_ns` (the identity with none).
  [[nodiscard]] localize::PlanarCorrection kept_before(TimestampNs stamp_ns) const noexcept;

  localize::ScanMatcher matcher_;
  std::array<bool, kMaxLasers> matched_{};
  // The last matched scans' corrections, by stamp, for the other lasers' scans.
  struct StampedCorrection {
    TimestampNs stamp_ns = 0;
    localize::PlanarCorrection correction;
  };
  RingBuffer<StampedCorrection, 16> corrections_;
  TimestampNs last_matched_scan_ns_ = 0;
  bool paused_ = false;  // carrier-phase fixes hold the poses; the grid is stale
};

}  // namespace blockmap::pipeline
