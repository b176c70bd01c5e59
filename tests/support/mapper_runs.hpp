// Simulated runs through the whole mapper, and how their planes, buildings, stream and path
// score against the world's truth: shared by the mapper's world tests (tests/map) and the
// accuracy tables (tests/bench/bench_accuracy.cpp). Checks that can fail in a test's own
// terms are EXPECTs; a run that cannot be made at all throws.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "blockmap/core/arena.hpp"
#include "blockmap/hal/config/robot.hpp"
#include "blockmap/hal/protocol/plane_stream.hpp"
#include "blockmap/hal/sim/simulated_robot.hpp"
#include "blockmap/hal/sim/world.hpp"
#include "blockmap/pipeline/mapper.hpp"
#include "footprint_score.hpp"
#include "plane_truth.hpp"

namespace blockmap::pipeline {

// A run that cannot be made is no result to score.
inline void require(bool holds, const char* what) {
  if (!holds) {
    throw std::runtime_error(std::string("mapper run: ") + what + " failed");
  }
}

#if defined(BLOCKMAP_QUICK_WORLDS)
inline constexpr double kDurationS = 60.0;
#else
inline constexpr double kDurationS = 0.0;  // the whole path
#endif
inline constexpr double kDeterminismDurationS = 8.0;
// The determinism tests' window: 5 tiles of 4 m (8-12 m beyond the robot), so that tiles
// with walls in them leave it within their seconds (with the far ground out of the map, no
// tile leaves the default 7 tiles of 8 m in the quick worlds' 8 s).
inline map::VoxelWindowConfig determinism_window() {
  map::VoxelWindowConfig window;
  window.tile_size_m = 4.0;
  window.tiles_across = 5;
  return window;
}

inline const map::VoxelWindowConfig kDeterminismWindow = determinism_window();

// Appends an update as the binary plane stream encodes it; the bytes written.
inline std::size_t append_encoded(std::vector<std::uint8_t>& stream, const PlaneUpdate& update) {
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
  std::size_t updates_before_end = 0;  // of those, the ones before the end of the input
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
inline void score_rigid_path(const localize::PathSmoother& path,
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

inline MapperRun map_world(const WorldRun& w) {
  const hal::config::RobotSpec robot = hal::config::load_robot(w.robot);
  hal::sim::SimOptions options;
  options.seed = w.seed;
  options.max_duration_s = w.duration_s;
  hal::sim::World loaded = hal::sim::load_world(w.world);
  require(hal::sim::repeat_laps(loaded, w.laps).empty(), "the world repeats its laps");
  auto simulated = std::make_unique<hal::sim::SimulatedRobot>(loaded, robot, options);
  require(simulated->start() == IoStatus::kOk, "the simulated robot starts");
  MapperConfig config = hal::config::mapper_config_for(robot);
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
      require(append_encoded(run.stream, mapper->update()) > 0, "an update encodes");
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
  run.updates_before_end = run.update_changes.size();
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

inline testing::PlaneScore score(const MapperRun& run, const char* label) {
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
  testing::print_missed_faces(run.faces, run.final_planes, s);
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
inline void expect_stream_gives_final_list(const MapperRun& run) {
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

// How far the planes a consumer of the stream holds after its first `updates` updates lie
// from where the final list has them: the mean horizontal distance between centroids, over
// the final planes the stream held by then.
inline double stream_off_final_after_m(const MapperRun& run, std::size_t updates) {
  std::map<std::uint32_t, msg::PlanePatch> held;
  for (std::size_t u = 0; u < std::min(updates, run.update_changes.size()); ++u) {
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

// ... after the first `fraction` of the updates (all but the last at 1).
inline double stream_off_final_m(const MapperRun& run, double fraction) {
  return stream_off_final_after_m(
      run, static_cast<std::size_t>(fraction * static_cast<double>(run.update_changes.size() - 1)));
}

// The planes issue's accuracy (docs/mapper.md, Accuracy), found faces at least `min_recall`
// of them, and a stream that gives the final list.
inline void expect_planes_issue_accuracy(const MapperRun& run, const testing::PlaneScore& s,
                                         double min_recall) {
  EXPECT_GE(s.faces_considered, 3u);
  EXPECT_GE(s.recall(), min_recall);
  EXPECT_GE(s.precision(), 0.95);
  EXPECT_EQ(s.faces_reported_twice, 0u);
  EXPECT_LE(s.median_angle_deg, 0.5);
  EXPECT_LE(s.median_offset_m, 0.03);
  expect_stream_gives_final_list(run);
}

// config/far_reach.toml: a window of 11 tiles (40-48 m from the robot) and ranges to 60 m, in
// the default window's pool. The four tiles beyond the default's 7 x 7 leave early, least
// recently touched first, when the pool runs low (map::VoxelWindowConfig::core_tiles_across).
inline map::VoxelWindowConfig far_reaching_window() {
  map::VoxelWindowConfig window;
  window.tiles_across = 11;
  window.core_tiles_across = 7;
  return window;
}

inline constexpr double kFarReachRangeM = 60.0;  // [projection] max_range_m

// A whole path with true poses through the far-reaching window.
inline MapperRun map_with_far_reach(const char* world) {
  const map::VoxelWindowConfig window = far_reaching_window();
  return map_world({.world = world,
                    .poses = PoseSource::kExternal,
                    .window = &window,
                    .max_range_m = kFarReachRangeM});
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

inline AlignedScore score_aligned(const MapperRun& run, const char* label) {
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

inline std::vector<BuildingMatch> building_matches(const MapperRun& run,
                                                   const hal::sim::World& world,
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

}  // namespace blockmap::pipeline
