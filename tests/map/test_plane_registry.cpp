// The plane registry: ids that stay over detections, changes reported once, planes frozen as
// their tiles leave, finalized when their region has left, merged, retracted, reopened.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <numbers>
#include <span>
#include <vector>

#include <Eigen/Geometry>

#include "blockmap/core/arena.hpp"
#include "blockmap/map/plane_registry.hpp"
#include "blockmap/pipeline/rigid_path_solver.hpp"
#include "blockmap/planes/voxel_grid.hpp"

namespace blockmap::map {
namespace {

// A wall on the plane y = y_m, from x0 to x1, 0 to 4 m high, as the detector reports it:
// the plane, its polygon, and the moments of points every 0.1 m over it.
struct Detected {
  msg::PlanePatch plane;
  planes::PointMoments moments;
};

Detected wall(double x0_m, double x1_m, double y_m, double z1_m = 4.0) {
  Detected d;
  for (double x = x0_m; x <= x1_m + 1e-9; x += 0.1) {
    for (double z = 0.0; z <= z1_m + 1e-9; z += 0.1) {
      d.moments.add(Eigen::Vector3d(x, y_m, z));
    }
  }
  d.plane.kind = msg::PlaneKind::kWall;
  d.plane.normal = Eigen::Vector3d::UnitY();
  d.plane.d_m = y_m;
  d.plane.support = d.moments.weight;
  d.plane.rmse_m = 0.01;
  d.plane.centroid_m = d.moments.mean();
  d.plane.polygon_size = 4;
  d.plane.polygon_m[0] = {x0_m, y_m, 0.0};
  d.plane.polygon_m[1] = {x1_m, y_m, 0.0};
  d.plane.polygon_m[2] = {x1_m, y_m, z1_m};
  d.plane.polygon_m[3] = {x0_m, y_m, z1_m};
  return d;
}

// A level laser's trace of a wall from from_m to to_m (x, y): points every 0.1 m along it in a
// slice 0.1 m high at the laser's height, reported as the vertical plane through the line.
Detected trace(const Eigen::Vector2d& from_m, const Eigen::Vector2d& to_m) {
  constexpr double kHeightM = 0.5;
  Detected d;
  const Eigen::Vector2d along = (to_m - from_m).normalized();
  const double length_m = (to_m - from_m).norm();
  for (double s = 0.0; s <= length_m + 1e-9; s += 0.1) {
    const Eigen::Vector2d p = from_m + s * along;
    for (const double z : {kHeightM - 0.05, kHeightM + 0.05}) {
      d.moments.add(Eigen::Vector3d(p.x(), p.y(), z));
    }
  }
  d.plane.kind = msg::PlaneKind::kWall;
  d.plane.normal = Eigen::Vector3d(-along.y(), along.x(), 0.0);
  d.plane.d_m = d.plane.normal.head<2>().dot(from_m);
  d.plane.support = d.moments.weight;
  d.plane.rmse_m = 0.02;
  d.plane.centroid_m = d.moments.mean();
  d.plane.polygon_size = 4;
  d.plane.polygon_m[0] = {from_m.x(), from_m.y(), kHeightM - 0.1};
  d.plane.polygon_m[1] = {to_m.x(), to_m.y(), kHeightM - 0.1};
  d.plane.polygon_m[2] = {to_m.x(), to_m.y(), kHeightM + 0.1};
  d.plane.polygon_m[3] = {from_m.x(), from_m.y(), kHeightM + 0.1};
  return d;
}

struct Registry {
  explicit Registry(const PlaneRegistryConfig& config = {})
      : arena(PlaneRegistry::arena_bytes(config)) {
    registry.init(arena, config);
    arena.seal();
  }
  // One detection with these planes; the changes it made.
  std::vector<msg::PlaneChange> detect(const std::vector<Detected>& planes) {
    registry.begin_update();
    std::vector<msg::PlanePatch> patches;
    std::vector<planes::PointMoments> moments;
    for (const Detected& d : planes) {
      patches.push_back(d.plane);
      moments.push_back(d.moments);
    }
    registry.update(patches, moments, now_ns);
    now_ns += kNanosecondsPerSecond;
    return {registry.changes().begin(), registry.changes().end()};
  }
  Arena arena;
  PlaneRegistry registry;
  TimestampNs now_ns = 0;  // of the next detection: one a second
};

std::size_t count(const std::vector<msg::PlaneChange>& changes, msg::PlaneChangeKind kind) {
  std::size_t n = 0;
  for (const msg::PlaneChange& c : changes) {
    n += c.change == kind ? 1U : 0U;
  }
  return n;
}

TEST(PlaneRegistry, AddsOnceThenReportsOnlyRealChangesUnderTheSameId) {
  Registry r;
  auto changes = r.detect({wall(0, 5, 10)});
  ASSERT_EQ(changes.size(), 1u);
  EXPECT_EQ(changes[0].change, msg::PlaneChangeKind::kAdded);
  const std::uint32_t id = changes[0].plane.id;
  EXPECT_NE(id, 0u);
  EXPECT_NEAR(changes[0].plane.d_m, 10.0, 1e-9);
  // The same plane again: nothing to say.
  EXPECT_TRUE(r.detect({wall(0, 5, 10)}).empty());
  // It grew: changed, same id, bigger extent.
  changes = r.detect({wall(0, 8, 10)});
  ASSERT_EQ(changes.size(), 1u);
  EXPECT_EQ(changes[0].change, msg::PlaneChangeKind::kChanged);
  EXPECT_EQ(changes[0].plane.id, id);
  EXPECT_GT(changes[0].plane.support, wall(0, 5, 10).moments.weight);
  // A second wall elsewhere is a second plane.
  changes = r.detect({wall(0, 8, 10), wall(0, 5, 30)});
  ASSERT_EQ(count(changes, msg::PlaneChangeKind::kAdded), 1u);
  EXPECT_NE(changes[0].plane.id, id);
  EXPECT_EQ(r.registry.live_count(), 2u);
}

TEST(PlaneRegistry, FinalizesPlanesWhoseRegionLeftTheWindow) {
  Registry r;
  static_cast<void>(r.detect({wall(0, 5, 10), wall(50, 55, 10)}));
  r.registry.begin_update();
  r.registry.finalize_outside(Eigen::AlignedBox2d(Eigen::Vector2d(20, 0), Eigen::Vector2d(80, 40)));
  ASSERT_EQ(r.registry.changes().size(), 1u);
  EXPECT_EQ(r.registry.changes()[0].change, msg::PlaneChangeKind::kFinalized);
  EXPECT_NEAR(r.registry.changes()[0].plane.centroid_m.x(), 2.5, 1e-6);
  ASSERT_EQ(r.registry.final_planes().size(), 1u);
  EXPECT_EQ(r.registry.live_count(), 1u);
  r.registry.begin_update();
  r.registry.finalize_all();
  EXPECT_EQ(r.registry.final_planes().size(), 2u);
  EXPECT_EQ(r.registry.live_count(), 0u);
}

TEST(PlaneRegistry, KeepsThePointsOfTilesThatLeaveAndCountsThemOnce) {
  Registry r;
  static_cast<void>(r.detect({wall(0, 10, 10)}));
  // The tile x in [0, 5) leaves with samples on the wall (one point each at 0.1 m spacing,
  // as the window keeps them: sums about the voxel's centre).
  std::vector<planes::VoxelSums> samples;
  for (double x = 0.05; x < 5.0; x += 0.2) {
    for (double z = 0.05; z < 4.0; z += 0.2) {
      const Eigen::Vector3d p(x, 10.0, z);
      planes::VoxelSums sums;
      const auto cx = static_cast<std::int64_t>(std::floor(p.x() / 0.2));
      const auto cy = static_cast<std::int64_t>(std::floor(p.y() / 0.2));
      const auto cz = static_cast<std::int64_t>(std::floor(p.z() / 0.2));
      sums.key = planes::pack_cell(cx, cy, cz);
      sums.point_count = 1;
      const Eigen::Vector3d centre =
          (planes::unpack_cell(sums.key).cast<double>().array() + 0.5) * 0.2;
      const Eigen::Vector3f local = (p - centre).cast<float>();
      sums.sum_m[0] = local.x();
      sums.sum_m[1] = local.y();
      sums.sum_m[2] = local.z();
      samples.push_back(sums);
    }
  }
  // Samples off the wall (a tree 2 m in front of it) stay out.
  planes::VoxelSums tree;
  tree.key = planes::pack_cell(10, 40, 10);
  tree.point_count = 5;
  samples.push_back(tree);
  r.registry.begin_update();
  r.registry.on_evicted(VoxelWindow::EvictedTile{
      Eigen::AlignedBox2d(Eigen::Vector2d(0, 0), Eigen::Vector2d(5, 20)), 0.2, samples});
  EXPECT_EQ(r.registry.counters().samples_frozen, samples.size() - 1);
  // The next detection sees only what is left in the window: x from 5 to 10.
  auto changes = r.detect({wall(5, 10, 10)});
  ASSERT_EQ(changes.size(), 1u);
  EXPECT_EQ(changes[0].change, msg::PlaneChangeKind::kChanged);
  const double expected = wall(5, 10, 10).moments.weight + static_cast<double>(samples.size() - 1);
  EXPECT_NEAR(changes[0].plane.support, expected, 1e-6);
  // Its extent is still the whole wall.
  double x_min = 1e9;
  for (std::size_t i = 0; i < changes[0].plane.polygon_size; ++i) {
    x_min = std::min(x_min, changes[0].plane.polygon_m[i].x());
  }
  EXPECT_LT(x_min, 0.2);
  EXPECT_NEAR(changes[0].plane.d_m, 10.0, 0.01);
}

TEST(PlaneRegistry, ADetectionSpanningTwoPlanesMakesThemOne) {
  Registry r;
  const auto first = r.detect({wall(0, 4, 10), wall(7, 11, 10)});
  ASSERT_EQ(first.size(), 2u);
  const auto changes = r.detect({wall(0, 11, 10)});
  EXPECT_EQ(count(changes, msg::PlaneChangeKind::kRemoved), 1u);
  EXPECT_EQ(count(changes, msg::PlaneChangeKind::kChanged), 1u);
  EXPECT_EQ(r.registry.live_count(), 1u);
  EXPECT_EQ(r.registry.counters().merged, 1u);
}

// A facade that a level laser saw through drifting poses: two 30 m traces 1.5 deg apart, the
// second beginning where the first ends. Their centroids lie 0.36-0.44 m off each other's line
// (over the 0.15 m that matches), and they meet at the joint: with walls_from_lines they are
// one plane. A trace 0.4 m in front of the first (a fence, a row of cars) stays apart, and
// planes of surfaces keep the centroid rule.
TEST(PlaneRegistry, LevelLaserTracesOfABentFacadeMeetAtTheirEnds) {
  const double rise_m = 30.0 * std::tan(1.5 * std::numbers::pi / 180.0);
  const Detected first = trace({0.0, 0.0}, {30.0, 0.0});
  const Detected bent = trace({30.5, 0.05}, {60.5, 0.05 + rise_m});
  const Detected fence = trace({30.5, 0.4}, {60.5, 0.4});
  PlaneRegistryConfig lines;
  lines.walls_from_lines = true;
  {
    Registry r(lines);
    const auto added = r.detect({first});
    ASSERT_EQ(added.size(), 1u);
    const auto changes = r.detect({bent});
    ASSERT_EQ(changes.size(), 1u);
    EXPECT_EQ(changes[0].change, msg::PlaneChangeKind::kChanged);
    EXPECT_EQ(changes[0].plane.id, added[0].plane.id);
    EXPECT_EQ(r.registry.live_count(), 1u);
  }
  {
    Registry r(lines);
    static_cast<void>(r.detect({first}));
    EXPECT_EQ(count(r.detect({fence}), msg::PlaneChangeKind::kAdded), 1u);
    EXPECT_EQ(r.registry.live_count(), 2u);
  }
  {
    Registry r;  // surfaces: the centroids decide
    static_cast<void>(r.detect({first}));
    EXPECT_EQ(count(r.detect({bent}), msg::PlaneChangeKind::kAdded), 1u);
    EXPECT_EQ(r.registry.live_count(), 2u);
  }
}

TEST(PlaneRegistry, RetractsAPlaneNoLongerSeenAndFinalizesOneThatKeptPoints) {
  PlaneRegistryConfig config;
  config.retract_after_misses = 2;
  Registry r(config);
  static_cast<void>(r.detect({wall(0, 4, 10)}));
  EXPECT_TRUE(r.detect({}).empty());
  const auto changes = r.detect({});
  ASSERT_EQ(changes.size(), 1u);
  EXPECT_EQ(changes[0].change, msg::PlaneChangeKind::kRemoved);
  EXPECT_EQ(r.registry.counters().retracted, 1u);
  EXPECT_TRUE(r.registry.final_planes().empty());
}

TEST(PlaneRegistry, AFinalPlaneSeenAgainIsReopenedNotDuplicated) {
  Registry r;
  const auto added = r.detect({wall(0, 5, 10)});
  r.registry.begin_update();
  r.registry.finalize_outside(
      Eigen::AlignedBox2d(Eigen::Vector2d(50, 50), Eigen::Vector2d(60, 60)));
  ASSERT_EQ(r.registry.final_planes().size(), 1u);
  // The robot comes back: the same wall, a little more of it.
  const auto changes = r.detect({wall(0, 6, 10)});
  ASSERT_EQ(changes.size(), 1u);
  EXPECT_EQ(changes[0].change, msg::PlaneChangeKind::kChanged);
  EXPECT_EQ(changes[0].plane.id, added[0].plane.id);
  EXPECT_TRUE(r.registry.final_planes().empty());
  EXPECT_EQ(r.registry.counters().reopened, 1u);
}

// When a plane was seen: detections less than 20 s apart are one span, a later look (the
// robot came back) another; the mapper's rigid path moves it by the keyframes of those times.
TEST(PlaneRegistry, AFinalPlaneKnowsWhenItWasSeen) {
  Registry r;
  for (int i = 0; i < 3; ++i) {
    static_cast<void>(r.detect({wall(0, 5, 10)}));  // at 0, 1 and 2 s
  }
  r.registry.begin_update();
  r.registry.finalize_all();
  ASSERT_EQ(r.registry.final_planes().size(), 1u);
  const SeenSpans& once = r.registry.seen_spans(0);
  ASSERT_EQ(once.count, 1u);
  EXPECT_EQ(once.from_ns[0], 0);
  EXPECT_EQ(once.to_ns[0], 2 * kNanosecondsPerSecond);
  // Seen again 100 s later: reopened, and a second span when it is final again.
  r.now_ns = 100 * kNanosecondsPerSecond;
  static_cast<void>(r.detect({wall(0, 6, 10)}));
  r.registry.begin_update();
  r.registry.finalize_all();
  ASSERT_EQ(r.registry.final_planes().size(), 1u);
  const SeenSpans& twice = r.registry.seen_spans(0);
  ASSERT_EQ(twice.count, 2u);
  EXPECT_TRUE(twice.covers(kNanosecondsPerSecond, 0));
  EXPECT_TRUE(twice.covers(100 * kNanosecondsPerSecond, 0));
  EXPECT_FALSE(twice.covers(50 * kNanosecondsPerSecond, 0)) << "between the passes";
  EXPECT_TRUE(twice.covers(95 * kNanosecondsPerSecond, 10 * kNanosecondsPerSecond))
      << "points drawn shortly before the detection that found them";
}

TEST(SeenSpans, JoinsNearLooksAndWhenFullTheNearestSpans) {
  constexpr TimestampNs kS = kNanosecondsPerSecond;
  SeenSpans seen;
  for (const TimestampNs t : {0 * kS, 10 * kS, 25 * kS}) {
    seen.add(t);  // each within 20 s of the one before: one span
  }
  ASSERT_EQ(seen.count, 1u);
  EXPECT_EQ(seen.to_ns[0], 25 * kS);
  for (const TimestampNs t : {100 * kS, 200 * kS, 300 * kS}) {
    seen.add(t);
  }
  ASSERT_EQ(seen.count, SeenSpans::kMaxSpans);
  // A fifth look: the two spans nearest in time (0-25 s and 100 s, 75 s apart) become one.
  seen.add(400 * kS);
  ASSERT_EQ(seen.count, SeenSpans::kMaxSpans);
  EXPECT_TRUE(seen.covers(60 * kS, 0)) << "the joined span covers the gap it closed";
  EXPECT_FALSE(seen.covers(150 * kS, 0));
  EXPECT_TRUE(seen.covers(400 * kS, 0));
  EXPECT_TRUE(seen.covers(200 * kS, 0));
  // A span that bridges two others takes both.
  SeenSpans bridge;
  bridge.add(0);
  bridge.add(40 * kS);
  ASSERT_EQ(bridge.count, 2u);
  SeenSpans middle;
  middle.add(20 * kS);
  bridge.merge(middle);
  ASSERT_EQ(bridge.count, 1u);
  EXPECT_EQ(bridge.from_ns[0], 0);
  EXPECT_EQ(bridge.to_ns[0], 40 * kS);
}

// A view that moves every plane by one shift east, which a test sets (the mapper's rigid path
// as a stand-in: it moves each plane by its own keyframes).
class ShiftEast final : public PlaneView {
 public:
  [[nodiscard]] PlaneMove move_of(const msg::PlanePatch& /*plane*/,
                                  const SeenSpans& /*seen*/) const noexcept override {
    return PlaneMove{0.0, Eigen::Vector3d(east_m, 0.0, 0.0)};
  }
  double east_m = 0.0;
};

// With a view, the stream and the buildings see each plane where the view puts it, while the
// registry keeps it as drawn: a later look, drawn alike, still matches it.
TEST(PlaneRegistry, AViewShowsThePlanesMovedWhileTheyStayAsDrawn) {
  Registry r;
  ShiftEast view;
  view.east_m = 2.0;
  r.registry.set_view(&view, 0.05);
  const auto added = r.detect({wall(0, 5, 10)});
  ASSERT_EQ(added.size(), 1u);
  EXPECT_EQ(added[0].change, msg::PlaneChangeKind::kAdded);
  EXPECT_NEAR(added[0].plane.centroid_m.x(), 4.5, 1e-9);  // 2.5 drawn, 2 m east
  double west_m = 1e9;
  for (std::size_t v = 0; v < added[0].plane.polygon_size; ++v) {
    west_m = std::min(west_m, added[0].plane.polygon_m[v].x());
  }
  EXPECT_NEAR(west_m, 2.0, 1e-9);               // its polygon with it
  EXPECT_NEAR(added[0].plane.d_m, 10.0, 1e-9);  // y = 10 does not move east
  // Drawn again where it was: the same plane, nothing to say.
  EXPECT_TRUE(r.detect({wall(0, 5, 10)}).empty());
  std::vector<msg::PlanePatch> seen;
  r.registry.for_each_plane([&](const msg::PlanePatch& plane) { seen.push_back(plane); });
  ASSERT_EQ(seen.size(), 1u);
  EXPECT_NEAR(seen[0].centroid_m.x(), 4.5, 1e-9);
  r.registry.begin_update();
  r.registry.finalize_all();
  ASSERT_EQ(r.registry.changes().size(), 1u);
  EXPECT_NEAR(r.registry.changes()[0].plane.centroid_m.x(), 4.5, 1e-9);
  ASSERT_EQ(r.registry.final_planes().size(), 1u);
  EXPECT_NEAR(r.registry.final_planes()[0].centroid_m.x(), 2.5, 1e-9);  // kept as drawn
  // A snapshot keeps it where the stream shows it, its points with it.
  std::array<SavedPlane, 2> saved{};
  ASSERT_EQ(r.registry.save(saved), 1u);
  EXPECT_NEAR(saved[0].plane.centroid_m.x(), 4.5, 1e-9);
  EXPECT_NEAR(saved[0].moments.mean().x(), 4.5, 1e-9);
}

// A refreshed view reports again only the planes it moved more than its change distance,
// live ones as changed and final ones as finalized.
TEST(PlaneRegistry, ARefreshedViewReportsOnlyThePlanesItMovedFarEnough) {
  Registry r;
  ShiftEast view;
  r.registry.set_view(&view, 0.05);
  static_cast<void>(r.detect({wall(0, 5, 10), wall(50, 55, 10)}));
  r.registry.begin_update();
  r.registry.finalize_outside(Eigen::AlignedBox2d(Eigen::Vector2d(20, 0), Eigen::Vector2d(80, 40)));
  ASSERT_EQ(r.registry.final_planes().size(), 1u);
  view.east_m = 0.04;  // within the change distance: nothing to say
  r.registry.begin_update();
  r.registry.refresh_view(64);
  EXPECT_TRUE(r.registry.changes().empty());
  view.east_m = 0.3;
  r.registry.begin_update();
  r.registry.refresh_view(64);
  const std::vector<msg::PlaneChange> changes(r.registry.changes().begin(),
                                              r.registry.changes().end());
  ASSERT_EQ(changes.size(), 2u);
  EXPECT_EQ(count(changes, msg::PlaneChangeKind::kFinalized), 1u);
  EXPECT_EQ(count(changes, msg::PlaneChangeKind::kChanged), 1u);
  for (const msg::PlaneChange& c : changes) {
    const double drawn_x_m = c.change == msg::PlaneChangeKind::kFinalized ? 2.5 : 52.5;
    EXPECT_NEAR(c.plane.centroid_m.x(), drawn_x_m + 0.3, 1e-9);
  }
  EXPECT_EQ(r.registry.counters().view_moved, 2u);
  r.registry.begin_update();
  r.registry.refresh_view(64);  // where it showed them: nothing new
  EXPECT_TRUE(r.registry.changes().empty());
}

// A refresh hands out at most so many changes an update, and the next call goes on where
// it stopped: each update of the view fits one datagram.
TEST(PlaneRegistry, ARefreshGoesOnWhereItsLastUpdateStopped) {
  Registry r;
  ShiftEast view;
  r.registry.set_view(&view, 0.05);
  static_cast<void>(r.detect({wall(0, 5, 10), wall(0, 5, 30), wall(0, 5, 50)}));
  view.east_m = 1.0;
  std::vector<std::uint32_t> ids;
  for (int call = 0; call < 3; ++call) {
    r.registry.begin_update();
    const bool done = r.registry.refresh_view(1);
    EXPECT_LE(r.registry.changes().size(), 1u);
    for (const msg::PlaneChange& c : r.registry.changes()) {
      ids.push_back(c.plane.id);
    }
    if (done) {
      break;
    }
  }
  EXPECT_EQ(ids.size(), 3u);
  std::sort(ids.begin(), ids.end());
  EXPECT_EQ(std::unique(ids.begin(), ids.end()), ids.end()) << "each plane once";
  r.registry.begin_update();
  EXPECT_TRUE(r.registry.refresh_view(1));
  EXPECT_TRUE(r.registry.changes().empty());
}

// At the end the view's moves are made for good: a plane the stream already shows there is
// not reported again, one shown elsewhere is, and so is one that the view at last leaves as
// drawn; the view is then off.
// One wall, finalized with `view` showing it `east_m` east.
void finalize_a_wall_shown_east(Registry& r, ShiftEast& view, double east_m) {
  view.east_m = east_m;
  r.registry.set_view(&view, 0.05);
  static_cast<void>(r.detect({wall(0, 5, 10)}));
  r.registry.begin_update();
  r.registry.finalize_all();
  ASSERT_EQ(r.registry.changes().size(), 1u);
}

TEST(PlaneRegistry, TheFinalMoveReportsOnlyWhatTheStreamDoesNotShowAlready) {
  Registry r;
  ShiftEast view;
  finalize_a_wall_shown_east(r, view, 1.0);
  r.registry.begin_update();
  EXPECT_EQ(r.registry.move_finals_by(view), 1u);
  EXPECT_TRUE(r.registry.changes().empty());  // the stream has it there
  EXPECT_NEAR(r.registry.final_planes()[0].centroid_m.x(), 3.5, 1e-9);
  // The view is off now: what it would say no longer moves what is reported.
  view.east_m = 5.0;
  r.registry.begin_update();
  r.registry.refresh_view(64);
  EXPECT_TRUE(r.registry.changes().empty());

  Registry other;
  ShiftEast shown;
  finalize_a_wall_shown_east(other, shown, 1.0);
  ShiftEast stays;  // the final solve leaves it as drawn
  other.registry.begin_update();
  EXPECT_EQ(other.registry.move_finals_by(stays), 0u);
  ASSERT_EQ(other.registry.changes().size(), 1u);
  EXPECT_EQ(other.registry.changes()[0].change, msg::PlaneChangeKind::kFinalized);
  EXPECT_NEAR(other.registry.changes()[0].plane.centroid_m.x(), 2.5, 1e-9);
}

// The rigid path moves a final plane with its points: the plane, its polygon and its moments
// turn and shift together, and it is reported final again where it now is.
TEST(PlaneRegistry, AMovedFinalPlaneTakesItsPointsAlongAndIsFinalAgain) {
  Registry r;
  const auto added = r.detect({wall(0, 5, 10)});
  r.registry.begin_update();
  r.registry.finalize_all();
  ASSERT_EQ(r.registry.final_planes().size(), 1u);
  r.registry.begin_update();
  // A quarter turn about the vertical, then 1 m east: the wall y = 10 becomes x = -9.
  class QuarterTurnThenEast final : public PlaneView {
   public:
    [[nodiscard]] PlaneMove move_of(const msg::PlanePatch& /*plane*/,
                                    const SeenSpans& /*seen*/) const noexcept override {
      return PlaneMove{std::numbers::pi / 2.0, Eigen::Vector3d(1.0, 0.0, 0.0)};
    }
  };
  EXPECT_EQ(r.registry.move_finals_by(QuarterTurnThenEast{}), 1u);
  const auto changes = r.registry.changes();
  ASSERT_EQ(changes.size(), 1u);
  EXPECT_EQ(changes[0].change, msg::PlaneChangeKind::kFinalized);
  EXPECT_EQ(changes[0].plane.id, added[0].plane.id);
  const msg::PlanePatch& moved = r.registry.final_planes()[0];
  EXPECT_NEAR(moved.normal.x(), -1.0, 1e-12);
  EXPECT_NEAR(moved.d_m, 9.0, 1e-9);  // -x = 9
  EXPECT_NEAR(moved.centroid_m.x(), -9.0, 1e-9);
  EXPECT_NEAR(moved.centroid_m.y(), 2.5, 1e-9);
  for (std::size_t v = 0; v < moved.polygon_size; ++v) {
    EXPECT_NEAR(moved.normal.dot(moved.polygon_m[v]), moved.d_m, 1e-9);
  }
  std::array<SavedPlane, 4> saved{};
  ASSERT_EQ(r.registry.save(saved), 1u);
  const planes::PlaneFit fit = planes::fit_plane(saved[0].moments);
  EXPECT_NEAR(std::abs(fit.normal_unit.x()), 1.0, 1e-9);
  EXPECT_NEAR(fit.centroid_m.x(), -9.0, 1e-9);
  EXPECT_NEAR(fit.centroid_m.y(), 2.5, 1e-9);
}

// A loop closure's move: what was first seen after the first minute lies 2 m south of where
// it was drawn.
class LaterSouth final : public PlaneView {
 public:
  [[nodiscard]] PlaneMove move_of(const msg::PlanePatch& /*plane*/,
                                  const SeenSpans& seen) const noexcept override {
    const bool later = seen.count > 0 && seen.from_ns[0] > 60 * kNanosecondsPerSecond;
    return PlaneMove{0.0, Eigen::Vector3d(0.0, later ? -2.0 : 0.0, 0.0)};
  }
};

// A loop's start, drawn again at its end before the path closed it: two final planes, 2 m
// apart as drawn. The final move lays the later one on the earlier, and the two become one
// with both looks' points, under the bigger one's id; a wall elsewhere stays apart.
TEST(PlaneRegistry, FinalPlanesTheMoveLaysOnOneSurfaceBecomeOne) {
  Registry r;
  const auto start = r.detect({wall(0, 20, 10)});
  r.now_ns += 100 * kNanosecondsPerSecond;  // driving round the block
  static_cast<void>(r.detect({wall(0, 20, 10), wall(5, 15, 12), wall(0, 5, 30)}));
  r.registry.begin_update();
  r.registry.finalize_all();
  ASSERT_EQ(r.registry.final_planes().size(), 3u);
  r.registry.begin_update();
  EXPECT_EQ(r.registry.move_finals_by(LaterSouth{}), 2u);
  r.registry.begin_update();
  EXPECT_TRUE(r.registry.join_finals_on_one_surface(2));
  const auto changes = r.registry.changes();
  ASSERT_EQ(changes.size(), 2u);
  EXPECT_EQ(changes[0].change, msg::PlaneChangeKind::kRemoved);
  EXPECT_EQ(changes[1].change, msg::PlaneChangeKind::kFinalized);
  EXPECT_EQ(changes[1].plane.id, start[0].plane.id);
  EXPECT_EQ(r.registry.counters().finals_joined, 1u);
  ASSERT_EQ(r.registry.final_planes().size(), 2u);
  const auto joined =
      std::find_if(r.registry.final_planes().begin(), r.registry.final_planes().end(),
                   [&](const msg::PlanePatch& p) { return p.id == start[0].plane.id; });
  ASSERT_NE(joined, r.registry.final_planes().end());
  EXPECT_NEAR(joined->d_m, 10.0, 1e-9);
  EXPECT_NEAR(joined->support, wall(0, 20, 10).moments.weight + wall(5, 15, 12).moments.weight,
              1e-6);
  std::array<SavedPlane, 4> saved{};
  ASSERT_EQ(r.registry.save(saved), 2u);
  for (const SavedPlane& plane : std::span(saved).first(2)) {
    EXPECT_NEAR(plane.moments.weight, plane.plane.support, 1e-9);
  }
  // Nothing is left to join, and a second call says so without a change.
  r.registry.begin_update();
  EXPECT_TRUE(r.registry.join_finals_on_one_surface(2));
  EXPECT_TRUE(r.registry.changes().empty());
}

// A wall's lower part seen on the way back is too low to be called a wall (other); joined
// with the wall, the plane is a wall, though the lower part holds more points.
TEST(PlaneRegistry, AJoinedPlaneIsAWallWhenOneOfItsPartsIs) {
  Registry r;
  static_cast<void>(r.detect({wall(5, 15, 10)}));
  r.now_ns += 100 * kNanosecondsPerSecond;
  Detected low = wall(0, 30, 12, 1.5);
  low.plane.kind = msg::PlaneKind::kOther;
  ASSERT_GT(low.moments.weight, wall(5, 15, 10).moments.weight);
  static_cast<void>(r.detect({wall(5, 15, 10), low}));
  r.registry.begin_update();
  r.registry.finalize_all();
  r.registry.begin_update();
  static_cast<void>(r.registry.move_finals_by(LaterSouth{}));
  r.registry.begin_update();
  EXPECT_TRUE(r.registry.join_finals_on_one_surface(64));
  ASSERT_EQ(r.registry.final_planes().size(), 1u);
  EXPECT_EQ(r.registry.final_planes()[0].kind, msg::PlaneKind::kWall);
}

// Joins that do not fit an update's changes wait for the next update.
TEST(PlaneRegistry, JoiningFinalPlanesGoesOnInTheNextUpdateWhenOneIsFull) {
  Registry r;
  static_cast<void>(r.detect({wall(0, 20, 10), wall(0, 20, 40)}));
  r.now_ns += 100 * kNanosecondsPerSecond;
  static_cast<void>(r.detect({wall(0, 20, 10), wall(0, 20, 40), wall(0, 20, 12), wall(0, 20, 42)}));
  r.registry.begin_update();
  r.registry.finalize_all();
  ASSERT_EQ(r.registry.final_planes().size(), 4u);
  r.registry.begin_update();
  static_cast<void>(r.registry.move_finals_by(LaterSouth{}));
  r.registry.begin_update();
  EXPECT_FALSE(r.registry.join_finals_on_one_surface(3));  // one join: two changes
  EXPECT_EQ(r.registry.changes().size(), 2u);
  r.registry.begin_update();
  EXPECT_TRUE(r.registry.join_finals_on_one_surface(3));
  EXPECT_EQ(r.registry.changes().size(), 2u);
  EXPECT_EQ(r.registry.final_planes().size(), 2u);
  EXPECT_EQ(r.registry.counters().finals_joined, 2u);
}

TEST(PlaneRegistry, WhenFullTheSmallestLivePlaneMakesRoomOrTheNewOneIsRefused) {
  PlaneRegistryConfig config;
  config.max_live_planes = 2;
  Registry r(config);
  static_cast<void>(r.detect({wall(0, 5, 10), wall(0, 2, 20)}));
  // A bigger one: the smallest (x 0-2 at y 20) is finalized early.
  auto changes = r.detect({wall(0, 5, 10), wall(0, 2, 20), wall(0, 9, 30)});
  EXPECT_EQ(count(changes, msg::PlaneChangeKind::kFinalized), 1u);
  EXPECT_EQ(count(changes, msg::PlaneChangeKind::kAdded), 1u);
  EXPECT_EQ(r.registry.counters().finalized_early, 1u);
  // A smaller one than both: refused.
  changes = r.detect({wall(0, 5, 10), wall(0, 9, 30), wall(0, 1, 40)});
  EXPECT_EQ(count(changes, msg::PlaneChangeKind::kAdded), 0u);
  EXPECT_EQ(r.registry.counters().refused_full, 1u);
}

// What a consumer of the stream holds: each plane by id, as its last change left it.
struct StreamHolder {
  void apply(std::span<const msg::PlaneChange> changes) {
    for (const msg::PlaneChange& c : changes) {
      if (c.change == msg::PlaneChangeKind::kRemoved) {
        ASSERT_EQ(planes.erase(c.plane.id), 1u) << "removed, but never shown: " << c.plane.id;
      } else {
        planes[c.plane.id] = c.plane;
      }
    }
  }
  std::map<std::uint32_t, msg::PlanePatch> planes;
};

std::vector<std::uint32_t> ids_of(std::span<const msg::PlanePatch> planes) {
  std::vector<std::uint32_t> ids;
  for (const msg::PlanePatch& p : planes) {
    ids.push_back(p.id);
  }
  std::sort(ids.begin(), ids.end());
  return ids;
}

std::vector<std::uint32_t> ids_of(const StreamHolder& stream) {
  std::vector<std::uint32_t> ids;
  for (const auto& [id, plane] : stream.planes) {
    ids.push_back(id);
  }
  return ids;
}

// A full final list keeps the biggest planes, and whichever it leaves out, the new one or an
// older one, the stream is told: it holds what the final list holds.
TEST(PlaneRegistry, AFullFinalListDropsTheSmallestAndTheStreamDropsItToo) {
  PlaneRegistryConfig config;
  config.max_final_planes = 2;
  Registry r(config);
  StreamHolder stream;
  const Eigen::AlignedBox2d far_away(Eigen::Vector2d(500, 500), Eigen::Vector2d(600, 600));
  const auto finalize_one = [&](const Detected& d) {
    stream.apply(r.detect({d}));
    r.registry.begin_update();
    r.registry.finalize_outside(far_away);
    stream.apply(r.registry.changes());
    return std::vector<msg::PlaneChange>(r.registry.changes().begin(), r.registry.changes().end());
  };
  static_cast<void>(finalize_one(wall(0, 5, 10)));  // support 51 x 41
  static_cast<void>(finalize_one(wall(0, 8, 20)));  // 81 x 41
  auto changes = finalize_one(wall(0, 3, 30));      // the smallest: left out itself
  ASSERT_EQ(changes.size(), 1u);
  EXPECT_EQ(changes[0].change, msg::PlaneChangeKind::kRemoved);
  EXPECT_NEAR(changes[0].plane.d_m, 30.0, 1e-9);
  EXPECT_EQ(r.registry.counters().final_dropped, 1u);
  EXPECT_EQ(ids_of(r.registry.final_planes()), ids_of(stream));
  changes = finalize_one(wall(0, 12, 40));  // bigger than the one at y 10: that one goes
  EXPECT_EQ(count(changes, msg::PlaneChangeKind::kRemoved), 1u);
  EXPECT_EQ(count(changes, msg::PlaneChangeKind::kFinalized), 1u);
  EXPECT_EQ(r.registry.counters().final_dropped, 2u);
  ASSERT_EQ(r.registry.final_planes().size(), 2u);
  EXPECT_EQ(ids_of(r.registry.final_planes()), ids_of(stream));
  for (const msg::PlanePatch& p : r.registry.final_planes()) {
    EXPECT_TRUE(std::abs(p.d_m - 20.0) < 1e-6 || std::abs(p.d_m - 40.0) < 1e-6) << p.d_m;
  }
}

// Many final planes on one surface (a restored map) and one detection across them all: an
// update reports at most kExtraChangesPerUpdate of them joining it, the rest join at the next.
TEST(PlaneRegistry, FinalPlanesJoiningADetectionPastWhatAnUpdateHoldsWaitForTheNext) {
  constexpr std::size_t kPieces = PlaneRegistry::kExtraChangesPerUpdate + 6;
  Registry r;
  std::vector<SavedPlane> saved;
  for (std::size_t i = 0; i < kPieces; ++i) {
    const double x0_m = 0.1 * static_cast<double>(i);
    Detected piece = wall(x0_m, x0_m + 4.0, 10);
    piece.plane.id = static_cast<std::uint32_t>(i + 1);
    saved.push_back(SavedPlane{piece.plane, piece.moments});
  }
  r.registry.restore(saved);
  StreamHolder stream;
  for (const SavedPlane& s : saved) {
    stream.planes[s.plane.id] = s.plane;  // what the run before showed
  }
  const Detected across = wall(0, 12, 10);
  auto changes = r.detect({across});
  EXPECT_LE(changes.size(), r.registry.change_capacity());
  EXPECT_EQ(count(changes, msg::PlaneChangeKind::kRemoved), PlaneRegistry::kExtraChangesPerUpdate);
  stream.apply(changes);
  EXPECT_EQ(r.registry.final_planes().size(), kPieces - 1 - PlaneRegistry::kExtraChangesPerUpdate);
  changes = r.detect({across});
  EXPECT_EQ(count(changes, msg::PlaneChangeKind::kRemoved),
            kPieces - 1 - PlaneRegistry::kExtraChangesPerUpdate);
  stream.apply(changes);
  EXPECT_TRUE(r.registry.final_planes().empty());
  ASSERT_EQ(r.registry.live_count(), 1u);
  ASSERT_EQ(stream.planes.size(), 1u) << "one wall, under one id";
  EXPECT_EQ(r.registry.counters().merged, kPieces - 1);
}

TEST(PlaneRegistry, RefusesAnUnusableConfiguration) {
  EXPECT_EQ(validate(PlaneRegistryConfig{}), "");
  PlaneRegistryConfig config;
  config.max_live_planes = 0;
  EXPECT_NE(validate(config), "");
  config = PlaneRegistryConfig{};
  config.retract_after_misses = 0;
  EXPECT_NE(validate(config), "");
  config = PlaneRegistryConfig{};
  config.band_m = 0.5;  // above max_band_m
  EXPECT_NE(validate(config), "");
}

// The rigid path pairs a wall of this pass with an earlier pass's drawing of it where the path
// puts both: the earlier as the stream shows it (the view's move), this one by this pass's
// correction. Drawn, a loop's end lies as far off its start as the lasers drifted round it.
// A level laser's traces, 0.2 m high, pair too.
class TurnedByTwelve final : public PlaneView {
 public:
  [[nodiscard]] PlaneMove move_of(const msg::PlanePatch& /*plane*/,
                                  const SeenSpans& /*seen*/) const noexcept override {
    return kMove;
  }
  static constexpr double kYawRad = 12.0 * std::numbers::pi / 180.0;
  inline static const PlaneMove kMove{kYawRad, Eigen::Vector3d(1.0, -2.0, 0.0)};
};

TEST(RigidPathPairing, AWallIsPairedWithItsEarlierDrawingWhereThePathPutsBoth) {
  Registry r;
  TurnedByTwelve view;
  r.registry.set_view(&view, 0.05);
  static_cast<void>(r.detect({trace({0.0, 10.0}, {20.0, 10.0})}));
  r.registry.begin_update();
  r.registry.finalize_all();
  ASSERT_EQ(r.registry.final_planes().size(), 1u);
  // This pass's frame has drifted: its correction is 6 degrees and a shift, so the same wall
  // is drawn where that correction's inverse takes its place on the path.
  const PlaneMove this_pass{6.0 * std::numbers::pi / 180.0, Eigen::Vector3d(-0.5, 0.7, 0.0)};
  msg::PlanePatch drawn = trace({0.0, 10.0}, {20.0, 10.0}).plane;
  move_plane(drawn, TurnedByTwelve::kMove);
  move_plane(drawn, PlaneMove{-this_pass.yaw_rad, Eigen::Vector3d::Zero()});
  const Eigen::Vector3d unshift =
      Eigen::AngleAxisd(-this_pass.yaw_rad, Eigen::Vector3d::UnitZ()) * -this_pass.shift_m;
  move_plane(drawn, PlaneMove{0.0, unshift});
  const TimestampNs later_ns = 100 * kNanosecondsPerSecond;
  EXPECT_EQ(pipeline::RigidPathSolver::earlier_drawing_of(drawn, this_pass, r.registry, later_ns),
            0u);
  // This pass as drawn lies 6 degrees off the earlier one where the path puts it: no pair.
  EXPECT_EQ(pipeline::RigidPathSolver::earlier_drawing_of(drawn, PlaneMove{}, r.registry, later_ns),
            1u);
  // Nor within this pass's own minute.
  EXPECT_EQ(pipeline::RigidPathSolver::earlier_drawing_of(drawn, this_pass, r.registry,
                                                          5 * kNanosecondsPerSecond),
            1u);
}

}  // namespace
}  // namespace blockmap::map
