// Loop closing for the rigid path (docs/localize.md, Loop closing).
//
// Why. The scan matcher's grid is a window of about 100 m that scrolls with the robot: a
// street seen again minutes later is new ground to it, and its path has drifted by then (a
// few tenths of a degree, a few decimetres a hundred metres). Only the receiver's fixes and
// the walls' ties then hold the two passes to each other. A loop closure matches what the
// level lasers saw on this pass against what they saw on the earlier one, and says how the
// two poses lie to each other as tightly as the surfaces say (Cartographer's loop closing:
// Hess et al., ICRA 2016).
//
// What it keeps: submaps. Over every submap_length_m of the path, the level scans' matched
// points (a scan every scan_spacing_m), as the cells they hit in the frame of the submap's
// first pose, neighbouring returns joined; at most max_cells_per_submap of them (thinned
// evenly). At most max_submaps: when full, every other one goes (the run at half the
// resolution), so a route of any length fits.
//
// What it does when a submap is finished, against each earlier one whose cells' centroid
// the path as last solved puts within candidate_distance_m of its own (what the two saw, not
// where they were: a laser that looks ahead sees a street's other half on the way back), at
// least min_travel_apart_m of path before it (nearer ones are in the scan matcher's grid
// still):
//  1. the earlier submap's cells into a scratch grid, with coarser levels that take the
//     largest of the cells under them;
//  2. the finished submap's cells searched exhaustively on the coarse level, over
//     search_radius_m and search_yaw_deg about where the solved path puts them (the
//     receiver's slow error, both passes; without fixes, the odometry's drift over the path
//     between the two, growing with it);
//  3. Gauss-Newton from the best of them, coarse to fine;
//  4. verification: the share of its cells that land on the earlier ones (min_score), and
//     the match still inside the window;
//  5. the closure: the relative pose, with the information its surfaces give (the match's
//     Hessian: along a bare street little) and a floor under its sigmas.
//
// Fixed size: the submaps, the scratch grid and the query are taken from the arena at init;
// add_scan() and find_closures() allocate nothing.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

#include <Eigen/Core>

#include "blockmap/core/arena.hpp"
#include "blockmap/localize/particle_filter.hpp"
#include "blockmap/localize/path_smoother.hpp"

namespace blockmap::localize {

struct LoopClosureConfig {
  bool enabled = true;
  double cell_m = 0.1;
  double submap_length_m = 10.0;
  // At the end of the run the submap being filled is matched too when the robot drove this
  // far into it (a loop that ends where it began overlaps its start by its last metres).
  double last_submap_min_m = 2.5;
  double scan_spacing_m = 0.5;
  double max_range_m = 30.0;  // returns farther from the robot are not kept
  // Neighbouring returns closer than this mark the cells between them (one surface).
  double join_gap_m = 1.0;
  std::size_t max_submaps = 128;
  std::size_t max_cells_per_submap = 2048;
  std::size_t max_query_points = 512;
  std::uint32_t grid_across = 768;  // the scratch grid's side in cells (76.8 m at 0.1 m)
  std::uint32_t levels = 4;         // 0.1 to 0.8 m: the search on the finest that spans its window
  double candidate_distance_m = 15.0;
  double min_travel_apart_m = 100.0;
  std::size_t max_candidates = 4;  // the nearest earlier submaps tried per finished one
  double search_radius_m = 2.5;
  double search_yaw_deg = 3.0;
  // A path without fixes drifts with the distance driven between the two passes: the window
  // grows by these per metre of path between them, up to the max_ ones.
  double search_radius_per_m = 0.01;
  double search_yaw_deg_per_m = 0.01;
  double max_search_radius_m = 8.0;
  double max_search_yaw_deg = 8.0;
  double min_score = 0.6;
  // Where the window above finds no match, a wider one (0: none) on a coarser level, whose
  // match must lie on the earlier submap's surfaces more: with fixes, the newest stretch of
  // the path can be turned by a few degrees where the gyroscope alone carried it.
  double wide_search_radius_m = 4.0;
  double wide_search_yaw_deg = 5.0;
  double wide_min_score = 0.8;
  // A cell's offset across its surface, as one of many neighbours (they are not independent
  // measurements), and the least sigmas a closure has.
  double point_sigma_m = 0.5;
  double floor_sigma_m = 0.05;
  double floor_sigma_deg = 0.25;
};

// The most closures find_closures() gives at once.
inline constexpr std::size_t kMaxClosureCandidates = 4;

// Empty when usable, otherwise what is wrong.
[[nodiscard]] std::string validate(const LoopClosureConfig& config);

struct LoopClosureCounters {
  std::uint64_t submaps = 0;
  std::uint64_t thinnings = 0;      // the submaps filled and every other one went
  std::uint64_t searches = 0;       // earlier submaps a finished one was matched against
  std::uint64_t closures = 0;       // matches verified
  std::uint64_t low_score = 0;      // too few cells on the earlier submap's
  std::uint64_t off_window = 0;     // the match left the search window
  std::uint64_t wide_closures = 0;  // of the closures, found by the wider search
};

class LoopCloser {
 public:
  void init(Arena& arena, const LoopClosureConfig& config);
  [[nodiscard]] static std::size_t arena_bytes(const LoopClosureConfig& config) noexcept;
  [[nodiscard]] std::size_t memory_bytes() const noexcept;
  [[nodiscard]] bool enabled() const noexcept { return config_.enabled; }

  // A matched level scan: its pose in the path's odometry frame (what PathSmoother::add was
  // given) and the points its match used, in the robot frame. Returns whether a submap was
  // finished (find_closures() is due).
  bool add_scan(const Pose2& pose, std::span<const Eigen::Vector2d> robot_points_m) noexcept;
  // At the end of the run: the submap being filled is finished as it is, when the robot drove
  // at least last_submap_min_m into it. Returns whether it was (find_closures() is due).
  bool finish_last_submap() noexcept;

  // After add_scan() finished a submap: it is matched against the earlier ones near it by
  // `path`'s solution, the verified closures into `found` (at most max_candidates); returns
  // how many.
  std::size_t find_closures(const PathSmoother& path,
                            std::span<LoopClosure, kMaxClosureCandidates> found) noexcept;

  [[nodiscard]] std::size_t submap_count() const noexcept { return submap_count_; }
  [[nodiscard]] const LoopClosureCounters& counters() const noexcept { return counters_; }

 private:
  struct Cell {
    std::int16_t x = 0;
    std::int16_t y = 0;
  };
  struct Submap {
    Pose2 origin;         // the first scan's pose, in the path's odometry frame
    double from_m = 0.0;  // the path's length at its first scan and at its last
    double to_m = 0.0;
    Eigen::Vector2d seen_m = Eigen::Vector2d::Zero();  // its cells' centroid, in its frame
    std::uint32_t slot = 0;  // its cells: cells_[slot * max_cells_per_submap, + count)
    std::uint32_t count = 0;
  };
  struct Level {
    std::span<std::uint8_t> cells;  // 1: a surface, row-major, across x across
    std::int64_t across = 0;
    double cell_m = 0.0;
  };
  struct Match {
    Eigen::Vector3d pose = Eigen::Vector3d::Zero();  // x, y, yaw of the query in the target
    Eigen::Matrix3d hessian = Eigen::Matrix3d::Zero();
    double score = 0.0;
  };

  void add_cells(const Pose2& pose, std::span<const Eigen::Vector2d> robot_points_m) noexcept;
  void add_cell(const Eigen::Vector2d& local_m) noexcept;
  void compact_staging() noexcept;
  // The open submap, as it is, into the kept ones; none is open after it.
  void finish_submap() noexcept;
  [[nodiscard]] std::uint32_t free_slot() noexcept;
  void thin_submaps() noexcept;
  [[nodiscard]] std::span<const Cell> cells_of(const Submap& submap) const noexcept;

  void rasterize(const Submap& target) noexcept;
  void load_query(const Submap& query) noexcept;
  // The search window about a guess: its reach (m) and turn (rad).
  struct Window {
    double radius_m = 0.0;
    double yaw_rad = 0.0;
    std::size_t level = 0;  // the level searched, and refined from
    double min_score = 0.0;
  };
  [[nodiscard]] Window window_between(const Submap& target, const Submap& query,
                                      bool placed_by_fixes) const noexcept;
  // The wider window tried where `window` found nothing; its radius 0 when it is no wider.
  [[nodiscard]] Window widened(const Window& window) const noexcept;
  [[nodiscard]] std::size_t level_spanning(double radius_m) const noexcept;
  [[nodiscard]] Eigen::Vector3d coarse_search(const Eigen::Vector3d& guess,
                                              const Window& window) const noexcept;
  void refine(const Level& level, const Eigen::Vector3d& start, Match& match) const noexcept;
  [[nodiscard]] double score(const Eigen::Vector3d& pose) const noexcept;
  [[nodiscard]] double value(const Level& level, std::int64_t x, std::int64_t y) const noexcept;
  [[nodiscard]] bool match(const Submap& target, const Submap& query, const Eigen::Vector3d& guess,
                           const Window& window, LoopClosure& closure) noexcept;

  LoopClosureConfig config_;
  std::span<Cell> cells_;
  std::span<Submap> submaps_;
  std::span<std::uint32_t> free_slots_;
  std::span<Cell> staging_;
  std::span<Level> levels_;
  std::span<Eigen::Vector2d> query_m_;
  std::size_t submap_count_ = 0;
  std::size_t free_count_ = 0;
  std::size_t staging_count_ = 0;
  std::size_t query_count_ = 0;
  bool open_ = false;  // a submap is being gathered
  Pose2 open_origin_;
  double open_from_m_ = 0.0;  // the path's length at its first scan
  bool have_last_ = false;
  Pose2 last_pose_;
  Pose2 last_added_;
  double travel_m_ = 0.0;
  LoopClosureCounters counters_;
};

}  // namespace blockmap::localize
