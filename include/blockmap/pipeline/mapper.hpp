// The onboard mapper: the one object that takes the devices' messages in and hands plane-list
// updates out. Its stages, each a class of its own (docs/design.md, "The pipeline"):
//   ReorderBuffer     odometry, IMU, fixes back in time order
//   ScanPoses         the particle filter (or given poses)            -> the robot's pose
//   ScanQueue         scans wait until the poses cover their last beam
//   ScanProjector     a scan with the pose at each beam                -> points
//   ScanCorrection    level scans matched against their own grid       -> corrected poses
//   RigidPathSolver   the whole run's path from matched scans and fixes -> where planes go
//   VoxelWindow       a ring of tiles around the robot                 -> samples
//   every extract_every_s:
//   PlaneDetector     Hough over sections, refit, merge (less ScanPlanes' own planes)
//   PlaneRegistry     ids over time                     -> added / changed / finalized
//   BuildingFitter    walls to rectangles, L and T, with virtual walls
//
// Everything is sized by init() from the configuration; step() allocates nothing. The same
// messages in the same order give the same updates, bit for bit.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>

#include "blockmap/buildings/building_fitter.hpp"
#include "blockmap/core/arena.hpp"
#include "blockmap/localize/localizer.hpp"
#include "blockmap/localize/path_smoother.hpp"
#include "blockmap/localize/scan_matcher.hpp"
#include "blockmap/map/free_space_grid.hpp"
#include "blockmap/map/plane_registry.hpp"
#include "blockmap/map/scan_projector.hpp"
#include "blockmap/map/voxel_window.hpp"
#include "blockmap/msg/laser_scan.hpp"
#include "blockmap/msg/odometry.hpp"
#include "blockmap/msg/plane_patch.hpp"
#include "blockmap/pipeline/compact_scan.hpp"
#include "blockmap/pipeline/lasers.hpp"
#include "blockmap/pipeline/mapper_config.hpp"
#include "blockmap/pipeline/reorder_buffer.hpp"
#include "blockmap/pipeline/rigid_path_solver.hpp"
#include "blockmap/pipeline/scan_correction.hpp"
#include "blockmap/pipeline/scan_planes.hpp"
#include "blockmap/pipeline/scan_poses.hpp"
#include "blockmap/pipeline/scan_queue.hpp"
#include "blockmap/planes/plane_detector.hpp"
#include "blockmap/planes/planes_config.hpp"

namespace blockmap::pipeline {

struct MapperCounters {
  std::uint64_t base_samples = 0;
  std::uint64_t fixes = 0;
  std::uint64_t fixes_rejected = 0;   // the localizer left them out as outliers
  std::uint64_t fixes_recovered = 0;  // the localizer started over around them
  std::uint64_t poses = 0;
  std::uint64_t scans = 0;
  std::uint64_t scans_projected = 0;
  std::uint64_t scans_refused_full = 0;  // the scan queue was full: the newest was refused
  std::uint64_t scans_without_pose = 0;  // no pose covers the scan (before the first one)
  std::uint64_t scans_unknown_laser = 0;
  std::uint64_t scans_too_many_beams = 0;  // more than max_beams: refused
  std::uint64_t messages_late = 0;         // older than what was already processed: dropped
  std::uint64_t reorder_forced = 0;        // the reorder buffer was full: its oldest went early
  std::uint64_t extractions = 0;
  std::uint64_t incremental_extractions = 0;  // of those, with the detector's kept samples
  std::uint64_t sections_searched = 0;        // over all extractions
  std::uint64_t sections_replayed = 0;        // of those, as the extraction before found them
  std::uint64_t sections_still_barren = 0;    // of those, planeless and grown too little
  std::uint64_t sections_settled = 0;         // of those, with planes and grown too little
  std::size_t peak_blocks = 0;  // the detector's occupied blocks, for sizing max_blocks
  // The most window samples the detector had no room for at one extraction (its blocks full:
  // [planes] max_blocks). Their points are in the window, not in the planes.
  std::size_t peak_samples_without_room = 0;
  // The most section planes and merged planes of one extraction: what [planes] max_patches
  // and max_planes are sized against.
  std::size_t peak_section_planes = 0;
  std::size_t peak_detected_planes = 0;
  std::uint64_t scan_planes_rejected = 0;  // detected planes that were a laser's scan plane
  std::uint64_t points = 0;
  // Times scan matching gave way to carrier-phase fixes (Localizer::carrier_phase_holds).
  std::uint64_t scan_matching_pauses = 0;
};

// A plane-list update: what changed since the previous one, at `stamp_ns` (scan time).
struct PlaneUpdate {
  TimestampNs stamp_ns = 0;
  std::span<const msg::PlaneChange> changes;
};

// Sees every projected scan's points (a recorder of the point cloud, when one is asked for).
class PointSink {
 public:
  PointSink() = default;
  PointSink(const PointSink&) = default;
  PointSink& operator=(const PointSink&) = default;
  virtual ~PointSink() = default;
  virtual void on_points(std::span<const Eigen::Vector3f> points_m) = 0;
};

class Mapper {
 public:
  // Takes every buffer from the arena; CHECK-fails on an invalid configuration.
  void init(Arena& arena, const MapperConfig& config);
  // An arena budget that init() fits in.
  [[nodiscard]] static std::size_t arena_bytes(const MapperConfig& config) noexcept;

  // Messages in. Each is queued (or counted and dropped) and processed by step().
  void on_base(const msg::OdometrySample& odometry, const msg::ImuSample& imu) noexcept;
  void on_fix(const localize::GpsObservation& fix, double up_m) noexcept;
  void on_pose(const localize::Pose3& pose) noexcept;
  // False when the scan was refused (queue full, or no such laser); counted either way.
  bool on_scan(std::size_t laser, const msg::LaserScan& scan) noexcept;
  // Optional; the sink must outlive the mapper's use of it.
  void set_point_sink(PointSink* sink) noexcept { point_sink_ = sink; }
  // No more messages: step() then processes everything left, extracts once more and
  // finalizes every plane.
  void end_of_input() noexcept { ending_ = true; }

  // Runs the pipeline over what is due. True when it produced a plane update (update()),
  // which stays valid until the next step(); call again until it returns false.
  bool step() noexcept;
  [[nodiscard]] PlaneUpdate update() const noexcept { return {update_stamp_ns_, changes_}; }

  // Poses of the localizer that left its smoothing window (each once), for trajectory.csv;
  // at the end, smoothed_poses() gives the rest.
  std::size_t drain_final_poses(std::span<localize::Pose3> out) noexcept;
  std::size_t smoothed_poses(std::span<localize::Pose3> out) const noexcept;

  [[nodiscard]] std::span<const msg::PlanePatch> final_planes() const noexcept {
    return registry_.final_planes();
  }
  // The buildings of the map as it stands (refitted after every extraction and at the end);
  // empty when fit_buildings is off. Valid until the next step().
  [[nodiscard]] std::span<const buildings::Building> buildings() const noexcept {
    return config_.fit_buildings ? building_fitter_.buildings()
                                 : std::span<const buildings::Building>{};
  }
  [[nodiscard]] const buildings::BuildingFitter& building_fitter() const noexcept {
    return building_fitter_;
  }
  [[nodiscard]] const MapperConfig& config() const noexcept { return config_; }
  [[nodiscard]] const MapperCounters& counters() const noexcept { return counters_; }
  [[nodiscard]] const map::VoxelWindow& window() const noexcept { return window_; }
  [[nodiscard]] const map::PlaneRegistry& registry() const noexcept { return registry_; }
  [[nodiscard]] const map::FreeSpaceGrid& free_space() const noexcept { return free_space_; }
  // For snapshots: every plane as it would be if the run ended now
  // (PlaneRegistry::save); the map is left as it was.
  [[nodiscard]] std::size_t save_planes(std::span<map::SavedPlane> out) noexcept {
    return registry_.save(out);
  }
  // Resuming from a snapshot, before the first message: the saved planes become the map's
  // final planes (reopened under their ids when seen again), and the buildings are fitted.
  void restore_planes(std::span<const map::SavedPlane> planes) noexcept;
  // A prior 2D map's walls, at start-up ([prior_map] enabled): empty when it worked, else why
  // not (its extent over the grid's capacity, no walls).
  [[nodiscard]] std::string set_prior_map(std::span<const localize::MapWall> walls) {
    return path_on_ && config_.prior_map.enabled
               ? path_.set_prior_map(walls)
               : std::string("the prior map needs [prior_map] enabled and the rigid path");
  }
  [[nodiscard]] const planes::PlaneDetector& detector() const noexcept { return detector_; }
  [[nodiscard]] const localize::Localizer& localizer() const noexcept { return poses_.localizer(); }
  [[nodiscard]] const localize::ScanMatcher& scan_matcher() const noexcept {
    return scan_correction_.matcher();
  }
  [[nodiscard]] const localize::PathSmoother& rigid_path() const noexcept { return path_.path(); }
  [[nodiscard]] RigidPathCounters rigid_path_counters() const noexcept { return path_.counters(); }
  [[nodiscard]] const localize::LoopCloser& loop_closer() const noexcept {
    return path_.loop_closer();
  }
  [[nodiscard]] const localize::MapLocalizer& map_localizer() const noexcept {
    return path_.map_localizer();
  }
  [[nodiscard]] bool rigid_path_on() const noexcept { return path_on_; }
  [[nodiscard]] const map::ProjectionCounters& projection(std::size_t laser) const noexcept {
    return projectors_[laser].counters();
  }
  // The ground returns far from the lasers, dropped (ScanProjectorConfig::far_ground_range_m).
  [[nodiscard]] std::uint64_t far_ground_returns() const noexcept {
    std::uint64_t sum = 0;
    for (std::size_t laser = 0; laser < config_.laser_count; ++laser) {
      sum += projectors_[laser].counters().far_ground;
    }
    return sum;
  }

 private:
  void enqueue(const TimedMessage& message) noexcept;
  // A message in time order to the pose source; its fixes to the rigid path too.
  void feed_poses(const TimedMessage& message) noexcept;
  // Before the first pose: the queued scans that start before it (all that the released
  // messages rule out) are counted without a pose and leave the queue.
  void drop_scans_before_first_pose() noexcept;

  // The stages of step(), in order; true when the step made an update.
  bool show_planes_where_the_path_puts_them() noexcept;
  bool draw_scans_until_extraction() noexcept;
  bool finish_map() noexcept;
  // After the end's move: final planes it laid on one surface become one, in updates of
  // their own (kChangesPerDatagram changes each).
  bool join_final_planes() noexcept;
  // The changes of an update the mapper makes beyond a detection's (the view's, the joins'):
  // one datagram, 128 entries of at most 427 bytes.
  static constexpr std::size_t kChangesPerDatagram = 128;
  bool report_changes() noexcept;

  // The oldest queued scan whose last beam the poses cover (all of them when ending); or -1.
  // oldest_waiting_ns: the oldest stamp among the queued scans the poses do not cover yet.
  [[nodiscard]] std::ptrdiff_t next_ready_scan(TimestampNs& oldest_waiting_ns) const noexcept;
  // The scan at `position` of the queue: projected with its poses, corrected by scan
  // matching, into the voxel window.
  void draw_scan(std::size_t position) noexcept;
  // The poses of a scan's first and last beams; false when the poses do not cover it.
  bool poses_of_scan(TimestampNs first_ns, TimestampNs last_ns, localize::Pose3& first,
                     localize::Pose3& last) noexcept;
  // A level laser's beams carve the free-space grid, from its position at `pose`.
  void carve_free_space(std::size_t laser, const localize::Pose3& pose,
                        std::span<const Eigen::Vector3f> points_m) noexcept;

  // The window's planes: detected, registered, the buildings fitted again.
  void extract(TimestampNs stamp_ns) noexcept;
  // The window's samples into the detector: all of them, or those that changed.
  void give_detector_the_window() noexcept;
  void count_detection(std::size_t plane_count) noexcept;
  void refit_buildings() noexcept;
  void fit_buildings_to_map() noexcept;

  // A tile leaving the window: the registry freezes what it held of its planes, and its
  // samples leave the detector's kept grid, which then goes on instead of starting over.
  class TileLeaving final : public map::VoxelWindow::EvictionSink {
   public:
    explicit TileLeaving(Mapper& mapper) noexcept : mapper_(&mapper) {}
    void on_evicted(const map::VoxelWindow::EvictedTile& tile) noexcept override;

   private:
    Mapper* mapper_;
  };

  MapperConfig config_;
  // The stages, in the order a message goes through them.
  ReorderBuffer reorder_;
  ScanPoses poses_;
  ScanQueue scans_;
  std::array<map::ScanProjector, kMaxLasers> projectors_{
      map::ScanProjector({}, {}), map::ScanProjector({}, {}), map::ScanProjector({}, {}),
      map::ScanProjector({}, {})};
  ScanCorrection scan_correction_;
  RigidPathSolver path_;
  map::VoxelWindow window_;
  ScanPlanes scan_planes_;
  planes::PlaneDetector detector_;
  map::PlaneRegistry registry_;
  buildings::BuildingFitter building_fitter_;
  map::FreeSpaceGrid free_space_;

  TileLeaving tile_leaving_{*this};
  std::span<Eigen::Vector3f> points_;  // the scan being drawn
  std::array<bool, kMaxLasers> carves_free_space_{};
  bool path_on_ = false;
  // The path was solved before the last extraction: the view is refreshed in the update after
  // it (an extraction's step always returns, so where it lands does not depend on how the
  // messages were batched between steps).
  bool view_due_ = false;
  // Level lasers only: no laser sees a height, so the scans are drawn at the first pose's
  // height (held_z_m) rather than the GPS's, which wanders by metres (only_level_lasers()).
  bool level_lasers_only_ = false;
  bool height_held_ = false;
  double held_z_m_ = 0.0;

  bool extraction_scheduled_ = false;
  bool extracted_before_ = false;
  TimestampNs next_extraction_ns_ = 0;
  TimestampNs last_scan_ns_ = 0;
  bool ending_ = false;
  bool final_extracted_ = false;
  bool finalized_ = false;
  bool finals_joined_ = false;
  TimestampNs update_stamp_ns_ = 0;
  std::span<const msg::PlaneChange> changes_;
  PointSink* point_sink_ = nullptr;
  MapperCounters counters_;
};

}  // namespace blockmap::pipeline
