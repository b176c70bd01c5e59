// The mapper's planes over time. Each detection over the sliding window gives the planes of
// what the window holds now; the registry keeps the map's planes across detections, under
// ids that stay, and says what changed: a plane seen for the first time (added), one that grew
// or moved (changed), one whose region has left the window for good (finalized).
//
// A plane's points are in two parts whose moments add up exactly (the paper's weighting by
// size, as in the merger):
//   - live: the points behind it in the latest detection, all inside the window;
//   - frozen: the points of the tiles that left the window while it was live, taken from
//     their samples as they left (samples within its noise band).
// So the part of a wall the robot drove past is neither lost nor counted twice when the
// window detects the rest of it again. A final plane keeps its moments: when the robot comes
// back (a loop) and the window sees it again, it is live again under its id (reported as
// changed when it grows), not a second plane.
//
// The latest detection is the authority on what the window holds. A detected plane that
// matches several live planes shows they are one: the biggest takes the others' points and
// ids of the others are removed. A live plane that no detection has matched for
// retract_after_misses detections in a row is no longer there as a plane (what looked flat
// from afar turned out to be foliage, or the laser's own scan plane through bushes): it is
// finalized with the points that already left the window, or removed when there are none.
//
// Capacity, with a named policy when full: at most max_live_planes live planes; a new plane
// that finds them all taken replaces the smallest live one if it is bigger (that one is
// finalized early, counted), or is refused (counted). At most max_final_planes final planes; a
// plane finalized when they are all taken replaces the smallest if it is bigger, else is
// dropped (counted either way). Either way the dropped plane is reported removed, so that the
// stream keeps showing what the final list holds.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <span>
#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "blockmap/core/arena.hpp"
#include "blockmap/core/time.hpp"
#include "blockmap/map/voxel_window.hpp"
#include "blockmap/msg/plane_patch.hpp"
#include "blockmap/planes/point_moments.hpp"

namespace blockmap::map {

struct PlaneRegistryConfig {
  // The planes in the mapper's window: at most 32 on benning, 21 over ten laps of usc_block
  // (the run's "capacities" line); 256 leaves eight times that.
  std::size_t max_live_planes = 256;
  // The planes that left the window: 82 on benning, 170 over ten laps of usc_block.
  std::size_t max_final_planes = 2048;
  // The most planes one detection gives (the detector's max_planes): it sizes the change list.
  std::size_t max_detected_planes = 4096;
  // A detected plane is a live plane's next look when their normals differ by at most
  // match_angle_deg, each centroid lies within match_distance_m (or twice the planes' RMS
  // distance, when larger) of the other plane, and their extents come within match_gap_m.
  // With walls_from_lines, the polygons' vertices nearest each other may stand for the
  // centroids: the traces of a facade bent by the poses meet where they join.
  double match_angle_deg = 5.0;
  double match_distance_m = 0.15;
  double match_gap_m = 2.0;
  // An evicted sample belongs to a live plane when its centroid lies within this band (or
  // three times the plane's RMS distance, up to max_band_m) and inside its extent grown by
  // the band.
  double band_m = 0.1;
  double max_band_m = 0.4;
  // Walls seen as horizontal lines are the vertical planes through them (the detector's
  // walls_from_lines); a line is one when it is narrower than line_width_m.
  bool walls_from_lines = false;
  double line_width_m = 0.1;
  std::uint32_t retract_after_misses = 3;
  double min_final_support = 50.0;  // a retracted plane with fewer frozen points is removed
  // A plane is reported changed when it moved or grew by more than these.
  double change_angle_deg = 0.05;
  double change_offset_m = 0.005;
  double change_support_ratio = 0.01;
  double change_extent_m = 0.05;
};

[[nodiscard]] std::string validate(const PlaneRegistryConfig& config);

struct PlaneRegistryCounters {
  std::uint64_t added = 0;
  std::uint64_t changed = 0;
  std::uint64_t finalized = 0;
  std::uint64_t merged = 0;           // live planes found to be one with a bigger one: removed
  std::uint64_t retracted = 0;        // no longer detected, nothing frozen: removed
  std::uint64_t finalized_early = 0;  // live planes full: the smallest made room
  std::uint64_t refused_full = 0;     // live planes full: the new one was the smallest
  std::uint64_t final_dropped = 0;    // final planes full: the smallest was dropped
  std::uint64_t samples_frozen = 0;   // evicted samples kept by a live plane
  std::uint64_t reopened = 0;         // final planes seen again (the robot came back)
  std::uint64_t view_moved = 0;       // planes reported again where a refreshed view puts them
  std::uint64_t finals_joined = 0;    // final planes a move laid on a bigger one's surface
  // The most live planes after an update, and the most changes one update held: what
  // max_live_planes and the change list (change_capacity()) are sized against.
  std::size_t peak_live = 0;
  std::size_t peak_changes = 0;
};

// When a plane was seen: the stamps of the detections that matched it, as at most kMaxSpans
// spans of time. Detections less than kJoinGapNs apart are one span (the robot driving past);
// a longer gap starts another (it came back). When every span is taken, the two with the
// shortest gap between them become one. The mapper's rigid path shows and moves a plane by
// the keyframes of these times only: another pass near it, behind the building, did not draw it.
struct SeenSpans {
  static constexpr std::size_t kMaxSpans = 4;
  static constexpr TimestampNs kJoinGapNs = 20 * kNanosecondsPerSecond;
  std::array<TimestampNs, kMaxSpans> from_ns{};
  std::array<TimestampNs, kMaxSpans> to_ns{};
  std::uint8_t count = 0;

  void add(TimestampNs stamp_ns) noexcept { add_span(stamp_ns, stamp_ns); }
  void merge(const SeenSpans& other) noexcept;
  // Whether `stamp_ns` falls in a span, or ends before one by at most `lead_ns` (a detection
  // holds points drawn before it).
  [[nodiscard]] bool covers(TimestampNs stamp_ns, TimestampNs lead_ns) const noexcept;
  // The first look's stamp and the last's (the spans are in no order); 0 with none.
  [[nodiscard]] TimestampNs first_ns() const noexcept {
    return count == 0 ? 0 : *std::min_element(from_ns.begin(), from_ns.begin() + count);
  }
  [[nodiscard]] TimestampNs last_ns() const noexcept {
    return count == 0 ? 0 : *std::max_element(to_ns.begin(), to_ns.begin() + count);
  }

 private:
  void add_span(TimestampNs from, TimestampNs to) noexcept;
};

// A rigid motion about the vertical, p' = R(yaw_rad) p + shift_m: where the mapper's rigid
// path puts what was drawn with the poses of its time (the identity: as drawn).
struct PlaneMove {
  double yaw_rad = 0.0;
  Eigen::Vector3d shift_m = Eigen::Vector3d::Zero();

  [[nodiscard]] bool is_identity() const noexcept {
    return yaw_rad == 0.0 && shift_m == Eigen::Vector3d::Zero();
  }
  [[nodiscard]] Eigen::Matrix3d rotation() const noexcept {
    return Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  }
  [[nodiscard]] bool operator==(const PlaneMove& other) const noexcept {
    return yaw_rad == other.yaw_rad && shift_m == other.shift_m;
  }
};

// `plane` moved by `move`: its normal, offset, centroid and polygon. Never inlined: the
// stream's copy and the plane moved for good at the end must come out of the same
// instructions, bit for bit (a compiler may contract multiply-adds differently per call site).
[[gnu::noinline]] void move_plane(msg::PlanePatch& plane, const PlaneMove& move) noexcept;

// Where the stream shows each plane. The registry keeps its planes as drawn (a later look is
// drawn with the poses of its time too, and must match them), and asks the view, for each
// plane it reports, how to move it; the mapper's rigid path is the view.
class PlaneView {
 public:
  virtual ~PlaneView() = default;
  // How to move `plane`, seen at the times `seen` holds (none: a restored plane, which the
  // run that saved it placed already).
  [[nodiscard]] virtual PlaneMove move_of(const msg::PlanePatch& plane,
                                          const SeenSpans& seen) const noexcept = 0;

 protected:
  PlaneView() = default;
  PlaneView(const PlaneView&) = default;
  PlaneView& operator=(const PlaneView&) = default;
};

// A plane as a snapshot keeps it (the map survives a crash): where the stream shows
// it, and the moments of all its points there, which is all a final plane is.
struct SavedPlane {
  msg::PlanePatch plane;
  planes::PointMoments moments;
};

class PlaneRegistry final : public VoxelWindow::EvictionSink {
 public:
  void init(Arena& arena, const PlaneRegistryConfig& config);
  [[nodiscard]] static std::size_t arena_bytes(const PlaneRegistryConfig& config) noexcept;

  // Changes an update may hold beyond what its detections bound (changes_per_update): final
  // planes that a detection finds on the surface of the plane it matched, each reported
  // removed as it joins that one, and final planes dropped to make room for a bigger one. Past
  // these, a final plane waits to join until the next update, and a plane finalized into a
  // full list is the one dropped.
  static constexpr std::size_t kExtraChangesPerUpdate = 64;

  // The changes since begin_update() accumulate until the next begin_update().
  void begin_update() noexcept {
    change_count_ = 0;
    extra_changes_ = 0;
  }
  [[nodiscard]] std::span<const msg::PlaneChange> changes() const noexcept {
    return changes_.first(change_count_);
  }

  // A window tile's samples as it leaves: the live planes they lie on freeze them.
  void on_evicted(const VoxelWindow::EvictedTile& tile) noexcept override;
  // The planes of the latest detection over the window, with the moments of their points.
  // `seen_ns` is the detection's stamp: the planes it matches were seen then (seen_spans()).
  void update(std::span<const msg::PlanePatch> detected,
              std::span<const planes::PointMoments> moments, TimestampNs seen_ns) noexcept;
  // Live planes whose extent lies wholly outside `window_m` (x, y) are finalized.
  void finalize_outside(const Eigen::AlignedBox2d& window_m) noexcept;
  // The end of the run: every live plane is finalized.
  void finalize_all() noexcept;
  // After finalize_all(): every final plane moved for good by `view`, with its points'
  // moments, and reported finalized where it now is unless the stream shows it there
  // already; the view, if one was set, is then off, since the planes are where it put them.
  // Returns how many moved.
  std::size_t move_finals_by(const PlaneView& view) noexcept;
  // After move_finals_by(): final planes the move laid on one surface (a loop's start,
  // drawn again at its end before the path closed it) become one, as a surface seen again
  // while live does (the same match, but extents that meet within match_distance_m: two
  // buildings' facades in one line, a gap apart, stay two): the bigger takes the other's
  // points and is reported finalized again, the other removed. At most `max_changes` changes (two a
  // join) an update: false while more are left, which the next call goes on with.
  bool join_finals_on_one_surface(std::size_t max_changes) noexcept;

  // From now on every plane reported is shown moved by `view` (nullptr: as drawn), and
  // buildings see the planes so (for_each_plane()). The registry does not own it.
  void set_view(const PlaneView* view, double change_m) noexcept {
    view_ = view;
    view_change_m_ = change_m;
  }
  [[nodiscard]] bool has_view() const noexcept { return view_ != nullptr; }
  // The view moved: each plane that the stream shows more than the view's change_m off
  // where the view now puts it (at any vertex) is reported there again, a live one as
  // changed, a final one as finalized. At most `max_changes` an update, so that one fits a
  // datagram: false while planes are left to look at, which the next call goes on with
  // (nothing else may change the registry in between).
  bool refresh_view(std::size_t max_changes) noexcept;

  // Every plane as it would be if the run ended now (final planes as they are, live ones as
  // finalize_all() would make them), where the stream shows it, into `out`; how many (at
  // most out.size(), the biggest first when more). The registry is left as it was.
  [[nodiscard]] std::size_t save(std::span<SavedPlane> out) noexcept;
  // Before the first update: the saved planes become final planes (the robot may be anywhere
  // now; seen again, a plane is reopened under its id), and new ids continue after theirs.
  void restore(std::span<const SavedPlane> planes) noexcept;
  [[nodiscard]] std::uint32_t next_id() const noexcept { return next_id_; }

  // The final planes (in no particular order).
  [[nodiscard]] std::span<const msg::PlanePatch> final_planes() const noexcept {
    return final_.first(final_count_);
  }
  // How the stream shows final plane `index` (the view's move when it was last reported).
  [[nodiscard]] const PlaneMove& final_shown(std::size_t index) const noexcept {
    return final_shown_[index];
  }
  // When final plane `index` (of final_planes()) was seen; no spans for a restored plane
  // (a snapshot keeps none) until it is seen again.
  [[nodiscard]] const SeenSpans& seen_spans(std::size_t index) const noexcept {
    return final_seen_[index];
  }
  // Every plane a consumer of the stream holds now: the final ones, then the live ones as
  // last reported, where the view showed them (the building fitter reads the map this way;
  // a plane is copied only when it is moved).
  template <typename Visit>
  void for_each_plane(Visit&& visit) const {
    for (std::size_t i = 0; i < final_count_; ++i) {
      visit_shown(final_[i], final_shown_[i], visit);
    }
    for (const LivePlane& plane : live_) {
      if (plane.in_use && plane.reported.id != 0) {
        visit_shown(plane.reported, plane.shown, visit);
      }
    }
  }
  [[nodiscard]] std::size_t live_count() const noexcept { return live_count_; }
  [[nodiscard]] std::size_t live_capacity() const noexcept { return live_.size(); }
  [[nodiscard]] std::size_t final_capacity() const noexcept { return final_.size(); }
  // The most changes one update can hold.
  [[nodiscard]] std::size_t change_capacity() const noexcept { return changes_.size(); }
  [[nodiscard]] const PlaneRegistryCounters& counters() const noexcept { return counters_; }
  [[nodiscard]] std::size_t memory_bytes() const noexcept {
    return live_.size_bytes() + final_.size_bytes() + final_moments_.size_bytes() +
           final_seen_.size_bytes() + final_shown_.size_bytes() + changes_.size_bytes() +
           scratch_2d_.size_bytes() + scratch_hull_.size_bytes();
  }

 private:
  struct LivePlane {
    bool in_use = false;
    bool fresh = false;            // live holds the latest detection, and nothing froze since
    std::uint64_t matched_in = 0;  // the update that last matched it
    std::uint32_t misses = 0;      // detections in a row that did not match it
    msg::PlaneKind kind = msg::PlaneKind::kOther;  // as the best look at it labelled it
    double kind_support = 0.0;                     // the points of that look
    planes::PointMoments live;
    planes::PointMoments frozen;
    std::array<Eigen::Vector3d, msg::kMaxPolygonVertices> live_polygon_m{};
    std::uint8_t live_polygon_size = 0;
    std::array<Eigen::Vector3d, msg::kMaxPolygonVertices> frozen_polygon_m{};
    std::uint8_t frozen_polygon_size = 0;
    Eigen::Vector3d reference_normal = Eigen::Vector3d::UnitZ();  // the reported side
    msg::PlanePatch reported;                                     // as last reported
    SeenSpans seen;
    PlaneMove shown;  // how the stream showed `reported` last (the view's move then)
    // The box of the reported polygon (Eigen's AlignedBox is not trivially destructible).
    Eigen::Vector3d box_min_m = Eigen::Vector3d::Zero();
    Eigen::Vector3d box_max_m = Eigen::Vector3d::Zero();
    [[nodiscard]] Eigen::AlignedBox3d box_m() const noexcept { return {box_min_m, box_max_m}; }
  };

  // On one surface, with extents at most `gap_m` apart.
  [[nodiscard]] bool matches(const msg::PlanePatch& known, const Eigen::AlignedBox3d& known_box,
                             const msg::PlanePatch& detected,
                             const Eigen::AlignedBox3d& detected_box, double gap_m) const noexcept;
  // The plane of `points`: the vertical one through a line when walls may be lines.
  [[nodiscard]] planes::PlaneFit fit_of(const planes::PointMoments& points) const noexcept;
  // Final planes that `detected` continues: reopened as a live plane when `into` is null
  // (returned), else merged into `into`.
  LivePlane* take_final_matches(const msg::PlanePatch& detected,
                                const Eigen::AlignedBox3d& detected_box, LivePlane* into) noexcept;
  void remove_final(std::size_t index) noexcept;
  // False when the list was full and `plane` the one left out (the caller reports it removed).
  [[nodiscard]] bool store_final(const msg::PlanePatch& plane, const planes::PointMoments& moments,
                                 const SeenSpans& seen, const PlaneMove& shown) noexcept;
  [[nodiscard]] std::size_t smallest_final() const noexcept;  // of a list that is not empty
  void put_final(std::size_t index, const msg::PlanePatch& plane,
                 const planes::PointMoments& moments, const SeenSpans& seen,
                 const PlaneMove& shown) noexcept;
  // Whether one more change beyond the update's bound fits (kExtraChangesPerUpdate); taken.
  [[nodiscard]] bool take_extra_change() noexcept;
  // The live plane `detected` continues (the biggest of those it matches, the others merged
  // into it), or nullptr.
  [[nodiscard]] LivePlane* match_and_merge(const msg::PlanePatch& detected) noexcept;
  void absorb(LivePlane& big, LivePlane& small) noexcept;
  void remove(LivePlane& plane) noexcept;
  void count_misses() noexcept;
  // A slot for a new plane of `support` points; nullptr when refused.
  [[nodiscard]] LivePlane* free_slot(double support) noexcept;
  // The points behind a plane: frozen and live.
  [[nodiscard]] static planes::PointMoments points_of(const LivePlane& plane) noexcept;
  // The plane of frozen + live points (or what is left of it) into `out`.
  void combine(const LivePlane& plane, msg::PlanePatch& out) noexcept;
  [[nodiscard]] bool differs(const msg::PlanePatch& a, const msg::PlanePatch& b) const noexcept;
  void report(LivePlane& plane, msg::PlaneChangeKind change) noexcept;
  void finalize(LivePlane& plane) noexcept;
  // The change into the update's list, the plane moved as `shown` says.
  void emit(msg::PlaneChangeKind change, const msg::PlanePatch& plane,
            const PlaneMove& shown) noexcept;
  // Where the view puts `plane` now (the identity without a view).
  [[nodiscard]] PlaneMove view_move(const msg::PlanePatch& plane,
                                    const SeenSpans& seen) const noexcept {
    return view_ == nullptr ? PlaneMove{} : view_->move_of(plane, seen);
  }
  // Whether the stream, showing `plane` by `shown`, is more than view_change_m_ off `now`.
  [[nodiscard]] bool shown_off(const msg::PlanePatch& plane, const PlaneMove& shown,
                               const PlaneMove& now) const noexcept;
  void move_final(std::size_t index, const PlaneMove& move) noexcept;
  // Final plane `into` takes final plane `from`'s points and extent, refitted; `from` goes.
  void join_final(std::size_t into, std::size_t from) noexcept;
  template <typename Visit>
  static void visit_shown(const msg::PlanePatch& plane, const PlaneMove& shown, Visit& visit) {
    if (shown.is_identity()) {
      visit(plane);
      return;
    }
    msg::PlanePatch moved = plane;
    move_plane(moved, shown);
    visit(moved);
  }
  // The convex hull of two polygons' vertices on the plane (normal, through centroid).
  std::uint8_t hull_on_plane(const Eigen::Vector3d& normal, const Eigen::Vector3d& centroid,
                             std::span<const Eigen::Vector3d> a, std::span<const Eigen::Vector3d> b,
                             std::span<Eigen::Vector3d> out) noexcept;

  PlaneRegistryConfig config_;
  double cos_match_angle_ = 1.0;
  double cos_change_angle_ = 1.0;
  std::span<LivePlane> live_;
  std::size_t live_count_ = 0;
  std::span<msg::PlanePatch> final_;
  std::span<planes::PointMoments> final_moments_;
  std::span<SeenSpans> final_seen_;
  std::span<PlaneMove> final_shown_;
  std::size_t final_count_ = 0;
  const PlaneView* view_ = nullptr;
  double view_change_m_ = 0.05;
  std::size_t refresh_next_ = 0;  // where refresh_view() goes on: finals, then live slots
  std::span<msg::PlaneChange> changes_;
  std::size_t change_count_ = 0;
  std::size_t extra_changes_ = 0;  // of kExtraChangesPerUpdate, taken in this update
  std::span<Eigen::Vector2d> scratch_2d_;
  std::span<Eigen::Vector2d> scratch_hull_;
  std::uint32_t next_id_ = 1;
  std::uint64_t update_number_ = 0;
  PlaneRegistryCounters counters_;
};

}  // namespace blockmap::map
