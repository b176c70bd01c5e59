// A prior 2D map for Monte Carlo localization (the seed's section II, its USC run): the walls
// of a map made before (building footprints from an earlier run, or from a GIS file) as a
// likelihood field: each cell holds the distance to the nearest wall (Thrun, Burgard and Fox,
// Probabilistic Robotics, 6.4), and whether it lies inside a footprint. A laser does not see
// into a building: a return inside one says the pose is wrong, where a return in the open
// may be a hedge or a parked car the map does not hold. Without that, a row of bushes two
// metres in front of a wall matches the wall as well as the wall does.
//
// Fixed size: the grid's capacity (max_cells) is taken from the arena at init; build() fits
// the walls' extent into it at start-up, and distance_m() allocates nothing.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

#include <Eigen/Core>

#include "blockmap/core/arena.hpp"

namespace blockmap::localize {

struct PriorMapConfig {
  bool enabled = false;
  double cell_m = 0.2;
  std::size_t max_cells = 1U << 20U;  // 1 MiB: 200 x 200 m at 0.2 m
  double margin_m = 5.0;              // beyond the walls' extent the grid reaches this far
  // The Monte Carlo localizer (MapLocalizer).
  std::size_t particles = 256;
  std::size_t max_points = 64;  // of a scan, evenly spread, weigh the particles
  // A return's distance to the nearest wall: a Gaussian of this sigma, plus this share of
  // returns from what the map does not hold (parked cars, trees, a building not in it), and
  // a far smaller share inside a footprint (where only the map's own errors put returns).
  double hit_sigma_m = 0.2;
  double unmapped_share = 0.2;
  double inside_share = 0.01;
  // Neighbouring returns of one scan are not independent: a scan weighs as this many.
  double independent_points = 8.0;
  // A scan weighs the particles after this much motion since the last (distance or turn).
  double update_spacing_m = 0.5;
  double update_turn_deg = 5.0;
  // The motion's noise per update: a floor and a share of the distance, and the turn's. The
  // matched path's motion is good to about a centimetre a metre; noise much beyond lets the
  // particles slide, a little each update, onto a hedge that stands in front of a wall.
  double motion_sigma_m = 0.005;
  double motion_sigma_per_m = 0.01;
  double turn_sigma_deg = 0.1;
  double turn_sigma_deg_per_m = 0.1;
  // Where the particles start: around the solved path's pose by these sigmas, once it has
  // fixes over start_after_m of motion (its heading known to about a degree: the receiver's
  // slow error across 100 m); or at once, for a robot that started at a known pose, by the
  // localizer's start sigmas.
  double start_after_m = 100.0;
  double start_sigma_m = 2.0;
  double start_yaw_sigma_deg = 3.0;
  // How far the map's frame may sit off the start pose's, for a robot started at a known
  // pose, and how slowly that offset changes along the route: an earlier run's receiver put
  // its walls where that run's path was, a metre or two off. The placings then share a slow
  // error of this sigma and time constant (PathSmoother::carry_map_offset), and the particles
  // start this much wider. 0: the map is in the start pose's frame (a survey).
  double frame_sigma_m = 1.5;
  double frame_time_s = 300.0;
  // The placing handed to the path, every place_spacing_m of motion: the estimate, with the
  // information the walls its returns land on give (none along a bare street), in the
  // directions they pin down to within max_placing_sigma_m. Given when the estimate's returns
  // land on the map's walls (min_hit_share within two hit sigmas) and the particles agree
  // within max_spread_m in those directions; its sigmas are the walls' and the particles'
  // spread together, at least min_sigma_m.
  double max_placing_sigma_m = 1.0;
  double max_spread_m = 0.3;
  double min_hit_share = 0.4;
  double place_spacing_m = 2.0;
  double min_sigma_m = 0.1;
  // A placing farther than this from where the path has the robot is refused: the
  // particles have slid onto something else (before the first placing, three start sigmas:
  // the path is the receiver's then). After restart_after such in a row, or lost_after
  // updates in a row whose returns missed the map's walls, they start again around the
  // path's pose.
  double placing_gate_m = 1.0;
  std::uint32_t restart_after = 5;
  std::uint32_t lost_after = 40;
  std::uint64_t seed = 1;
};

// Empty when usable, otherwise what is wrong.
[[nodiscard]] std::string validate(const PriorMapConfig& config);

// A wall of the prior map, seen from above: a segment in the local frame. `encloses`: an edge
// of a closed footprint (what the footprints' edges enclose, by the even-odd rule, is solid).
struct MapWall {
  Eigen::Vector2d from_m = Eigen::Vector2d::Zero();
  Eigen::Vector2d to_m = Eigen::Vector2d::Zero();
  bool encloses = false;
};

class PriorMap {
 public:
  // Distances are kept in steps of kStepM up to kMaxDistanceM (farther is as far), in a
  // cell's low 7 bits; its high bit says it is inside a footprint.
  static constexpr double kStepM = 0.04;
  static constexpr std::uint8_t kFarthest = 127;
  static constexpr std::uint8_t kInside = 128;
  static constexpr double kMaxDistanceM = kFarthest * kStepM;

  void init(Arena& arena, const PriorMapConfig& config);
  [[nodiscard]] static std::size_t arena_bytes(const PriorMapConfig& config) noexcept;
  [[nodiscard]] std::size_t memory_bytes() const noexcept { return cells_.size_bytes(); }

  // The grid over the walls' extent (plus the margin); empty when it worked, else why not
  // (no walls, a coordinate that is not finite, an extent over max_cells).
  [[nodiscard]] std::string build(std::span<const MapWall> walls);
  [[nodiscard]] bool built() const noexcept { return across_ > 0; }
  [[nodiscard]] std::size_t wall_count() const noexcept { return wall_count_; }

  // The distance from `point_m` to the nearest wall, interpolated between cell centres;
  // kMaxDistanceM off the grid.
  [[nodiscard]] double distance_m(const Eigen::Vector2d& point_m) const noexcept;
  // Whether `point_m` lies inside a footprint (its cell's centre does).
  [[nodiscard]] bool inside(const Eigen::Vector2d& point_m) const noexcept;
  // The nearest wall's normal n at `point_m` as n n' (its sign does not matter): from the
  // curvature of the squared distance, which is 2 n n' near a straight wall (and 2 I beyond
  // a wall's end: a point pinned in no one direction). The distance's own slope would not
  // do: it flips on the wall, where the returns are. For returns near walls (the steps of
  // the kept distances grow with it).
  [[nodiscard]] Eigen::Matrix2d normal_outer(const Eigen::Vector2d& point_m) const noexcept;

 private:
  void draw_wall(const MapWall& wall) noexcept;
  // The cells inside the enclosing walls, row by row (even-odd).
  void fill_inside(std::span<const MapWall> walls);

  PriorMapConfig config_;
  std::span<std::uint8_t> cells_;
  Eigen::Vector2d corner_m_ = Eigen::Vector2d::Zero();  // the grid's south-west corner
  std::int64_t across_ = 0;                             // cells east
  std::int64_t up_ = 0;                                 // cells north
  std::size_t wall_count_ = 0;
};

}  // namespace blockmap::localize
