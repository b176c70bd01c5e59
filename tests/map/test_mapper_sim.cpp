// The streaming mapper over the simulated robot: the devices' bytes through the device layer,
// the particle filter or the true poses, the sliding window, the planes and the registry.
// Scored against the world's truth faces, as the planes issue scores the batch detector.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <map>
#include <memory>
#include <numbers>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "blockmap/core/arena.hpp"
#include "blockmap/hal/protocol/plane_stream.hpp"
#include "blockmap/hal/sim/simulated_robot.hpp"
#include "blockmap/hal/sim/world.hpp"
#include "blockmap/pipeline/mapper.hpp"
#include "footprint_score.hpp"
#include "long_test.hpp"
#include "plane_truth.hpp"
#include "recorded_mapper_inputs.hpp"

namespace blockmap::pipeline {
namespace {

#if defined(BLOCKMAP_QUICK_WORLDS)
constexpr double kDurationS = 60.0;
#else
constexpr double kDurationS = 0.0;  // the whole path
#endif
constexpr double kDeterminismDurationS = 8.0;
// The determinism tests' window: 5 tiles of 4 m (8-12 m beyond the robot), so that tiles
// with walls in them leave it within their seconds (with the far ground out of the map, no
// tile leaves the default 7 tiles of 8 m in the quick worlds' 8 s).
map::VoxelWindowConfig determinism_window() {
  map::VoxelWindowConfig window;
  window.tile_size_m = 4.0;
  window.tiles_across = 5;
  return window;
}
const map::VoxelWindowConfig kDeterminismWindow = determinism_window();

// Appends an update as the binary plane stream encodes it; the bytes written.
std::size_t append_encoded(std::vector<std::uint8_t>& stream, const PlaneUpdate& update) {
  const std::size_t at = stream.size();
  stream.resize(at + hal::protocol::plane_stream::record_size(update.changes));
  return hal::protocol::plane_stream::encode_update(update.stamp_ns, update.changes,
                                                    std::span<std::uint8_t>(stream).subspan(at));
}

struct MapperRun {
  std::vector<msg::PlanePatch> final_planes;
  std::vector<buildings::Building> buildings;
  std::vector<hal::sim::TruthFace> faces;
  // The plane list a consumer of the stream holds at the end: every change applied by id.
  std::map<std::uint32_t, msg::PlanePatch> streamed;
  std::map<std::uint32_t, msg::PlaneChangeKind> last_change;
  std::vector<std::vector<msg::PlaneChange>> update_changes;  // every update's, in order
  std::size_t updates = 0;
  bool id_reused = false;            // a change to a plane after it was removed
  std::vector<std::uint8_t> stream;  // every update as the binary plane stream encodes it
  MapperCounters counters;
  pipeline::RigidPathCounters rigid_path;
  map::PlaneRegistryCounters registry;
  std::size_t peak_samples = 0;
  std::uint64_t tiles_evicted = 0;
  std::uint64_t tiles_left_early = 0;     // beyond the window's core, for room
  std::uint64_t points_dropped_full = 0;  // a new voxel and the window's pool full
  std::uint64_t scan_matcher_scans = 0;   // level laser scans given to the scan matcher
  std::uint64_t scan_matched = 0;         // of those, matched
  // With the rigid path: its keyframes' drawn and solved poses against the truth (RMS, and
  // RMS with the mean error taken out), metres.
  double drawn_rms_m = 0.0;
  double solved_rms_m = 0.0;
  double drawn_shape_m = 0.0;
  double solved_shape_m = 0.0;
  std::size_t ties = 0;  // the rigid path's ties between passes
  std::uint64_t ties_dropped = 0;
  std::uint64_t ties_replaced = 0;
};

// The rigid path's keyframes against the truth: the poses the scans were drawn with and the
// solved ones (RMS, and RMS with the mean error taken out), and the matched path laid onto the
// truth by one turn and shift (how rigid the smoother's odometry is).
void score_rigid_path(const localize::PathSmoother& path,
                      const std::vector<localize::Pose2>& truth_path, MapperRun& run) {
  std::vector<Eigen::Vector2d> drawn_errors;
  std::vector<Eigen::Vector2d> solved_errors;
  std::vector<Eigen::Vector2d> odometry_points;
  std::vector<Eigen::Vector2d> truth_points;
  for (std::size_t k = 0; k < path.keyframe_count(); ++k) {
    const localize::Pose2 solved = path.pose(k);
    const auto at =
        std::lower_bound(truth_path.begin(), truth_path.end(), solved.stamp_ns,
                         [](const localize::Pose2& p, TimestampNs t) { return p.stamp_ns < t; });
    if (at == truth_path.end()) {
      continue;
    }
    drawn_errors.emplace_back(path.drawn(k).x_m - at->x_m, path.drawn(k).y_m - at->y_m);
    odometry_points.emplace_back(path.odometry(k).x_m, path.odometry(k).y_m);
    truth_points.emplace_back(at->x_m, at->y_m);
    solved_errors.emplace_back(solved.x_m - at->x_m, solved.y_m - at->y_m);
  }
  const auto rms = [](const std::vector<Eigen::Vector2d>& errors, bool shape) {
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (const Eigen::Vector2d& e : errors) {
      mean += e / static_cast<double>(errors.size());
    }
    double sq = 0.0;
    for (const Eigen::Vector2d& e : errors) {
      sq += (shape ? (e - mean) : e).squaredNorm() / static_cast<double>(errors.size());
    }
    return std::sqrt(sq);
  };
  {
    // The matched path laid onto the truth by one turn and shift (2D Procrustes).
    Eigen::Vector2d mo = Eigen::Vector2d::Zero();
    Eigen::Vector2d mt = Eigen::Vector2d::Zero();
    for (std::size_t i = 0; i < odometry_points.size(); ++i) {
      mo += odometry_points[i] / static_cast<double>(odometry_points.size());
      mt += truth_points[i] / static_cast<double>(truth_points.size());
    }
    double dot = 0.0;
    double cross = 0.0;
    for (std::size_t i = 0; i < odometry_points.size(); ++i) {
      const Eigen::Vector2d a = odometry_points[i] - mo;
      const Eigen::Vector2d b = truth_points[i] - mt;
      dot += a.dot(b);
      cross += a.x() * b.y() - a.y() * b.x();
    }
    const double yaw = std::atan2(cross, dot);
    const Eigen::Rotation2Dd turn(yaw);
    double sq = 0.0;
    for (std::size_t i = 0; i < odometry_points.size(); ++i) {
      sq += (turn * (odometry_points[i] - mo) + mt - truth_points[i]).squaredNorm() /
            static_cast<double>(odometry_points.size());
    }
    std::printf(
        "matched path laid onto the truth: %.2f m RMS (turn %.2f deg); %zu keyframes, "
        "%llu fixes, %llu thinnings; %zu ties between passes (%llu refreshed, %llu dropped, "
        "%llu replaced), %llu conjugate-gradient steps\n",
        std::sqrt(sq), yaw * 180.0 / std::numbers::pi, path.keyframe_count(),
        static_cast<unsigned long long>(path.counters().fixes),
        static_cast<unsigned long long>(path.counters().thinnings), path.tie_count(),
        static_cast<unsigned long long>(path.counters().ties_refreshed),
        static_cast<unsigned long long>(path.counters().ties_dropped),
        static_cast<unsigned long long>(path.counters().ties_replaced),
        static_cast<unsigned long long>(path.counters().cg_steps));
  }
  run.drawn_rms_m = rms(drawn_errors, false);
  run.solved_rms_m = rms(solved_errors, false);
  run.drawn_shape_m = rms(drawn_errors, true);
  run.solved_shape_m = rms(solved_errors, true);
  run.ties = path.tie_count();
  run.ties_dropped = path.counters().ties_dropped;
  run.ties_replaced = path.counters().ties_replaced;
}

// One simulated run through the mapper: which world, robot and poses, and what of the
// mapper's configuration differs from the robot's defaults.
struct WorldRun {
  std::string world;
  PoseSource poses = PoseSource::kLocalizer;
  std::string robot = "paper_rmp";
  double duration_s = kDurationS;
  bool incremental_extraction = true;
  double pose_lag_s = 0.0;
  bool sections_wait = true;
  std::uint64_t seed = 3;
  const localize::ScanMatchConfig* scan_matching = nullptr;
  const map::VoxelWindowConfig* window = nullptr;
  double max_range_m = 0.0;  // 0: the mapper's
  RigidPath rigid_path = RigidPath::kWhereScansAreMatched;
  int laps = 1;
  bool rigid_view = true;
  std::size_t max_final_planes = 0;
  std::optional<std::size_t> max_ties = std::nullopt;
};

MapperRun map_world(const WorldRun& w) {
  const hal::sim::RobotSpec robot = hal::sim::load_robot(w.robot);
  hal::sim::SimOptions options;
  options.seed = w.seed;
  options.max_duration_s = w.duration_s;
  hal::sim::World loaded = hal::sim::load_world(w.world);
  EXPECT_EQ(hal::sim::repeat_laps(loaded, w.laps), "");
  auto simulated = std::make_unique<hal::sim::SimulatedRobot>(loaded, robot, options);
  EXPECT_EQ(simulated->start(), IoStatus::kOk);
  MapperConfig config = hal::sim::mapper_config_for(robot);
  config.pose_source = w.poses;
  config.incremental_extraction = w.incremental_extraction;
  config.localizer.map_pose_lag_s = w.pose_lag_s;
  if (w.scan_matching != nullptr) {
    config.scan_matching = *w.scan_matching;
  }
  if (w.window != nullptr) {
    config.window = *w.window;
  }
  if (w.max_range_m > 0.0) {
    config.projection.max_range_m = w.max_range_m;
  }
  config.rigid_path = w.rigid_path;
  config.rigid_view = w.rigid_view;
  if (w.max_final_planes > 0) {
    config.registry.max_final_planes = w.max_final_planes;
  }
  if (w.max_ties.has_value()) {
    config.path.max_ties = *w.max_ties;
  }
  if (!w.sections_wait) {
    // Every section searched again whenever anything in it changed.
    config.planes.barren_section_growth = 0.0;
    config.planes.settled_section_growth = 0.0;
  }
  Arena arena(Mapper::arena_bytes(config));
  auto mapper = std::make_unique<Mapper>();
  mapper->init(arena, config);
  arena.seal();

  MapperRun run;
  const auto consume = [&] {
    while (mapper->step()) {
      ++run.updates;
      EXPECT_GT(append_encoded(run.stream, mapper->update()), 0u);
      run.update_changes.emplace_back(mapper->update().changes.begin(),
                                      mapper->update().changes.end());
      for (const msg::PlaneChange& change : mapper->update().changes) {
        const auto previous = run.last_change.find(change.plane.id);
        if (previous != run.last_change.end() &&
            previous->second == msg::PlaneChangeKind::kRemoved) {
          run.id_reused = true;
        }
        run.last_change[change.plane.id] = change.change;
        if (change.change == msg::PlaneChangeKind::kRemoved) {
          run.streamed.erase(change.plane.id);
        } else {
          run.streamed[change.plane.id] = change.plane;
        }
      }
    }
  };
  bool more = true;
  std::vector<localize::Pose2> truth_path;
  const bool solved = mapper->rigid_path_on();
  while (more) {
    more = simulated->advance();
    if (solved) {
      hal::sim::SimulatedRobot::TrueState state;
      while (simulated->truth().try_pop(state)) {
        truth_path.push_back({state.stamp_ns, state.state.position_m.x(),
                              state.state.position_m.y(), state.state.yaw_rad});
      }
    }
    simulated->feed(*mapper, w.poses == PoseSource::kExternal);
    consume();
  }
  mapper->end_of_input();
  consume();
  if (solved && !truth_path.empty()) {
    score_rigid_path(mapper->rigid_path(), truth_path, run);
  }
  run.final_planes.assign(mapper->final_planes().begin(), mapper->final_planes().end());
  run.buildings.assign(mapper->buildings().begin(), mapper->buildings().end());
  run.faces = simulated->simulation().scene().faces();
  run.counters = mapper->counters();
  run.rigid_path = mapper->rigid_path_counters();
  run.registry = mapper->registry().counters();
  run.peak_samples = mapper->window().counters().peak_samples;
  run.tiles_evicted = mapper->window().counters().tiles_evicted;
  run.tiles_left_early = mapper->window().counters().tiles_left_early;
  run.points_dropped_full = mapper->window().counters().points_dropped_full;
  run.scan_matcher_scans = mapper->scan_matcher().counters().scans;
  run.scan_matched = mapper->scan_matcher().counters().matched;
  return run;
}

testing::PlaneScore score(const MapperRun& run, const char* label) {
  testing::PlaneScore s = testing::score_planes(run.faces, run.final_planes);
  std::printf(
      "%s: %zu final planes; faces %zu/%zu found, structural %zu/%zu real, %zu twice, median "
      "%.2f deg %.3f m; %llu points, %llu extractions, %zu updates, window peak %zu samples, "
      "%zu blocks\n",
      label, run.final_planes.size(), s.faces_found, s.faces_considered, s.structural_real,
      s.structural_planes, s.faces_reported_twice, s.median_angle_deg, s.median_offset_m,
      static_cast<unsigned long long>(run.counters.points),
      static_cast<unsigned long long>(run.counters.extractions), run.updates, run.peak_samples,
      run.counters.peak_blocks);
  for (const int id : s.missed_faces) {
    for (const hal::sim::TruthFace& face : run.faces) {
      if (face.id != id) {
        continue;
      }
      const msg::PlanePatch* nearest = nullptr;
      testing::FaceMatch nearest_match;
      for (const msg::PlanePatch& plane : run.final_planes) {
        const testing::FaceMatch m = testing::match_face(face, plane, {});
        if (m.angle_deg < 10.0 && (nearest == nullptr || m.offset_m < nearest_match.offset_m)) {
          nearest = &plane;
          nearest_match = m;
        }
      }
      std::printf("  MISSED face %d n (%.2f %.2f %.2f) d %.2f, %llu returns", id, face.normal.x(),
                  face.normal.y(), face.normal.z(), face.d_m,
                  static_cast<unsigned long long>(face.returns));
      if (nearest != nullptr) {
        std::printf("; nearest plane %u %s: %.2f deg, %.3f m, support %.0f\n", nearest->id,
                    std::string(msg::to_string(nearest->kind)).c_str(), nearest_match.angle_deg,
                    nearest_match.offset_m, nearest->support);
      } else {
        std::printf("; no plane within 10 deg\n");
      }
    }
  }
  for (const hal::sim::TruthFace& face : run.faces) {
    std::size_t matches = 0;
    for (const msg::PlanePatch& plane : run.final_planes) {
      matches += testing::structural(plane.kind) && testing::match_face(face, plane, {}).matches;
    }
    if (matches < 2 || face.returns < 200) {
      continue;
    }
    std::printf("  face %d reported %zu times:\n", face.id, matches);
    for (const msg::PlanePatch& plane : run.final_planes) {
      if (testing::structural(plane.kind) && testing::match_face(face, plane, {}).matches) {
        Eigen::AlignedBox3d box;
        for (std::size_t i = 0; i < plane.polygon_size; ++i) {
          box.extend(plane.polygon_m[i]);
        }
        std::printf("    plane %u support %.0f d %.2f box (%.1f %.1f %.1f)-(%.1f %.1f %.1f)\n",
                    plane.id, plane.support, plane.d_m, box.min().x(), box.min().y(), box.min().z(),
                    box.max().x(), box.max().y(), box.max().z());
      }
    }
  }
  return s;
}

// What a consumer of the stream holds at the end (every change applied by id, removed ones
// dropped) is the final plane list, plane for plane.
void expect_stream_gives_final_list(const MapperRun& run) {
  EXPECT_FALSE(run.id_reused) << "a removed plane's id came back";
  ASSERT_EQ(run.streamed.size(), run.final_planes.size());
  for (const msg::PlanePatch& plane : run.final_planes) {
    const auto streamed = run.streamed.find(plane.id);
    ASSERT_NE(streamed, run.streamed.end()) << "plane " << plane.id;
    // Bit for bit, every field.
    const msg::PlanePatch& held = streamed->second;
    EXPECT_EQ(held.kind, plane.kind) << "plane " << plane.id;
    EXPECT_EQ(held.normal, plane.normal) << "plane " << plane.id;
    EXPECT_EQ(held.d_m, plane.d_m) << "plane " << plane.id;
    EXPECT_EQ(held.support, plane.support) << "plane " << plane.id;
    EXPECT_EQ(held.rmse_m, plane.rmse_m) << "plane " << plane.id;
    EXPECT_EQ(held.centroid_m, plane.centroid_m) << "plane " << plane.id;
    ASSERT_EQ(held.polygon_size, plane.polygon_size) << "plane " << plane.id;
    for (std::size_t v = 0; v < plane.polygon_size; ++v) {
      EXPECT_EQ(held.polygon_m[v], plane.polygon_m[v]) << "plane " << plane.id << " vertex " << v;
    }
    const auto last = run.last_change.find(plane.id);
    ASSERT_NE(last, run.last_change.end());
    EXPECT_EQ(last->second, msg::PlaneChangeKind::kFinalized);
  }
}

// How far the planes a consumer of the stream holds after the first `fraction` of the updates
// (all but the last at 1) lie from where the final list has them: the mean horizontal
// distance between centroids, over the final planes the stream held by then.
double stream_off_final_m(const MapperRun& run, double fraction) {
  std::map<std::uint32_t, msg::PlanePatch> held;
  const auto updates =
      static_cast<std::size_t>(fraction * static_cast<double>(run.update_changes.size() - 1));
  for (std::size_t u = 0; u < updates; ++u) {
    for (const msg::PlaneChange& change : run.update_changes[u]) {
      if (change.change == msg::PlaneChangeKind::kRemoved) {
        held.erase(change.plane.id);
      } else {
        held[change.plane.id] = change.plane;
      }
    }
  }
  double sum_m = 0.0;
  std::size_t count = 0;
  for (const msg::PlanePatch& plane : run.final_planes) {
    const auto shown = held.find(plane.id);
    if (shown != held.end()) {
      sum_m += (shown->second.centroid_m - plane.centroid_m).head<2>().norm();
      ++count;
    }
  }
  return count == 0 ? 0.0 : sum_m / static_cast<double>(count);
}

// The planes issue's accuracy (docs/mapper.md, Accuracy), found faces at least `min_recall`
// of them, and a stream that gives the final list.
void expect_planes_issue_accuracy(const MapperRun& run, const testing::PlaneScore& s,
                                  double min_recall) {
  EXPECT_GE(s.faces_considered, 3u);
  EXPECT_GE(s.recall(), min_recall);
  EXPECT_GE(s.precision(), 0.95);
  EXPECT_EQ(s.faces_reported_twice, 0u);
  EXPECT_LE(s.median_angle_deg, 0.5);
  EXPECT_LE(s.median_offset_m, 0.03);
  expect_stream_gives_final_list(run);
}

TEST(MapperSim, UscBlockWithTruePosesFindsTheFaces) {
  BLOCKMAP_LONG_TEST();
  const MapperRun run = map_world({.world = "usc_block", .poses = PoseSource::kExternal});
  expect_planes_issue_accuracy(run, score(run, "usc_block, true poses"), 0.95);
  EXPECT_EQ(run.counters.scans_refused_full, 0u);
  EXPECT_EQ(run.counters.messages_late, 0u);
}

// The same run twice gives the same bytes. And the detector keeps the window's samples, their
// shapes and its sections' results: it takes only the samples that gained points, lets go of
// those whose tile left, and replays every section whose inputs are as they were. What it
// keeps is what it would find again, so with sections searched again at every change
// (barren_section_growth and settled_section_growth 0) the stream is also the same, byte for byte,
// as with every window detected afresh (incremental_extraction off).
TEST(MapperSim, TheSameRunGivesTheSameStreamWithOrWithoutKeptShapes) {
  BLOCKMAP_LONG_TEST();
  const MapperRun a = map_world(
      {.world = "usc_block", .duration_s = kDeterminismDurationS, .window = &kDeterminismWindow});
  const MapperRun b = map_world(
      {.world = "usc_block", .duration_s = kDeterminismDurationS, .window = &kDeterminismWindow});
  ASSERT_EQ(a.stream.size(), b.stream.size());
  EXPECT_GT(a.stream.size(), 0u);
  EXPECT_TRUE(a.stream == b.stream) << "the plane stream's bytes differ";
  EXPECT_GT(a.counters.sections_still_barren, 0u) << "the default lets barren sections wait";
  EXPECT_GT(a.counters.sections_settled, 0u) << "... and sections that gave planes";

  const MapperRun exact = map_world({.world = "usc_block",
                                     .duration_s = kDeterminismDurationS,
                                     .sections_wait = false,
                                     .window = &kDeterminismWindow});
  const MapperRun afresh = map_world({.world = "usc_block",
                                      .duration_s = kDeterminismDurationS,
                                      .incremental_extraction = false,
                                      .window = &kDeterminismWindow});
  EXPECT_EQ(exact.counters.incremental_extractions, exact.counters.extractions - 1)
      << "all but the first";
  EXPECT_GT(exact.tiles_evicted, 0u);
  EXPECT_GT(exact.counters.sections_replayed, exact.counters.sections_searched / 2);
  EXPECT_EQ(exact.counters.sections_still_barren, 0u);
  EXPECT_EQ(exact.counters.sections_settled, 0u);
  EXPECT_EQ(afresh.counters.incremental_extractions, 0u);
  EXPECT_EQ(afresh.counters.sections_replayed, 0u);
  ASSERT_EQ(exact.stream.size(), afresh.stream.size());
  EXPECT_TRUE(exact.stream == afresh.stream) << "the kept shapes changed the stream";
}

// The same messages in the same order give the same stream however they were batched between
// two steps: one message a step (blockmap replay), or whatever arrived since the last step (the
// daemon's pipeline thread, whose batches grow when it falls behind).
TEST(MapperSim, TheSameMessagesBatchedAnyWayGiveTheSameStream) {
  BLOCKMAP_LONG_TEST();
  testing::RecordedMapperInputs inputs("usc_block", kDeterminismDurationS + 10.0);
  ASSERT_TRUE(inputs.started);
  // In time order, as blockmap replay and the daemon's replay source hand them over.
  using Event = testing::RecordedMapperInputs::Event;
  const auto stamp_of = [&](const Event& e) -> TimestampNs {
    switch (e.kind) {
      case Event::kBase:
        return inputs.bases[e.index].first.header.stamp_ns;
      case Event::kFix:
        return inputs.fixes[e.index].first.stamp_ns;
      case Event::kPose:
        return inputs.poses[e.index].stamp_ns;
      case Event::kScan:
        return inputs.scans[e.index].second->header.stamp_ns;
    }
    return 0;
  };
  std::stable_sort(inputs.events.begin(), inputs.events.end(),
                   [&](const Event& a, const Event& b) { return stamp_of(a) < stamp_of(b); });
  // A scan queue of 64 (128 by default): the scans from before the filter's first pose (35
  // here) and those waiting out the reorder window would overflow it if the first ones
  // waited for the first pose to be dropped, and how far would depend on the batches.
  MapperConfig config = inputs.config;
  config.scan_queue_capacity = 64;
  const auto stream_of = [&](std::uint32_t seed) {
    Arena arena(Mapper::arena_bytes(config));
    auto mapper = std::make_unique<Mapper>();
    mapper->init(arena, config);
    std::vector<std::uint8_t> stream;
    const auto drain = [&] {
      while (mapper->step()) {
        static_cast<void>(append_encoded(stream, mapper->update()));
      }
    };
    // Batches of up to 20 messages, 0.1 s (the daemon's batches grow to what its queues from
    // the devices hold, about 0.4 s, which the default queue takes).
    std::mt19937 random(seed);
    std::uniform_int_distribution<int> batch(1, 20);
    int left = seed == 0 ? 1 : batch(random);
    inputs.feed(*mapper, [&](bool) {
      if (--left > 0) {
        return;  // the batch goes on: no step
      }
      left = seed == 0 ? 1 : batch(random);
      drain();
    });
    drain();  // what the end of the input left
    EXPECT_EQ(mapper->counters().scans_refused_full, 0u) << "batches of seed " << seed;
    // The rigid path's view was refreshed: its updates are in the stream compared.
    EXPECT_GT(mapper->registry().counters().view_moved, 0u) << "batches of seed " << seed;
    return stream;
  };
  const std::vector<std::uint8_t> one_by_one = stream_of(0);
  EXPECT_GT(one_by_one.size(), 0u);
  for (std::uint32_t seed = 1; seed <= 6; ++seed) {
    EXPECT_TRUE(stream_of(seed) == one_by_one) << "batches of seed " << seed;
  }
}

// The paper's robot with an RTK receiver (config/robots/paper_rmp_rtk.toml: the same base and
// lasers, fixes of 2 cm that say they are carrier-phase): the particle filter's live poses are
// then centimetres off, and the streamed map meets the planes issue's accuracy against truth
// as with the true poses. What keeps the paper's robot from it is its 2 m receiver, whose
// error averaged over a run no mapper removes (scripts/gps-bound; docs/localize.md, RTK
// receivers).
TEST(MapperSim, UscBlockWithAnRtkReceiverFindsTheFacesWithTheFiltersPoses) {
  BLOCKMAP_LONG_TEST();
  const MapperRun run = map_world({.world = "usc_block", .robot = "paper_rmp_rtk"});
  expect_planes_issue_accuracy(run, score(run, "usc_block, RTK receiver, filter poses"), 0.95);
  EXPECT_EQ(run.counters.fixes_rejected, 0u);
}

TEST(MapperSim, BenningWithAnRtkReceiverScoresAsWithTruePoses) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive benning through the mapper";
#endif
  const MapperRun run = map_world({.world = "benning", .robot = "paper_rmp_rtk"});
  // benning's floor, as with true poses (below): three small walls beyond the window's reach.
  expect_planes_issue_accuracy(run, score(run, "benning, RTK receiver, filter poses"), 0.90);
}

// benning's floor with true poses and the default window, below the planes issue's 95 %:
// three small walls facing east (about 2,000 returns each), seen only from 30-60 m, are not
// found (docs/mapper.md); a window reaching farther finds two of them (below).
TEST(MapperSim, BenningWithTruePoses) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive benning through the mapper";
#endif
  const MapperRun run = map_world({.world = "benning", .poses = PoseSource::kExternal});
  const testing::PlaneScore s = score(run, "benning, true poses");
  EXPECT_GE(s.recall(), 0.90);
  EXPECT_GE(s.precision(), 0.95);
  EXPECT_EQ(s.faces_reported_twice, 0u);
  expect_stream_gives_final_list(run);
  // The compact map: the final list as one binary record against the cloud of every point
  // the mapper took in (three float32 each, as a binary PLY holds them).
  std::vector<msg::PlaneChange> final_list;
  for (const msg::PlanePatch& plane : run.final_planes) {
    final_list.push_back({msg::PlaneChangeKind::kFinalized, plane});
  }
  const std::size_t map_bytes = hal::protocol::plane_stream::record_size(final_list);
  const std::uint64_t cloud_bytes = run.counters.points * 3 * sizeof(float);
  std::printf("benning: final plane list %zu bytes, its cloud %llu bytes: %.0f times smaller\n",
              map_bytes, static_cast<unsigned long long>(cloud_bytes),
              static_cast<double>(cloud_bytes) / static_cast<double>(map_bytes));
  EXPECT_GE(cloud_bytes, std::uint64_t{1000} * map_bytes);
}

// config/far_reach.toml: a window of 11 tiles (40-48 m from the robot) and ranges to 60 m, in
// the default window's pool. The four tiles beyond the default's 7 x 7 leave early, least
// recently touched first, when the pool runs low (map::VoxelWindowConfig::core_tiles_across).
map::VoxelWindowConfig far_reaching_window() {
  map::VoxelWindowConfig window;
  window.tiles_across = 11;
  window.core_tiles_across = 7;
  return window;
}
constexpr double kFarReachRangeM = 60.0;  // [projection] max_range_m

// A whole path with true poses through the far-reaching window.
MapperRun map_with_far_reach(const char* world) {
  const map::VoxelWindowConfig window = far_reaching_window();
  return map_world({.world = world,
                    .poses = PoseSource::kExternal,
                    .window = &window,
                    .max_range_m = kFarReachRangeM});
}

// benning's three small walls facing east are seen only from 30-60 m: the far-reaching window
// finds them, within the default budget (docs/mapper.md, Accuracy).
TEST(MapperSim, BenningWithTruePosesAndAFarReachingWindowMeetsThePlanesIssue) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive benning through the mapper";
#endif
  MapperConfig config = hal::sim::mapper_config_for(hal::sim::load_robot("paper_rmp"));
  config.window = far_reaching_window();
  EXPECT_LE(Mapper::arena_bytes(config), std::size_t{64} << 20);
  const MapperRun run = map_with_far_reach("benning");
  expect_planes_issue_accuracy(run, score(run, "benning, true poses, far-reaching window"), 0.95);
  EXPECT_EQ(run.points_dropped_full, 0u);
}

// usc_block's walls fill more than the pool holds of an 11-tile window: its outer tiles leave
// early and the block's faces are found as with the default window, nothing dropped for room.
TEST(MapperSim, UscBlockWithAFarReachingWindowLetsItsOuterTilesLeaveEarly) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the pool fills over the whole path, which the optimized tree drives (the "
                  "memory tier lets tiles leave early in every tree)";
#endif
  const MapperRun run = map_with_far_reach("usc_block");
  expect_planes_issue_accuracy(run, score(run, "usc_block, true poses, far-reaching window"), 0.95);
  EXPECT_GT(run.tiles_left_early, 0u);
  EXPECT_EQ(run.points_dropped_full, 0u);
}

// config/far_reach_rtk.toml: with an RTK receiver the filter's poses find benning's far walls
// too when the scans are drawn 5 s late, with the smoothed path, whose heading is twice as
// good as the live one (docs/mapper.md, Accuracy; DISABLED_TheTableOfBenningsReachOverSeeds).
TEST(MapperSim, BenningWithAnRtkReceiverAndAFarReachingWindowMeetsThePlanesIssue) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive benning through the mapper";
#endif
  const map::VoxelWindowConfig window = far_reaching_window();
  const MapperRun run = map_world({.world = "benning",
                                   .robot = "paper_rmp_rtk",
                                   .pose_lag_s = 5.0,
                                   .window = &window,
                                   .max_range_m = kFarReachRangeM});
  expect_planes_issue_accuracy(run, score(run, "benning, RTK receiver, far-reaching window"), 0.95);
  EXPECT_EQ(run.points_dropped_full, 0u);
}

// docs/mapper.md's table of benning with the RTK receiver over the simulation's seeds 1-6: the
// default window, the far-reaching one, and the far-reaching one with scans drawn 5 s late.
TEST(MapperSim, DISABLED_TheTableOfBenningsReachOverSeeds) {
  const map::VoxelWindowConfig window = far_reaching_window();
  for (std::uint64_t seed = 1; seed <= 6; ++seed) {
    const std::string label = "seed " + std::to_string(seed);
    score(map_world({.world = "benning", .robot = "paper_rmp_rtk", .seed = seed}),
          (label + ", default window").c_str());
    score(map_world({.world = "benning",
                     .robot = "paper_rmp_rtk",
                     .seed = seed,
                     .window = &window,
                     .max_range_m = kFarReachRangeM}),
          (label + ", far-reaching window").c_str());
    score(map_world({.world = "benning",
                     .robot = "paper_rmp_rtk",
                     .pose_lag_s = 5.0,
                     .seed = seed,
                     .window = &window,
                     .max_range_m = kFarReachRangeM}),
          (label + ", far-reaching window, 5 s late").c_str());
  }
}

// With the particle filter's poses the stream holds together; the accuracy against truth is
// printed, and docs/mapper.md says how far it is from the true poses' and why. Scans drawn
// with the smooth map poses (Localizer::map_pose_at) keep each wall in few pieces: 21
// structural planes for usc_block's five faces, where the estimate's own poses, stepping at
// every fix, gave 52.
// Where the map sits is the GPS's; its shape is the mapper's. Laid onto the truth by the best
// turn about the vertical and shift, the planes are scored again (docs/mapper.md, Accuracy).
struct AlignedScore {
  testing::MapAlignment alignment;
  testing::PlaneScore score;
};

AlignedScore score_aligned(const MapperRun& run, const char* label) {
  AlignedScore out;
  out.alignment = testing::align_planes_to_faces(run.faces, run.final_planes);
  MapperRun aligned = run;
  for (msg::PlanePatch& plane : aligned.final_planes) {
    plane = out.alignment.apply(plane);
  }
  std::printf("%s: turned %.2f deg and shifted (%.2f %.2f %.2f) m onto the truth, %zu pairs\n",
              label, out.alignment.yaw_rad * 180.0 / std::numbers::pi, out.alignment.shift_m.x(),
              out.alignment.shift_m.y(), out.alignment.shift_m.z(), out.alignment.pairs);
  out.score = score(aligned, label);
  return out;
}

// The mapper's buildings against the world's footprints: for each truth building, the
// best-overlapping fitted one.
struct BuildingMatch {
  int truth_id = 0;
  std::string truth_shape;
  std::string shape = "not found";
  double iou = 0.0;
};

std::vector<BuildingMatch> building_matches(const MapperRun& run, const hal::sim::World& world,
                                            const char* label) {
  std::vector<BuildingMatch> matches;
  for (const hal::sim::Building& truth : world.buildings) {
    BuildingMatch match;
    match.truth_id = truth.id;
    match.truth_shape = hal::sim::to_string(truth.shape);
    for (const buildings::Building& building : run.buildings) {
      const double iou = testing::footprint_iou(
          std::span<const Eigen::Vector2d>(building.footprint_m.data(), building.footprint_size),
          truth.footprint_m);
      if (iou > match.iou) {
        match.iou = iou;
        match.shape = std::string(buildings::to_string(building.shape));
      }
    }
    std::printf("%s: truth building %d %s: %s, IoU %.3f\n", label, truth.id,
                match.truth_shape.c_str(), match.shape.c_str(), match.iou);
    matches.push_back(match);
  }
  return matches;
}

// Scans drawn 30 s late, with the smoothed path (LocalizerConfig::map_pose_lag_s): the loop's
// walls keep their directions. Measured on the whole path (filter seed 1): the best turn onto
// the truth is 0.17 deg (5.2 deg drawn live), 10 structural planes (18 live). Where the map
// sits stays the GPS's: 0.3-0.5 m across, 2.3 m in height.
TEST(MapperSim, UscBlockWithLaggedFilterPoses) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive usc_block with the lagged poses";
#endif
  const MapperRun run = map_world({.world = "usc_block", .pose_lag_s = 30.0});
  const testing::PlaneScore s = score(run, "usc_block, lagged filter poses");
  const AlignedScore a = score_aligned(run, "usc_block, lagged filter poses, aligned");
  // Over the filter's seeds 1-4 (2026-11-24): turns of 0.12-0.92 deg (2.4-5.7 deg live), 2-4
  // faces found after the turn, IoU 0.90-0.96. (One seed's 5/5 faces was a lucky draw.)
  EXPECT_LT(std::abs(a.alignment.yaw_rad) * 180.0 / std::numbers::pi, 1.5);
  EXPECT_GE(a.score.faces_found, 2u);
  EXPECT_LE(s.structural_planes, 15u);
  EXPECT_EQ(run.counters.scans_refused_full, 0u);
  EXPECT_LE(run.counters.scans_without_pose, 40u);  // before the first fix, as when live
  EXPECT_GT(run.counters.scans_projected, 20000u);
  expect_stream_gives_final_list(run);
  // The block's building: IoU 0.96 with seed 1 (0.91 drawn live).
  const std::vector<BuildingMatch> matches =
      building_matches(run, hal::sim::load_world("usc_block"), "usc_block, lagged");
  ASSERT_EQ(matches.size(), 1u);
  EXPECT_EQ(matches[0].shape, "rect");
  EXPECT_GE(matches[0].iou, 0.87);
}

// benning's buildings from scans drawn 30 s late (docs/buildings.md): the shapes come right
// where the live poses bent them. Measured on the whole path, seed 3: 6 of 6 shapes right,
// IoU 0.68-0.83, mean 0.76 (2026-11-25, with walls cut at a full front; drawn live: 3 of 6,
// 0.33-0.80, mean 0.65). The issue's 0.85 still waits on the smoothed path's metre of
// absolute error.
TEST(MapperSim, BenningBuildingsWithLaggedFilterPoses) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive benning with the lagged poses";
#endif
  const MapperRun run = map_world({.world = "benning", .pose_lag_s = 30.0});
  std::size_t right_shapes = 0;
  double iou_sum = 0.0;
  const hal::sim::World world = hal::sim::load_world("benning");
  const std::vector<BuildingMatch> matches = building_matches(run, world, "benning, lagged");
  for (const BuildingMatch& match : matches) {
    right_shapes += match.shape == match.truth_shape ? 1U : 0U;
    iou_sum += match.iou;
    EXPECT_GT(match.iou, 0.62) << "truth building " << match.truth_id;
  }
  ASSERT_EQ(matches.size(), 6u);
  EXPECT_GE(right_shapes, 5u);
  EXPECT_GT(iou_sum / static_cast<double>(matches.size()), 0.74);
  EXPECT_EQ(run.counters.scans_refused_full, 0u);
}

// docs/buildings.md's table of benning's buildings with the lagged filter poses over the
// simulation's seeds 1-10 (the receiver's errors differ by seed; about 80 s): for each truth
// building, the best-overlapping fitted footprint as mapped, and again after the whole map is
// laid onto the truth by one turn and shift (align_planes_to_faces, as the planes are scored).
// The second says how much of the loss is where the GPS put the whole map, and how much is the
// map's own shape: buildings drawn at different times moved by different amounts.
TEST(MapperSim, DISABLED_TheTableOfBenningBuildingsOverSeeds) {
  const hal::sim::World world = hal::sim::load_world("benning");
  std::size_t shapes_right = 0;
  std::size_t buildings_scored = 0;
  for (std::uint64_t seed = 1; seed <= 10; ++seed) {
    const MapperRun run = map_world({.world = "benning", .pose_lag_s = 30.0, .seed = seed});
    const testing::MapAlignment alignment =
        testing::align_planes_to_faces(run.faces, run.final_planes);
    std::printf("seed %llu: the map laid onto the truth by %.2f deg and (%.2f %.2f) m, %zu pairs\n",
                static_cast<unsigned long long>(seed), alignment.yaw_rad * 180.0 / std::numbers::pi,
                alignment.shift_m.x(), alignment.shift_m.y(), alignment.pairs);
    for (const hal::sim::Building& truth : world.buildings) {
      BuildingMatch mapped;
      BuildingMatch aligned;
      for (const buildings::Building& building : run.buildings) {
        std::vector<Eigen::Vector2d> footprint_m(
            building.footprint_m.begin(),
            building.footprint_m.begin() + static_cast<std::ptrdiff_t>(building.footprint_size));
        const auto keep_best = [&](BuildingMatch& match) {
          const double iou = testing::footprint_iou(footprint_m, truth.footprint_m);
          if (iou > match.iou) {
            match.iou = iou;
            match.shape = std::string(buildings::to_string(building.shape));
          }
        };
        keep_best(mapped);
        for (Eigen::Vector2d& corner_m : footprint_m) {
          corner_m = alignment.apply(Eigen::Vector3d(corner_m.x(), corner_m.y(), 0.0)).head<2>();
        }
        keep_best(aligned);
      }
      std::printf("  truth building %d %s: %s, IoU %.3f; aligned %s, IoU %.3f\n", truth.id,
                  hal::sim::to_string(truth.shape), mapped.shape.c_str(), mapped.iou,
                  aligned.shape.c_str(), aligned.iou);
      shapes_right += mapped.shape == hal::sim::to_string(truth.shape) ? 1U : 0U;
      ++buildings_scored;
      // 2026-11-25: 0.49-0.92 (the lowest with a shape taken for another).
      EXPECT_GT(mapped.iou, 0.45) << "seed " << seed << ", truth building " << truth.id;
    }
  }
  std::printf("shapes right: %zu of %zu\n", shapes_right, buildings_scored);
  EXPECT_GE(shapes_right, 55u);  // 58 of 60 on 2026-11-25
}

// With an RTK receiver the filter's live poses give benning's buildings as the issue asks of
// fully seen ones (IoU 0.85 with the particle filter's poses): seed 3, 6 of 6 shapes right,
// IoU 0.946-0.992 (docs/buildings.md; over seeds 1-10, 59 of 60, mean 0.966).
TEST(MapperSim, BenningBuildingsWithAnRtkReceiverMeetTheIssue) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive benning through the mapper";
#endif
  const MapperRun run = map_world({.world = "benning", .robot = "paper_rmp_rtk"});
  const hal::sim::World world = hal::sim::load_world("benning");
  const std::vector<BuildingMatch> matches = building_matches(run, world, "benning, RTK");
  ASSERT_EQ(matches.size(), 6u);
  for (const BuildingMatch& match : matches) {
    EXPECT_EQ(match.shape, match.truth_shape) << "truth building " << match.truth_id;
    EXPECT_GE(match.iou, 0.85) << "truth building " << match.truth_id;
  }
}

// docs/buildings.md's table of benning's buildings with an RTK receiver over the simulation's
// seeds 1-10: the filter's live poses (the defaults), and the far-reaching window drawn 5 s
// late (config/far_reach_rtk.toml). Each line: every truth building's best fitted footprint.
TEST(MapperSim, DISABLED_TheTableOfBenningBuildingsWithAnRtkReceiverOverSeeds) {
  const hal::sim::World world = hal::sim::load_world("benning");
  const map::VoxelWindowConfig window = far_reaching_window();
  for (const bool far : {false, true}) {
    std::size_t shapes_right = 0;
    std::size_t meeting_the_issue = 0;
    double iou_sum = 0.0;
    std::size_t scored = 0;
    for (std::uint64_t seed = 1; seed <= 10; ++seed) {
      const MapperRun run =
          far ? map_world({.world = "benning",
                           .robot = "paper_rmp_rtk",
                           .pose_lag_s = 5.0,
                           .seed = seed,
                           .window = &window,
                           .max_range_m = kFarReachRangeM})
              : map_world({.world = "benning", .robot = "paper_rmp_rtk", .seed = seed});
      const std::string label =
          "seed " + std::to_string(seed) + (far ? ", far_reach_rtk" : ", defaults");
      for (const BuildingMatch& match : building_matches(run, world, label.c_str())) {
        shapes_right += match.shape == match.truth_shape ? 1U : 0U;
        meeting_the_issue += match.iou >= 0.85 ? 1U : 0U;
        iou_sum += match.iou;
        ++scored;
      }
    }
    std::printf("%s: shapes right %zu of %zu, IoU >= 0.85 %zu, mean IoU %.3f\n",
                far ? "far_reach_rtk" : "defaults", shapes_right, scored, meeting_the_issue,
                iou_sum / static_cast<double>(scored));
  }
}

// The rigid path (docs/localize.md, The whole path at once): the same benning run with the
// final planes moved by the whole run's solved path (the default; here against the same run
// without it). Seed 1 (2026-12-03): the keyframes' poses 1.96 m RMS off as drawn, 0.99 m as
// solved; the buildings' mean IoU 0.649 -> 0.779, shapes right 5 -> 6 of 6.
TEST(MapperSim, BenningBuildingsWithTheRigidPath) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive benning with the rigid path";
#endif
  const hal::sim::World world = hal::sim::load_world("benning");
  const auto mean_iou = [&](const MapperRun& run, const char* label, std::size_t& right) {
    double sum = 0.0;
    const std::vector<BuildingMatch> matches = building_matches(run, world, label);
    for (const BuildingMatch& match : matches) {
      sum += match.iou;
      right += match.shape == match.truth_shape ? 1U : 0U;
    }
    return sum / static_cast<double>(matches.size());
  };
  const MapperRun live = map_world({.world = "benning", .seed = 1, .rigid_path = RigidPath::kOff});
  const MapperRun rigid = map_world({.world = "benning", .seed = 1, .rigid_path = RigidPath::kOn});
  std::size_t live_right = 0;
  std::size_t rigid_right = 0;
  const double live_iou = mean_iou(live, "benning, live", live_right);
  const double rigid_iou = mean_iou(rigid, "benning, rigid path", rigid_right);
  EXPECT_GT(rigid_iou, live_iou + 0.04);
  EXPECT_GE(rigid_right, live_right);
  // Off the truth by the receiver's error averaged over the run (scripts/gps-bound), its
  // shape the odometry's between fixes: over seeds 1-10 the solved path is 0.44-0.91 of the
  // drawn one and its shape 0.35-0.86 (docs/localize.md; seed 1, 2026-12-05: 0.73 and 0.66).
  EXPECT_LT(rigid.solved_rms_m, 0.8 * rigid.drawn_rms_m);
  EXPECT_LT(rigid.solved_shape_m, 0.75 * rigid.drawn_shape_m);
  EXPECT_GT(rigid.rigid_path.planes_moved, rigid.final_planes.size() / 2);
  EXPECT_EQ(rigid.rigid_path.fixes_dropped, 0u);
  expect_stream_gives_final_list(rigid);
}

// With the rigid path the stream shows each plane where the latest solve puts it, so what a
// consumer holds as the run goes is the final map, not the map drawn with the poses of the
// moment that the end moves by a metre or two; the final list is the same, bit for bit.
// Seed 3 (2026-12-04): the stream before its last update 0.08 m off the final list (1.40 m
// as drawn), three quarters of the way 0.25 m (1.87 m), half way 0.83 m (2.06 m).
TEST(MapperSim, TheStreamShowsTheRigidMapAsTheRunGoes) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive usc_block with the rigid path";
#endif
  const MapperRun shown = map_world({.world = "usc_block", .rigid_path = RigidPath::kOn});
  const MapperRun drawn =
      map_world({.world = "usc_block", .rigid_path = RigidPath::kOn, .rigid_view = false});
  for (const double fraction : {0.5, 0.75, 1.0}) {
    std::printf("after %.0f %% of the updates: %.3f m off the final list as shown, %.3f m drawn\n",
                100.0 * fraction, stream_off_final_m(shown, fraction),
                stream_off_final_m(drawn, fraction));
  }
  std::printf(
      "%zu updates, %zu bytes shown; %zu updates, %zu bytes drawn; %llu planes moved by "
      "the view\n",
      shown.updates, shown.stream.size(), drawn.updates, drawn.stream.size(),
      static_cast<unsigned long long>(shown.registry.view_moved));
  EXPECT_GT(stream_off_final_m(drawn, 1.0), 0.5) << "the end's move is the receiver's error";
  EXPECT_LT(stream_off_final_m(shown, 1.0), 0.25 * stream_off_final_m(drawn, 1.0));
  EXPECT_LT(stream_off_final_m(shown, 0.75), 0.5 * stream_off_final_m(drawn, 0.75));
  EXPECT_GT(shown.registry.view_moved, 0u);
  EXPECT_EQ(drawn.registry.view_moved, 0u);
  expect_stream_gives_final_list(shown);
  expect_stream_gives_final_list(drawn);
  ASSERT_EQ(shown.final_planes.size(), drawn.final_planes.size());
  for (std::size_t i = 0; i < shown.final_planes.size(); ++i) {
    EXPECT_EQ(shown.final_planes[i].id, drawn.final_planes[i].id);
    EXPECT_EQ(shown.final_planes[i].d_m, drawn.final_planes[i].d_m);
    EXPECT_EQ(shown.final_planes[i].centroid_m, drawn.final_planes[i].centroid_m);
  }
}

// A final list too small for the block (8 of its 39 planes): each plane it leaves out, the
// new one or a smaller one it held, the stream reports removed, through the view's refreshes
// and the end's move, so a consumer still holds exactly the final list.
TEST(MapperSim, AFullFinalListKeepsTheStreamAndTheListOneMap) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive usc_block with the rigid path";
#endif
  constexpr std::size_t kFinalPlanes = 8;
  const MapperRun run = map_world(
      {.world = "usc_block", .rigid_path = RigidPath::kOn, .max_final_planes = kFinalPlanes});
  std::printf("%llu final planes dropped for %zu kept; %llu shown again by the view\n",
              static_cast<unsigned long long>(run.registry.final_dropped), run.final_planes.size(),
              static_cast<unsigned long long>(run.registry.view_moved));
  EXPECT_EQ(run.final_planes.size(), kFinalPlanes);
  EXPECT_GT(run.registry.final_dropped, 20u);
  EXPECT_GT(run.registry.view_moved, 0u);
  expect_stream_gives_final_list(run);
  // The biggest planes are the ones kept: the block's four walls among them.
  std::size_t walls = 0;
  for (const msg::PlanePatch& plane : run.final_planes) {
    walls += plane.kind == msg::PlaneKind::kWall && plane.support > 1000.0 ? 1U : 0U;
  }
  EXPECT_GE(walls, 4u);
}

// Twice round usc_block every wall is seen on two laps: the mapper pairs each wall of the
// second lap with its drawing on the first (the same face, overlapping, within 2 m and 5
// degrees), and the ties bend the solved path to one block. Seed 1 (2026-12-04): 34 ties; the
// solved path's shape 0.54 m RMS off the truth, against 0.84 m with max_ties = 0.
TEST(MapperSim, UscBlockTwiceRoundTiesTheWallsOfOneLapToTheOther) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive usc_block twice round";
#endif
  const MapperRun run =
      map_world({.world = "usc_block", .seed = 1, .rigid_path = RigidPath::kOn, .laps = 2});
  std::printf("%zu ties, %llu dropped; solved path %.2f m RMS, shape %.2f m\n", run.ties,
              static_cast<unsigned long long>(run.ties_dropped), run.solved_rms_m,
              run.solved_shape_m);
  EXPECT_GE(run.ties, 10u);
  EXPECT_EQ(run.ties_dropped, 0u);
  EXPECT_LT(run.solved_shape_m, 0.7);
  expect_stream_gives_final_list(run);
}

// docs/localize.md's ties over ten laps (The whole path at once): usc_block ten times round,
// where the default 256 ties fill in the third lap, against room for every tie.
TEST(MapperSim, DISABLED_TenLapsKeepTheirTiesSpreadOverTheRun) {
  const hal::sim::World truth = hal::sim::load_world("usc_block");
  for (std::uint64_t seed = 1; seed <= 6; ++seed) {
    for (const std::size_t max_ties : {std::size_t{256}, std::size_t{4096}}) {
      const MapperRun run = map_world({.world = "usc_block",
                                       .seed = seed,
                                       .rigid_path = RigidPath::kOn,
                                       .laps = 10,
                                       .max_ties = max_ties});
      const std::string label =
          "seed " + std::to_string(seed) + ", max_ties " + std::to_string(max_ties);
      double iou_sum = 0.0;
      const std::vector<BuildingMatch> matches = building_matches(run, truth, label.c_str());
      for (const BuildingMatch& match : matches) {
        iou_sum += match.iou;
      }
      std::printf(
          "%s: %zu ties (%llu dropped, %llu replaced); solved path %.2f m RMS, shape %.2f m; "
          "drawn %.2f m, shape %.2f m; mean IoU %.3f\n",
          label.c_str(), run.ties, static_cast<unsigned long long>(run.ties_dropped),
          static_cast<unsigned long long>(run.ties_replaced), run.solved_rms_m, run.solved_shape_m,
          run.drawn_rms_m, run.drawn_shape_m, iou_sum / static_cast<double>(matches.size()));
      expect_stream_gives_final_list(run);
    }
  }
}

// docs/localize.md's table of the rigid path (The whole path at once): benning and usc_block
// with the filter's live poses and matched scans over the simulation's seeds, without and with
// the final planes moved by the whole run's solved path: the buildings against truth.
// Then usc_block twice round, where the ties between passes have walls to tie.
TEST(MapperSim, DISABLED_TheTableOfTheRigidPathOverSeeds) {
  struct Drive {
    const char* world;
    int laps;
  };
  for (const Drive drive : {Drive{"benning", 1}, Drive{"usc_block", 1}, Drive{"usc_block", 2}}) {
    const char* world = drive.world;
    const hal::sim::World truth = hal::sim::load_world(world);
    double sums[2] = {0.0, 0.0};
    std::size_t right[2] = {0, 0};
    std::size_t scored[2] = {0, 0};
    for (std::uint64_t seed = 1; seed <= 10; ++seed) {
      for (const bool rigid : {false, true}) {
        const MapperRun run = map_world({.world = world,
                                         .seed = seed,
                                         .rigid_path = rigid ? RigidPath::kOn : RigidPath::kOff,
                                         .laps = drive.laps});
        const std::string label = std::string(world) + " x" + std::to_string(drive.laps) +
                                  (rigid ? ", rigid" : ", live") + ", seed " + std::to_string(seed);
        double iou_sum = 0.0;
        std::size_t shapes = 0;
        const std::vector<BuildingMatch> matches = building_matches(run, truth, label.c_str());
        for (const BuildingMatch& match : matches) {
          iou_sum += match.iou;
          shapes += match.shape == match.truth_shape ? 1U : 0U;
        }
        std::printf(
            "%s: mean IoU %.3f, %zu of %zu shapes right, %llu planes moved; path drawn "
            "%.2f m (shape %.2f), solved %.2f m (shape %.2f)\n",
            label.c_str(), iou_sum / static_cast<double>(matches.size()), shapes, matches.size(),
            static_cast<unsigned long long>(run.rigid_path.planes_moved), run.drawn_rms_m,
            run.drawn_shape_m, run.solved_rms_m, run.solved_shape_m);
        sums[rigid ? 1 : 0] += iou_sum;
        right[rigid ? 1 : 0] += shapes;
        scored[rigid ? 1 : 0] += matches.size();
        expect_stream_gives_final_list(run);
      }
    }
    std::printf("%s x%d over seeds: live mean IoU %.3f, %zu of %zu shapes; rigid %.3f, %zu\n",
                world, drive.laps, sums[0] / static_cast<double>(scored[0]), right[0], scored[0],
                sums[1] / static_cast<double>(scored[1]), right[1]);
  }
}

TEST(MapperSim, UscBlockWithFilterPoses) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive usc_block with the filter's poses";
#endif
  const MapperRun run = map_world({.world = "usc_block"});
  const testing::PlaneScore s = score(run, "usc_block, filter poses");
  EXPECT_LE(s.structural_planes, 30u);
  const AlignedScore a = score_aligned(run, "usc_block, filter poses, aligned");
  EXPECT_GE(a.alignment.pairs, 3u);  // 3-5 pairs over the filter's seeds 1-4
  EXPECT_LT(a.alignment.shift_m.norm(), 5.0) << "a GPS-grade map is metres off at most";
  EXPECT_GE(a.score.structural_real, s.structural_real) << "aligned, no fewer planes lie on faces";
  expect_stream_gives_final_list(run);
  EXPECT_GT(run.counters.scans_projected, 20000u);
  // The level laser's scans matched (localize::ScanMatcher, on by default): the loop's walls
  // hold their directions. Seed 3 (2026-12-01): the best turn onto the truth 2.3 deg (5.2
  // unmatched), the block's rectangle IoU 0.927 (0.891); over seeds 1-4, 0.85-0.95 against
  // 0.81-0.91 (docs/localize.md, Scan matching).
  EXPECT_GT(run.scan_matched, run.scan_matcher_scans * 8 / 10);
  EXPECT_LT(std::abs(a.alignment.yaw_rad) * 180.0 / std::numbers::pi, 3.5);
  const std::vector<BuildingMatch> matches =
      building_matches(run, hal::sim::load_world("usc_block"), "usc_block, filter poses");
  ASSERT_EQ(matches.size(), 1u);
  EXPECT_EQ(matches[0].shape, "rect");
  EXPECT_GE(matches[0].iou, 0.91);
}

// docs/localize.md's table of scan matching (Scan matching): usc_block and benning drawn with
// the filter's live poses over the simulation's seeds 1-4, with the scans matched (the
// default) and without: the planes against truth as mapped and after the best turn and shift,
// and the buildings. About two minutes.
TEST(MapperSim, DISABLED_TheTableOfScanMatchingOverSeeds) {
  localize::ScanMatchConfig off;
  off.enabled = false;
  const localize::ScanMatchConfig on;
  for (std::uint64_t seed = 1; seed <= 4; ++seed) {
    for (const char* world : {"usc_block", "benning"}) {
      for (const bool matching : {false, true}) {
        const MapperRun run = map_world({.world = world,
                                         .seed = seed,
                                         .scan_matching = matching ? &on : &off,
                                         .rigid_path = RigidPath::kOff});
        const std::string label = std::string(world) + (matching ? ", matched" : ", unmatched") +
                                  ", seed " + std::to_string(seed);
        const AlignedScore aligned = score_aligned(run, label.c_str());
        double iou_sum = 0.0;
        std::size_t right = 0;
        const std::vector<BuildingMatch> matches =
            building_matches(run, hal::sim::load_world(world), label.c_str());
        for (const BuildingMatch& match : matches) {
          iou_sum += match.iou;
          right += match.shape == match.truth_shape ? 1U : 0U;
        }
        std::printf("TABLE | %s | %llu | %s | %.2f deg | %zu/%zu | %zu/%zu | %zu of %zu | %.3f |\n",
                    world, static_cast<unsigned long long>(seed),
                    matching ? "matched" : "unmatched",
                    aligned.alignment.yaw_rad * 180.0 / std::numbers::pi, aligned.score.faces_found,
                    aligned.score.faces_considered, aligned.score.structural_real,
                    aligned.score.structural_planes, right, matches.size(),
                    iou_sum / static_cast<double>(matches.size()));
      }
    }
  }
}

}  // namespace
}  // namespace blockmap::pipeline
