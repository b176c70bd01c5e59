// The onboard mapper: the one object that takes the devices' messages in and hands plane-list
// updates out. Its step reads like the paper's pipeline:
//   odometry + IMU + GPS -> particle filter (the Localizer)         -> the robot's pose
//   laser scan + pose at each beam -> ScanProjector                  -> points
//   points -> VoxelWindow (a ring of tiles around the robot)         -> samples
//   every extract_every_s: samples -> PlaneDetector (Hough over sections, refit, merge)
//                          -> PlaneRegistry (ids over time)          -> added / changed / finalized
//
// Messages may arrive in any interleaving within reorder_window_s of the newest one: they wait
// in a fixed-size buffer ordered by time. A scan waits until the poses cover its last beam.
// Everything is sized by init() from the configuration; step() allocates nothing. The same
// messages in the same order give the same updates, bit for bit.
//
// A laser that moves within its own scan plane (a level one on a driving robot) lays every
// return on that plane, scan after scan, whatever it hits: the foliage, hedges and people it
// sweeps become flat sheets through the places it has been. Planes on such a laser's path
// are dropped (planes::PlaneExclusion); a laser sweeping across the way (the paper's vertical
// one) paints a new slice each scan and makes no sheet.
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
#include "blockmap/planes/plane_detector.hpp"
#include "blockmap/planes/planes_config.hpp"

namespace blockmap::pipeline {

inline constexpr std::size_t kMaxLasers = 4;
// Positions of each laser kept for recognising its scan plane (128 m at 0.5 m).
inline constexpr std::size_t kScanPlanePath = 256;

// Where the poses that project the scans come from.
enum class PoseSource : std::uint8_t {
  kLocalizer,  // the particle filter, fed by on_base() and on_fix() (on the robot)
  kExternal,   // on_pose(): a reference trajectory (a simulation's truth, a survey)
};

// The detector's defaults for a window: 6-9 samples per occupied block on the simulated
// worlds, so a quarter of the window's samples in blocks is plenty. max_blocks = 0 here means
// that quarter (detector_config), so that a larger window gets the blocks to hold it.
// The corner look is off: it found nothing more in the streamed maps measured (true, lagged
// and filter poses; docs/mapper.md) and took 4-6 % of the benning replay ([planes]
// corner_look = true turns it on).
[[nodiscard]] inline planes::PlanesConfig window_planes_config() noexcept {
  planes::PlanesConfig config;
  config.max_blocks = 0;
  config.corner_look = false;
  config.max_patches = 8192;
  config.max_planes = 512;
  return config;
}

// The localizer's defaults for the mapper: 2,000 particles (half the batch default) keep the
// whole pipeline inside 64 MiB; the smoothing window stays one minute.
[[nodiscard]] inline localize::LocalizerConfig mapper_localizer_config() noexcept {
  localize::LocalizerConfig config;
  config.filter.particle_count = 2000;
  return config;
}

[[nodiscard]] inline buildings::BuildingsConfig mapper_buildings_config() noexcept {
  buildings::BuildingsConfig config;
  config.max_walls = 512;
  config.max_buildings = 64;
  return config;
}

// When the mapper solves the whole run's path (MapperConfig::rigid_path).
enum class RigidPath : std::uint8_t {
  kOff,
  kWhereScansAreMatched,  // the default: scans matched and no free-space grid
  kOn  // asked for: a config with no scans to match or with a free-space grid is refused
};

// The path smoother as the mapper runs it. Its odometry is the scan matcher's matched poses,
// whose heading wanders more per metre than the calibrated wheels and gyroscope that the
// smoother's own defaults describe: a matcher against its own sliding map carries a heading
// error on, and starts a new frame when the filter's pose snaps. With 0.004 rad per root
// metre instead of 0.002 the solved path's shape over seeds 1-10 is 0.64 m instead of 0.70
// on benning, 0.48 instead of 0.54 on usc_block (docs/localize.md, In the mapper).
[[nodiscard]] inline localize::PathSmootherConfig path_for_matched_scans() noexcept {
  localize::PathSmootherConfig config;
  config.yaw_sigma_per_sqrt_m = 0.004;
  return config;
}

struct MapperConfig {
  localize::LocalizerConfig localizer = mapper_localizer_config();
  PoseSource pose_source = PoseSource::kLocalizer;
  // With the localizer's poses: each level laser's scan matched against the grid of what the
  // scans before it hit, and every scan drawn with the corrected pose (localize::ScanMatcher,
  // docs/localize.md).
  localize::ScanMatchConfig scan_matching;
  // The whole run's path at once (localize::PathSmoother, docs/localize.md): the level
  // lasers' matched poses as its odometry and every fix the localizer took. At the end of the
  // run every final plane is moved by how far the solved path lies from the poses it was
  // drawn with while the robot was near it and saw it, and the buildings are fitted again.
  // Needs scan matching (the localizer's live poses) and no free-space grid (it is not
  // moved); on by default wherever those hold (benning's buildings 0.684 -> 0.766 mean IoU
  // over seeds 1-10, docs/localize.md).
  RigidPath rigid_path = RigidPath::kWhereScansAreMatched;
  localize::PathSmootherConfig path = path_for_matched_scans();
  // With the rigid path, the stream shows each plane where the latest solve puts it (every
  // 10 s of scan time; docs/localize.md, The rigid map as it goes), and the buildings are
  // fitted to the planes so: a plane is reported again when that moves it more than
  // rigid_view_change_m at any vertex. Off: as drawn until the end's move.
  bool rigid_view = true;
  double rigid_view_change_m = 0.05;
  std::size_t max_external_poses = 1024;  // kExternal: the newest poses kept to interpolate

  std::array<map::SensorMount, kMaxLasers> laser_mounts{};
  std::size_t laser_count = 0;
  map::ScanProjectorConfig projection;
  map::VoxelWindowConfig window;
  // The detector runs over the window: its sample capacity is the window's (init() sets it),
  // and a window holds fewer planes and section planes than a whole city's cloud.
  planes::PlanesConfig planes = window_planes_config();
  map::PlaneRegistryConfig registry;

  double extract_every_s = 1.0;  // of scan time, between plane extractions
  // Between two extractions with no tile leaving the window, the detector keeps its samples
  // and shapes and takes only the samples that gained points (a few per cent of the window a
  // second); shapes are estimated again only around them. The planes are the same either way
  // (MapperSim.TheSameRunGivesTheSameStreamWithOrWithoutKeptShapes); false detects every
  // window afresh.
  bool incremental_extraction = true;
  // A detected plane within this angle of a laser's scan plane that passes this close to
  // where the laser has been, while moving within that plane, is that scan plane
  // (planes::PlaneExclusion): not reported. The positions are kept every
  // scan_plane_spacing_m of its path (the last kScanPlanePath). A real surface there (a car's
  // bonnet at the height of a level laser) is lost with it.
  double scan_plane_angle_deg = 10.0;
  double scan_plane_distance_m = 0.5;
  double scan_plane_spacing_m = 0.5;
  // Buildings from the map's walls (seed, section IV), fitted again after every extraction:
  // the estimate improves as data arrives. Capacities for one window's city block.
  bool fit_buildings = true;
  buildings::BuildingsConfig buildings = mapper_buildings_config();
  // Where the level lasers saw through (map::FreeSpaceGrid), for tracing the blocks the robot
  // drove around (buildings::BlockTracer). Off by default (tiles_across 0): it costs a grid
  // walk per beam, and a robot that maps a street rather than drives round blocks gains
  // nothing from it.
  map::FreeSpaceConfig free_space;
  double reorder_window_s = 0.25;  // a message this much older than the newest is released
  std::size_t reorder_capacity = 512;
  std::size_t scan_queue_capacity = 128;  // scans wait for the reorder window and the poses
  // The most beams a scan of these lasers has (a queued scan keeps room for this many), and
  // all lasers' scans per second together: with a pose lag (localizer.map_pose_lag_s) the
  // queue grows to hold the lag's scans (scan_queue_slots()). 0: not known, no growth.
  std::size_t max_beams = msg::kMaxLaserBeams;
  double scans_per_s = 0.0;
};

// The scans the queue holds: scan_queue_capacity, or the lag, the reorder window and a second
// more of scans at scans_per_s when that is more.
[[nodiscard]] std::size_t scan_queue_slots(const MapperConfig& config) noexcept;

// Empty when usable, otherwise what is wrong.
[[nodiscard]] std::string validate(const MapperConfig& config);

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
  std::uint64_t rigid_path_fixes_dropped = 0;    // fixes that waited for a matched scan too long
  std::uint64_t rigid_path_ties_other_side = 0;  // a wall paired with one seen from behind
  std::uint64_t planes_moved = 0;                // final planes the rigid path moved
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
  // For snapshots (issue 9): every plane as it would be if the run ended now
  // (PlaneRegistry::save); the map is left as it was.
  [[nodiscard]] std::size_t save_planes(std::span<map::SavedPlane> out) noexcept {
    return registry_.save(out);
  }
  // Resuming from a snapshot, before the first message: the saved planes become the map's
  // final planes (reopened under their ids when seen again), and the buildings are fitted.
  void restore_planes(std::span<const map::SavedPlane> planes) noexcept;
  [[nodiscard]] const planes::PlaneDetector& detector() const noexcept { return detector_; }
  [[nodiscard]] const localize::Localizer& localizer() const noexcept { return localizer_; }
  [[nodiscard]] const localize::ScanMatcher& scan_matcher() const noexcept { return matcher_; }
  [[nodiscard]] const localize::PathSmoother& rigid_path() const noexcept { return path_; }
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
  enum class Kind : std::uint8_t { kBase, kFix, kPose };
  struct Pending {
    TimestampNs stamp_ns = 0;
    Kind kind = Kind::kBase;
    msg::OdometrySample odometry;
    msg::ImuSample imu;
    localize::GpsObservation fix;
    double up_m = 0.0;
    localize::Pose3 pose;
  };
  struct QueuedScan {
    std::size_t laser = 0;
    CompactScanHeader scan;  // its beams: scan_codes_, max_beams per slot
  };

  void enqueue(const Pending& message) noexcept;
  void release_due() noexcept;
  void apply(const Pending& message) noexcept;
  // The newest time the poses cover.
  [[nodiscard]] bool pose_horizon(TimestampNs& out) const noexcept;
  [[nodiscard]] bool pose_at(TimestampNs stamp_ns, localize::Pose3& out) const noexcept;
  // The oldest queued scan whose last beam the poses cover (all of them when ending); or -1.
  // oldest_waiting_ns: the oldest stamp among the queued scans the poses do not cover yet.
  [[nodiscard]] std::ptrdiff_t next_ready_scan(TimestampNs& oldest_waiting_ns) const noexcept;
  void project(const QueuedScan& queued, std::span<const std::uint16_t> codes) noexcept;
  [[nodiscard]] std::span<std::uint16_t> codes_of(std::uint32_t slot) const noexcept {
    return scan_codes_.subspan(slot * config_.max_beams, config_.max_beams);
  }
  // Before the first pose: the queued scans that start before it (all that the released
  // messages rule out) are counted without a pose and leave the queue.
  void drop_scans_before_first_pose() noexcept;
  // Takes the scan at `position` in the queue out (its slot becomes free).
  void remove_scan(std::size_t position) noexcept;
  // The window's samples into the detector: all of them, or those that changed.
  void give_detector_the_window() noexcept;
  void extract(TimestampNs stamp_ns) noexcept;
  void refit_buildings() noexcept;
  void fit_buildings_to_map() noexcept;
  // With scan matching: a level laser's scan corrects the pose (matcher_), and every scan's
  // points and poses are moved by the correction.
  void correct_by_scan_matching(std::size_t laser, localize::Pose3& first, localize::Pose3& last,
                                std::span<Eigen::Vector3f> points_m) noexcept;
  // The rigid path: a matched scan's pose in the matcher's frame with the fixes before it, and
  // at the end the final planes moved by the solved path.
  void feed_rigid_path(TimestampNs stamp_ns, const localize::Pose2& drawn,
                       const localize::Pose2& odometry) noexcept;
  void move_planes_by_rigid_path() noexcept;
  // Where the solved path puts a plane drawn with the poses of its time, seen at the times
  // `seen` holds (the identity before the path has fixes and a solve, with no keyframe near,
  // or for a plane from a snapshot, which has no spans).
  [[nodiscard]] map::PlaneMove rigid_path_move(const msg::PlanePatch& plane,
                                               const map::SeenSpans& seen) const noexcept;
  // The first keyframe stamped at or after `stamp_ns` (keyframe_count() when none is).
  [[nodiscard]] std::size_t first_keyframe_from(TimestampNs stamp_ns) const noexcept;
  // The rigid path's ties between passes: each wall of a detection that continues a final
  // wall of an earlier pass (the same wall drawn with that pass's poses) ties the keyframes
  // that drew the two.
  void tie_walls_to_earlier_passes(std::span<const msg::PlanePatch> detected,
                                   TimestampNs stamp_ns) noexcept;
  // The keyframe nearest `point_m` (x, y) among those from `from_ns` to `to_ns` that
  // `seen` covers (every one when null): its stamp and drawn position; false when there is
  // none within reach.
  bool keyframe_that_drew(const Eigen::Vector2d& point_m, TimestampNs from_ns, TimestampNs to_ns,
                          const map::SeenSpans* seen, TimestampNs& stamp_ns,
                          Eigen::Vector2d& from_m) const noexcept;
  // A level laser's beams carve the free-space grid, from its position at `pose`.
  void carve_free_space(std::size_t laser, const localize::Pose3& pose,
                        std::span<const Eigen::Vector3f> points_m) noexcept;

  // A tile leaving the window: the registry freezes what it held of its planes, and its
  // samples leave the detector's kept grid, which then goes on instead of starting over.
  class TileLeaving final : public map::VoxelWindow::EvictionSink {
   public:
    explicit TileLeaving(Mapper& mapper) noexcept : mapper_(&mapper) {}
    void on_evicted(const map::VoxelWindow::EvictedTile& tile) noexcept override;

   private:
    Mapper* mapper_;
  };
  // The rigid path as the registry's view of its planes (rigid_path_move).
  class RigidPathView final : public map::PlaneView {
   public:
    explicit RigidPathView(const Mapper& mapper) noexcept : mapper_(&mapper) {}
    [[nodiscard]] map::PlaneMove move_of(const msg::PlanePatch& plane,
                                         const map::SeenSpans& seen) const noexcept override {
      return mapper_->rigid_path_move(plane, seen);
    }

   private:
    const Mapper* mapper_;
  };

  MapperConfig config_;
  TileLeaving tile_leaving_{*this};
  RigidPathView rigid_path_view_{*this};
  localize::Localizer localizer_;
  localize::ScanMatcher matcher_;
  std::array<bool, kMaxLasers> matches_scans_{};  // level lasers, with the localizer's poses
  // The last matched scans' corrections, by stamp, for the other lasers' scans.
  struct StampedCorrection {
    TimestampNs stamp_ns = 0;
    localize::PlanarCorrection correction;
  };
  std::array<StampedCorrection, 16> corrections_{};
  std::size_t correction_next_ = 0;
  std::size_t correction_count_ = 0;
  TimestampNs last_matched_scan_ns_ = 0;
  bool matching_paused_ = false;  // carrier-phase fixes hold the poses; the grid is stale
  localize::PathSmoother path_;
  bool path_on_ = false;
  // Fixes wait here for the first matched scan at or after them (scans are drawn after the
  // poses cover them, fixes go to the localizer as they are released).
  std::array<localize::GpsObservation, 64> path_fixes_{};
  std::size_t path_fix_first_ = 0;
  std::size_t path_fix_count_ = 0;
  TimestampNs next_path_solve_ns_ = 0;
  // The path was solved since the last extraction; the view is refreshed in the update after
  // the next one (an extraction's step always returns, so where it lands does not depend on
  // how the messages were batched between steps).
  bool path_solved_ = false;
  bool view_due_ = false;
  // The matcher's frame starts over when the filter's poses snap; the path's odometry goes on
  // across: the new frame is laid where the localizer's dead reckoning carries the last
  // matched pose (path_rebase_ takes matched poses into the path's one frame).
  localize::PlanarCorrection path_rebase_;
  bool path_rebase_due_ = false;
  bool path_have_last_ = false;
  localize::Pose2 path_last_pose_;
  localize::Pose2 path_last_odometry_;
  std::array<map::ScanProjector, kMaxLasers> projectors_{
      map::ScanProjector({}, {}), map::ScanProjector({}, {}), map::ScanProjector({}, {}),
      map::ScanProjector({}, {})};
  map::VoxelWindow window_;
  planes::PlaneDetector detector_;
  map::PlaneRegistry registry_;
  buildings::BuildingFitter building_fitter_;
  map::FreeSpaceGrid free_space_;
  std::array<bool, kMaxLasers> carves_free_space_{};

  std::span<Pending> pending_;  // ordered by time, oldest first
  std::size_t pending_count_ = 0;
  TimestampNs newest_in_ns_ = 0;
  TimestampNs released_ns_ = 0;  // everything up to here went to the localizer
  bool released_any_ = false;
  TimestampNs released_base_ns_ = 0;  // the last base sample that did
  bool released_base_any_ = false;

  std::span<localize::Pose3> poses_;  // kExternal: a ring, oldest at pose_first_
  std::size_t pose_first_ = 0;
  std::size_t pose_count_ = 0;

  // Waiting scans stay in their slot (a scan is kilobytes): the queue is the list of their
  // slots in arrival order, and the slots not in it are free.
  std::span<QueuedScan> scans_;
  std::span<std::uint32_t> scan_slots_;  // [0, scan_count_): waiting, in arrival order
  std::span<std::uint16_t> scan_codes_;
  msg::LaserScan* expanded_ = nullptr;  // the scan being projected, in full
  std::size_t scan_count_ = 0;
  std::span<Eigen::Vector3f> points_;
  // Each laser's scan plane at its latest scan, and where it has been (a ring, any order).
  struct LaserPath {
    std::array<Eigen::Vector3d, kScanPlanePath> origins_m{};
    std::size_t count = 0;
    std::size_t next = 0;
    Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
    Eigen::Vector3d last_origin_m = Eigen::Vector3d::Zero();
  };
  void record_laser_position(std::size_t laser, const localize::Pose3& pose) noexcept;
  std::array<LaserPath, kMaxLasers> laser_paths_{};
  double cos_scan_plane_angle_ = 1.0;
  double sin_scan_plane_angle_ = 0.0;
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
  TimestampNs update_stamp_ns_ = 0;
  std::span<const msg::PlaneChange> changes_;
  PointSink* point_sink_ = nullptr;
  MapperCounters counters_;
};

}  // namespace blockmap::pipeline
