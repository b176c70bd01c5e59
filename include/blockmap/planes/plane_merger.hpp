// Merging the planes of the sections into the planes of the map, in the manner of Tavares and
// Padilha (the paper's reference [4]) for line segments: planes that are close and of similar
// direction are merged, whether their extents overlap or not, each weighted by its size.
//
// Two stages keep it linear in the number of section planes:
//  1. section planes of neighbouring sections that lie on one plane are joined (union-find):
//     the pieces of one wall become one candidate;
//  2. candidates, largest first, are merged into the planes accepted so far when their
//     directions agree, they lie on the accepted plane, and their extents come within the
//     gap; repeated until nothing merges. Weighting by size is exact: moments add up.
#pragma once

#include <array>
#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "blockmap/core/arena.hpp"
#include "blockmap/msg/plane_patch.hpp"
#include "blockmap/planes/planes_config.hpp"
#include "blockmap/planes/point_moments.hpp"
#include "blockmap/planes/section_grid.hpp"

namespace blockmap::planes {

// A plane found in one section: its points' moments and the rectangle of its samples.
struct SectionPlane {
  CellKey section = 0;
  PointMoments moments;  // relative to the detector's origin
  Eigen::Vector3d normal_unit = Eigen::Vector3d::UnitZ();
  double d_m = 0.0;
  std::array<Eigen::Vector3f, 4> corners_m{};
};

// The section key of planes that a look after merging adds (CornerLook): after every real
// section's key, and no neighbour of one (a packed key never has its top bit set).
inline constexpr CellKey kLookSection = CellKey{1} << 63;
// The key of a wall the look found set back from another and parallel to it (a step, an L's
// notch). A merged plane most of whose points came from steps keeps their direction seen from
// above, its lean fitted: such points are a slab blurred by pose errors and sheared along the
// line of sight, whose least-squares yaw is off by degrees where the parallel to the wall is
// exact. The key comes after every look's and is no neighbour of one (the neighbour offsets
// are small).
inline constexpr CellKey kStepSection = kLookSection | (CellKey{1} << 62);

// A plane known not to be a surface: a laser's own scan plane. A laser sweeping foliage or
// clutter from a robot that drives within its scan plane lays its returns on that plane scan
// after scan, and they look flat, however far from the laser they are. A merged plane within
// acos(cos_max_angle) of `normal` that passes within distance_m of one of the laser's
// positions `origins_m` (where it has been lately) is that plane: it is dropped before the
// planes are labelled.
struct PlaneExclusion {
  std::span<const Eigen::Vector3d> origins_m;
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  double cos_max_angle = 1.0;
  double distance_m = 0.0;
};

class PlaneMerger {
 public:
  static constexpr std::size_t kMaxExclusions = 8;
  struct Counters {
    std::uint64_t section_planes_dropped_full = 0;
    std::uint64_t planes_dropped_full = 0;
    std::uint64_t stage2_merges = 0;
    std::uint64_t planes_excluded = 0;
  };

  void init(Arena& arena, const PlanesConfig& config);
  void clear() noexcept;

  // Section planes must come in section key order (the detector's order). False when full.
  bool add(const SectionPlane& plane) noexcept;

  // The exclusions of the next merge() (at most kMaxExclusions; kept until replaced).
  void set_exclusions(std::span<const PlaneExclusion> exclusions) noexcept;
  // Whether the plane n . p = d_m is one of the exclusions'.
  [[nodiscard]] bool excluded(const Eigen::Vector3d& normal_unit, double d_m) const noexcept;
  // fit_plane(), or fit_plane_or_wall() when walls may be lines (walls_from_lines).
  [[nodiscard]] PlaneFit fit_of(const PointMoments& moments) const noexcept;

  // Merges, labels and numbers the planes (largest first).
  std::span<const msg::PlanePatch> merge() noexcept;

  // The moments of the points behind each plane of the last merge(), in its order.
  [[nodiscard]] std::span<const PointMoments> plane_moments() const noexcept {
    return output_moments_.first(output_count_);
  }
  [[nodiscard]] std::size_t section_plane_count() const noexcept { return plane_count_; }
  // The section planes added since clear(), in their order.
  [[nodiscard]] std::span<const SectionPlane> section_planes() const noexcept {
    return planes_.first(plane_count_);
  }
  [[nodiscard]] const Counters& counters() const noexcept { return counters_; }
  [[nodiscard]] std::size_t memory_bytes() const noexcept;
  // Bytes init() takes from the arena for `config` (alignment padding included).
  [[nodiscard]] static std::size_t arena_bytes(const PlanesConfig& config) noexcept;

 private:
  struct Candidate {
    PointMoments moments;
    PlaneFit fit;
    std::array<Eigen::Vector3d, msg::kMaxPolygonVertices> polygon_m{};
    std::uint8_t polygon_size = 0;
    Eigen::Vector3d box_min_m = Eigen::Vector3d::Zero();
    Eigen::Vector3d box_max_m = Eigen::Vector3d::Zero();
    bool alive = true;
    // The points that came from steps (kStepSection), and their normals weighted by them.
    double step_weight = 0.0;
    Eigen::Vector3d step_normal_sum = Eigen::Vector3d::Zero();
  };
  // A candidate whose steps hold at least this share of its points keeps their direction.
  static constexpr double kStepShareMin = 0.5;
  static void add_step_normal(Candidate& candidate, const Eigen::Vector3d& normal_unit,
                              double weight) noexcept;
  [[nodiscard]] PlaneFit fit_candidate(const Candidate& candidate) const noexcept;

  std::uint32_t find_root(std::uint32_t i) noexcept;
  void join_neighbouring_section_planes() noexcept;
  void build_candidates() noexcept;
  // Polygon of `points` (3D, on or near the plane of `fit`) into `candidate`.
  void set_polygon(Candidate& candidate, std::span<const Eigen::Vector3d> points) noexcept;
  [[nodiscard]] bool can_merge(const Candidate& big, const Candidate& small) noexcept;
  // The RMS distance of a candidate's points that counts as its noise when merging.
  [[nodiscard]] double noise_rmse_m(const Candidate& c) const noexcept;
  // True when `small` lies wholly inside the noise slab of `big` and is much smaller.
  [[nodiscard]] bool within_noise_slab(const Candidate& big, const Candidate& small) const noexcept;
  void absorb(Candidate& big, const Candidate& small) noexcept;
  std::size_t merge_candidates() noexcept;
  [[nodiscard]] bool excluded(const Candidate& candidate) const noexcept;
  void drop_excluded() noexcept;
  void label_and_emit() noexcept;
  // label_and_emit()'s steps: the ground (the lowest horizontal plane with a quarter of the
  // largest one's points), its far pieces merged into it, and the planes out with their kinds.
  [[nodiscard]] Candidate* find_ground() noexcept;
  void absorb_far_ground(Candidate& ground) noexcept;
  void emit(const Candidate* ground) noexcept;
  [[nodiscard]] msg::PlaneKind kind_of(const Candidate& c, const Eigen::Vector3d& normal,
                                       const Candidate* ground) const noexcept;
  [[nodiscard]] bool horizontal(const Candidate& c) const noexcept;
  // A point's height above the ground plane, along the vertical.
  [[nodiscard]] static double height_above(const Candidate& ground,
                                           const Eigen::Vector3d& p) noexcept;

  PlanesConfig config_;
  std::array<PlaneExclusion, kMaxExclusions> exclusions_{};
  std::size_t exclusion_count_ = 0;
  std::span<SectionPlane> planes_;
  std::size_t plane_count_ = 0;
  std::span<std::uint32_t> parent_;
  std::span<std::uint32_t> member_order_;
  std::span<Candidate> candidates_;
  std::size_t candidate_count_ = 0;
  std::span<Eigen::Vector3d> scratch_points_;
  std::span<Eigen::Vector2d> scratch_2d_;
  std::span<Eigen::Vector2d> scratch_hull_;
  std::span<Eigen::Vector2d> scratch_other_;
  std::span<msg::PlanePatch> output_;
  std::span<PointMoments> output_moments_;
  std::size_t output_count_ = 0;
  Counters counters_;
};

}  // namespace blockmap::planes
