// Buildings from walls (seed, section IV): vertical planes become footprint segments, segments
// that meet at corners become a building, and each building is fitted to a rectangle, an L or
// a T, in that order of preference, with virtual walls where the robot saw nothing.
//
//   walls_to_segments  -> group_segments -> for each group: building_frame ->
//   propose models (rect, L x 4 corners, T x 4 sides) -> score each -> best -> walls
//
// Everything comes from an arena at init; fit() allocates nothing.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "blockmap/buildings/block_tracer.hpp"
#include "blockmap/buildings/building.hpp"
#include "blockmap/buildings/buildings_config.hpp"
#include "blockmap/core/arena.hpp"
#include "blockmap/msg/plane_patch.hpp"

namespace blockmap::buildings {

// A wall plane seen from above: the horizontal extent of its polygon on its line.
struct WallSegment {
  Eigen::Vector2d p0_m = Eigen::Vector2d::Zero();
  Eigen::Vector2d p1_m = Eigen::Vector2d::Zero();
  double z0_m = 0.0;
  double z1_m = 0.0;
  std::uint32_t plane_id = 0;
  bool is_tall = true;   // labelled a wall by the detector (else a low vertical plane)
  double support = 0.0;  // the plane's points
};

// The segment of a vertical plane (within 10 degrees), or false when the plane is not vertical
// or has no extent.
[[nodiscard]] bool wall_segment_of(const msg::PlanePatch& plane, WallSegment& segment) noexcept;

class BuildingFitter {
 public:
  struct Counters {
    std::uint64_t fits = 0;
    std::uint64_t walls_used = 0;
    std::uint64_t walls_dropped_full = 0;      // more wall segments than max_walls
    std::uint64_t buildings_dropped_full = 0;  // more groups than max_buildings
    std::uint64_t buildings_seen_through = 0;  // footprints mostly free space: unknown
    std::uint64_t roofs_dropped_full = 0;      // more roof planes than max_walls
  };

  // free_space_cells: room to trace blocks in free-space rasters of that many cells (0: none).
  void init(Arena& arena, const BuildingsConfig& config, std::size_t free_space_cells = 0);

  // The buildings of these planes (walls make footprints, roofs give heights). The result
  // stays valid until the next fit() or begin(). A building keeps its id from one fit to the
  // next (the streaming mapper refits after every extraction, and a consumer of its updates
  // follows buildings by id): it takes the id of the last fit's building with which it shares
  // the most observed wall planes (the plane registry's ids, stable across updates), else of
  // the one its extent overlaps most (half of the smaller one at least); a building matching
  // none gets a new id. Ids are never reused. A building missing from a fit (its walls did not
  // make a corner this time) is remembered for kRememberAbsentFits fits, so that it takes its
  // id back when it returns. The first fit numbers its buildings 1, 2, ...
  std::span<const Building> fit(std::span<const msg::PlanePatch> planes) noexcept;
  // The same, one plane at a time (planes kept apart, as a plane registry keeps its live and
  // final planes): begin(), add() each, finish().
  void begin() noexcept;
  void add(const msg::PlanePatch& plane) noexcept;
  std::span<const Building> finish() noexcept;
  // Where the robot's level laser saw through, for the next finish() (after begin()): blocks
  // traced in it (BlockTracer) replace the buildings fitted inside them, and a building whose
  // footprint is mostly ground that beams crossed keeps its seen walls only ("unknown"). The raster
  // must stay valid until finish() returns.
  void set_free_space(const map::FreeSpaceRaster& raster) noexcept {
    free_space_ = raster;
    has_free_space_ = true;
  }
  // The buildings of the last finish().
  [[nodiscard]] std::span<const Building> buildings() const noexcept {
    return buildings_.first(building_count_);
  }

  [[nodiscard]] const Counters& counters() const noexcept { return counters_; }
  [[nodiscard]] std::size_t memory_bytes() const noexcept;
  [[nodiscard]] static std::size_t arena_bytes(const BuildingsConfig& config,
                                               std::size_t free_space_cells = 0) noexcept;
  [[nodiscard]] static std::size_t past_set_bytes(const BuildingsConfig& config) noexcept;

  // One footprint model in the building's own frame (u along its main axis, v across): a
  // rectilinear polygon, counter-clockwise.
  struct Model {
    BuildingShape shape = BuildingShape::kRect;
    std::array<Eigen::Vector2d, kMaxFootprintVertices> corners{};
    std::uint8_t size = 0;
  };

  // A wall segment in its building's frame (u, v), snapped to the nearer axis.
  struct Piece {
    Eigen::Vector2d a = Eigen::Vector2d::Zero();
    Eigen::Vector2d b = Eigen::Vector2d::Zero();
    int axis = 0;        // 0: runs along u (its level is a v); 1: runs along v
    double level = 0.0;  // the across coordinate of its midpoint
    double lo = 0.0;     // its interval along its axis
    double hi = 0.0;
    std::uint32_t segment = 0;
    // Whether its ends tell where a notch is, and an edge in line with it was in view: a wall,
    // or a low trace seen densely (BuildingsConfig::min_low_wall_support_per_m). A sparse low
    // trace was seen from afar or through gaps (a hedge), and stops where the view stopped.
    bool trusted_ends = true;
  };
  // How well a model explains the pieces (the lowest cost wins).
  struct ModelScore {
    double unexplained_m = 0.0;  // observed length farther than fit_tolerance_m from the model
    double missed_m = 0.0;       // model edge length in line with an observed wall, not seen
    double distance_m = 0.0;     // length-weighted mean distance of what is explained
    double cost = 0.0;
  };
  // The bounding box of the pieces: lo and hi along u (index 0) and v (index 1).
  struct Box {
    std::array<double, 2> lo{};
    std::array<double, 2> hi{};
  };

 private:
  std::uint32_t find_root(std::uint32_t i) noexcept;
  void group_segments() noexcept;
  [[nodiscard]] bool same_building(const WallSegment& a, const WallSegment& b) const noexcept;
  // Fits the group of segments listed in group_members_ into `building`; false when the group
  // is too small to be a building.
  bool fit_group(std::span<const std::uint32_t> members, Building& building) noexcept;
  void to_pieces(std::span<const std::uint32_t> members, double axis_rad) noexcept;
  void merge_parallel_pieces() noexcept;
  // Cuts the pieces that run on past the outermost wall spanning the building across them:
  // what lies beyond a building's full front is not the building (trim_past_spanning_walls).
  void trim_past_spanning_walls(const Box& box) noexcept;
  // Of the pieces along `across`, cuts those that run on a little past low_m or high_m, and
  // drops low ones wholly beyond (parallel ones beyond, too).
  void cut_pieces_beyond(int across, double low_m, double high_m) noexcept;
  [[nodiscard]] Box bounding_box() const noexcept;
  void propose_models(const Box& box) noexcept;
  // An L: the box with the notch at corner (side_u, side_v) (0: lo, 1: hi).
  void propose_l(const Box& box, int side_u, int side_v) noexcept;
  // A T whose bar runs along `bar_axis` and whose stem points to `stem_side` of the other axis.
  void propose_t(const Box& box, int bar_axis, int stem_side) noexcept;
  void add_model(BuildingShape shape, const Box& box,
                 const std::array<const Eigen::Vector2d*, 4>& inner_corners) noexcept;
  [[nodiscard]] ModelScore score(const Model& model) const noexcept;
  // The first of the proposed models with the lowest cost (rect before L before T).
  [[nodiscard]] const Model& best_model(ModelScore& best_score) const noexcept;
  // No model explains the walls: the building is its observed walls as they are.
  void add_observed_walls(Building& building) const noexcept;
  void emit_walls(const Model& model, double axis_rad, Building& building) const noexcept;
  static void set_confidence(Building& building) noexcept;
  // The length-weighted direction of the walls modulo 90 degrees.
  [[nodiscard]] double dominant_axis(std::span<const std::uint32_t> members) const noexcept;
  // Blocks traced in the free space, each replacing the buildings inside it.
  void add_traced_blocks() noexcept;
  static void keep_observed_walls_only(Building& building) noexcept;
  // The share of the building's footprint that the free space says beams crossed.
  [[nodiscard]] double free_share(const Building& building) const noexcept;
  bool fit_block(const BlockTracer::Block& block, std::span<const std::uint32_t> members,
                 Building& building) noexcept;
  void set_height(Building& building) const noexcept;
  // Identity across fits (see fit()).
  struct Extent {
    double x0 = 0.0;
    double y0 = 0.0;
    double x1 = 0.0;
    double y1 = 0.0;
  };
  struct PastPlane {
    std::uint32_t plane_id = 0;
    std::uint32_t past = 0;  // index into past_ids_ and past_extents_
  };
  // A minute of the mapper's refits (one a second).
  static constexpr std::uint16_t kRememberAbsentFits = 60;
  // The remembered buildings: two sets of arrays, the last fit's and the one being written.
  struct PastSet {
    std::span<std::uint32_t> ids;
    std::span<Extent> extents;
    std::span<std::uint16_t> absent_fits;  // fits since it was last seen
    std::span<PastPlane> planes;           // observed wall planes, sorted by plane id
    std::size_t count = 0;
    std::size_t plane_count = 0;
  };
  void init_past_set(Arena& arena, PastSet& set) const;
  [[nodiscard]] static Extent extent_of(const Building& building) noexcept;
  [[nodiscard]] std::size_t past_match(const Building& building) noexcept;
  void assign_ids() noexcept;
  void remember_buildings() noexcept;

  BuildingsConfig config_;
  Counters counters_;
  std::span<WallSegment> segments_;
  std::size_t segment_count_ = 0;
  // Roof planes, for the buildings' heights.
  struct Roof {
    Eigen::Vector2d centroid_m = Eigen::Vector2d::Zero();
    double z_m = 0.0;
    double support = 0.0;
  };
  std::span<Roof> roofs_;
  std::size_t roof_count_ = 0;
  std::span<std::uint32_t> parent_;
  std::span<std::uint32_t> order_;  // segment indices, grouped
  std::span<Piece> pieces_;
  std::size_t piece_count_ = 0;
  std::array<Model, 9> models_{};  // rect, 4 L, 4 T
  std::size_t model_count_ = 0;
  std::span<Building> buildings_;
  std::size_t building_count_ = 0;
  // The buildings of the last fits (twice max_buildings: this fit's and those absent from it).
  std::array<PastSet, 2> past_sets_{};
  std::size_t past_ = 0;  // past_sets_[past_] is the last fit's
  std::span<std::uint8_t> past_taken_;
  std::span<std::uint32_t> past_votes_;
  std::span<std::uint32_t> past_remap_;
  std::uint32_t next_id_ = 1;
  // Traced blocks (set_free_space()).
  BlockTracer tracer_;
  map::FreeSpaceRaster free_space_;
  bool has_free_space_ = false;
  std::span<std::uint32_t> block_members_;
  std::span<SideWall> side_walls_;
};

}  // namespace blockmap::buildings
