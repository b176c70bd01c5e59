// The lasers' own scan planes, which are not surfaces. A laser that moves within its scan
// plane (a level one on a driving robot) lays every return on that plane, scan after scan,
// whatever it hits: the foliage, hedges and people it sweeps become flat sheets through the
// places it has been. A detected plane near such a laser's plane along its path is dropped
// (planes::PlaneExclusion); a laser sweeping across the way (the paper's vertical one) paints
// a new slice each scan and makes no sheet.
#pragma once

#include <array>
#include <cstddef>
#include <span>

#include <Eigen/Core>

#include "blockmap/localize/particle_filter.hpp"
#include "blockmap/map/scan_projector.hpp"
#include "blockmap/pipeline/lasers.hpp"
#include "blockmap/planes/plane_merger.hpp"

namespace blockmap::pipeline {

// Positions of each laser kept for recognising its scan plane (128 m at 0.5 m).
inline constexpr std::size_t kScanPlanePath = 256;

class ScanPlanes {
 public:
  // A plane within angle_deg of a laser's scan plane that passes within distance_m of where
  // the laser has been is that plane; positions are kept every spacing_m of its path.
  void init(double angle_deg, double distance_m, double spacing_m) noexcept;
  // A laser's position and scan plane at a scan's first beam.
  void record(std::size_t laser, const map::ScanProjector& projector,
              const localize::Pose3& pose) noexcept;
  // What the detector leaves out now, for the first `laser_count` lasers.
  [[nodiscard]] std::span<const planes::PlaneExclusion> exclusions(
      std::size_t laser_count) noexcept;

 private:
  // Where a laser has been, moving within its scan plane (a ring, in any order).
  struct LaserPath {
    std::array<Eigen::Vector3d, kScanPlanePath> origins_m{};
    std::size_t count = 0;
    std::size_t next = 0;
    Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
    Eigen::Vector3d last_origin_m = Eigen::Vector3d::Zero();
  };
  std::array<LaserPath, kMaxLasers> paths_{};
  std::array<planes::PlaneExclusion, kMaxLasers> exclusions_{};
  double cos_angle_ = 1.0;
  double sin_angle_ = 0.0;
  double distance_m_ = 0.0;
  double spacing_m_ = 0.0;
};

}  // namespace blockmap::pipeline
