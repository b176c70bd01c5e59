// The accuracy tables of the docs (docs/benchmarks.md), each a benchmark over the simulation's
// seeds: one case per seed and variant, run once, its figures as counters (the tests assert
// the project's targets on one seed; these say how they spread). Minutes each, so run by name:
//   taskset -c 1 build/release/tests/bench/bench_accuracy --benchmark_filter=BM_ScanMatching
// The runs print their details (missed faces, buildings, paths) as the tests do.
#include <benchmark/benchmark.h>

#include <array>
#include <cstdint>
#include <cstdio>
#include <numbers>
#include <string>
#include <vector>

#include "building_world_runs.hpp"
#include "mapper_runs.hpp"
#include "truth_cloud_runs.hpp"

namespace blockmap {
namespace {

using pipeline::AlignedScore;
using pipeline::BuildingMatch;
using pipeline::MapperRun;
using pipeline::RigidPath;
using pipeline::WorldRun;

constexpr double kDegPerRad = 180.0 / std::numbers::pi;

void set_plane_counters(benchmark::State& state, const testing::PlaneScore& s,
                        const std::string& prefix = "") {
  state.counters[prefix + "faces_found"] = static_cast<double>(s.faces_found);
  state.counters[prefix + "faces"] = static_cast<double>(s.faces_considered);
  state.counters[prefix + "real"] = static_cast<double>(s.structural_real);
  state.counters[prefix + "structural"] = static_cast<double>(s.structural_planes);
  state.counters[prefix + "twice"] = static_cast<double>(s.faces_reported_twice);
}

// The mean IoU and the shapes right of a run's buildings against the world's.
void set_building_counters(benchmark::State& state, const std::vector<BuildingMatch>& matches) {
  double iou_sum = 0.0;
  std::size_t right = 0;
  for (const BuildingMatch& match : matches) {
    iou_sum += match.iou;
    right += match.shape == match.truth_shape ? 1U : 0U;
  }
  state.counters["buildings"] = static_cast<double>(matches.size());
  state.counters["shapes_right"] = static_cast<double>(right);
  state.counters["mean_iou"] =
      matches.empty() ? 0.0 : iou_sum / static_cast<double>(matches.size());
}

std::uint64_t seed_of(const benchmark::State& state) {
  return static_cast<std::uint64_t>(state.range(0));
}

// Benning with the RTK receiver: the default window (0), the far-reaching one (1), and the
// far-reaching one with scans drawn 5 s late (2): docs/mapper.md, Accuracy.
void BM_BenningReach(benchmark::State& state) {
  const map::VoxelWindowConfig window = pipeline::far_reaching_window();
  const auto variant = state.range(1);
  WorldRun run{.world = "benning", .robot = "paper_rmp_rtk", .seed = seed_of(state)};
  if (variant > 0) {
    run.window = &window;
    run.max_range_m = pipeline::kFarReachRangeM;
  }
  if (variant == 2) {
    run.pose_lag_s = 5.0;
  }
  for (auto _ : state) {
    const MapperRun mapped = pipeline::map_world(run);
    set_plane_counters(state, pipeline::score(mapped, "benning, RTK"));
  }
}
BENCHMARK(BM_BenningReach)
    ->ArgsProduct({benchmark::CreateDenseRange(1, 6, 1), {0, 1, 2}})
    ->ArgNames({"seed", "window"})
    ->Iterations(1)
    ->Unit(benchmark::kSecond);

// Benning's buildings with the filter's poses drawn 30 s late: each truth building's best
// fitted footprint as mapped, and after the whole map is laid onto the truth by one turn and
// shift: how much of the loss is where the GPS put the map, and how much its own shape.
void BM_BenningBuildingsLagged(benchmark::State& state) {
  const hal::sim::World world = hal::sim::load_world("benning");
  for (auto _ : state) {
    const MapperRun run =
        pipeline::map_world({.world = "benning", .pose_lag_s = 30.0, .seed = seed_of(state)});
    const testing::MapAlignment alignment =
        testing::align_planes_to_faces(run.faces, run.final_planes);
    double mapped_sum = 0.0;
    double aligned_sum = 0.0;
    std::size_t right = 0;
    for (const hal::sim::Building& truth : world.buildings) {
      double mapped_iou = 0.0;
      double aligned_iou = 0.0;
      std::string mapped_shape;
      for (const buildings::Building& building : run.buildings) {
        std::vector<Eigen::Vector2d> footprint_m(
            building.footprint_m.begin(),
            building.footprint_m.begin() + static_cast<std::ptrdiff_t>(building.footprint_size));
        const double iou = testing::footprint_iou(footprint_m, truth.footprint_m);
        if (iou > mapped_iou) {
          mapped_iou = iou;
          mapped_shape = std::string(buildings::to_string(building.shape));
        }
        for (Eigen::Vector2d& corner_m : footprint_m) {
          corner_m = alignment.apply(Eigen::Vector3d(corner_m.x(), corner_m.y(), 0.0)).head<2>();
        }
        aligned_iou = std::max(aligned_iou, testing::footprint_iou(footprint_m, truth.footprint_m));
      }
      std::printf("seed %lld: truth building %d %s: %s, IoU %.3f; aligned IoU %.3f\n",
                  static_cast<long long>(state.range(0)), truth.id,
                  hal::sim::to_string(truth.shape), mapped_shape.c_str(), mapped_iou, aligned_iou);
      mapped_sum += mapped_iou;
      aligned_sum += aligned_iou;
      right += mapped_shape == hal::sim::to_string(truth.shape) ? 1U : 0U;
    }
    const auto count = static_cast<double>(world.buildings.size());
    state.counters["turn_deg"] = alignment.yaw_rad * kDegPerRad;
    state.counters["shift_m"] = alignment.shift_m.head<2>().norm();
    state.counters["shapes_right"] = static_cast<double>(right);
    state.counters["mean_iou"] = mapped_sum / count;
    state.counters["mean_iou_aligned"] = aligned_sum / count;
  }
}
BENCHMARK(BM_BenningBuildingsLagged)
    ->DenseRange(1, 10, 1)
    ->ArgName("seed")
    ->Iterations(1)
    ->Unit(benchmark::kSecond);

// Benning's buildings with an RTK receiver: the filter's live poses (far 0), and the
// far-reaching window drawn 5 s late (far 1, config/far_reach_rtk.toml).
void BM_BenningBuildingsRtk(benchmark::State& state) {
  const hal::sim::World world = hal::sim::load_world("benning");
  const map::VoxelWindowConfig window = pipeline::far_reaching_window();
  WorldRun run{.world = "benning", .robot = "paper_rmp_rtk", .seed = seed_of(state)};
  if (state.range(1) == 1) {
    run.pose_lag_s = 5.0;
    run.window = &window;
    run.max_range_m = pipeline::kFarReachRangeM;
  }
  for (auto _ : state) {
    const std::vector<BuildingMatch> matches =
        pipeline::building_matches(pipeline::map_world(run), world, "benning, RTK");
    set_building_counters(state, matches);
    std::size_t meeting = 0;
    for (const BuildingMatch& match : matches) {
      meeting += match.iou >= 0.85 ? 1U : 0U;
    }
    state.counters["iou_0.85"] = static_cast<double>(meeting);
  }
}
BENCHMARK(BM_BenningBuildingsRtk)
    ->ArgsProduct({benchmark::CreateDenseRange(1, 10, 1), {0, 1}})
    ->ArgNames({"seed", "far"})
    ->Iterations(1)
    ->Unit(benchmark::kSecond);

// usc_block ten times round with the rigid path: the default 256 ties, which fill in the third
// lap, against room for every tie (docs/localize.md, Ties between passes).
void BM_TenLapsTies(benchmark::State& state) {
  const hal::sim::World truth = hal::sim::load_world("usc_block");
  for (auto _ : state) {
    const MapperRun run =
        pipeline::map_world({.world = "usc_block",
                             .seed = seed_of(state),
                             .rigid_path = RigidPath::kOn,
                             .laps = 10,
                             .max_ties = static_cast<std::size_t>(state.range(1))});
    set_building_counters(state, pipeline::building_matches(run, truth, "usc_block x10"));
    state.counters["ties"] = static_cast<double>(run.ties);
    state.counters["ties_dropped"] = static_cast<double>(run.ties_dropped);
    state.counters["solved_m"] = run.solved_rms_m;
    state.counters["solved_shape_m"] = run.solved_shape_m;
    state.counters["drawn_m"] = run.drawn_rms_m;
    state.counters["drawn_shape_m"] = run.drawn_shape_m;
  }
}
BENCHMARK(BM_TenLapsTies)
    ->ArgsProduct({benchmark::CreateDenseRange(1, 6, 1), {256, 4096}})
    ->ArgNames({"seed", "max_ties"})
    ->Iterations(1)
    ->Unit(benchmark::kSecond);

// The rigid path (docs/localize.md, The whole path at once): benning (drive 0), usc_block
// (1) and usc_block twice round (2) with the filter's live poses and matched scans, the final
// planes as drawn (rigid 0) or moved by the whole run's solved path (1): buildings and path.
void BM_RigidPath(benchmark::State& state) {
  const auto drive = state.range(1);
  const char* world = drive == 0 ? "benning" : "usc_block";
  const hal::sim::World truth = hal::sim::load_world(world);
  for (auto _ : state) {
    const MapperRun run =
        pipeline::map_world({.world = world,
                             .seed = seed_of(state),
                             .rigid_path = state.range(2) == 1 ? RigidPath::kOn : RigidPath::kOff,
                             .laps = drive == 2 ? 2 : 1});
    set_building_counters(state, pipeline::building_matches(run, truth, world));
    state.counters["planes_moved"] = static_cast<double>(run.rigid_path.planes_moved);
    state.counters["solved_m"] = run.solved_rms_m;
    state.counters["solved_shape_m"] = run.solved_shape_m;
    state.counters["drawn_m"] = run.drawn_rms_m;
    state.counters["drawn_shape_m"] = run.drawn_shape_m;
  }
}
BENCHMARK(BM_RigidPath)
    ->ArgsProduct({benchmark::CreateDenseRange(1, 10, 1), {0, 1, 2}, {0, 1}})
    ->ArgNames({"seed", "drive", "rigid"})
    ->Iterations(1)
    ->Unit(benchmark::kSecond);

// Scan matching (docs/localize.md): usc_block (world 0) and benning (1) with the filter's live
// poses, the scans matched (1, the default) or not (0), without the rigid path: the planes
// after the best turn and shift onto the truth, and the buildings.
void BM_ScanMatching(benchmark::State& state) {
  const char* world = state.range(1) == 0 ? "usc_block" : "benning";
  localize::ScanMatchConfig matching;
  matching.enabled = state.range(2) == 1;
  for (auto _ : state) {
    const MapperRun run = pipeline::map_world({.world = world,
                                               .seed = seed_of(state),
                                               .scan_matching = &matching,
                                               .rigid_path = RigidPath::kOff});
    const AlignedScore aligned = pipeline::score_aligned(run, world);
    set_plane_counters(state, aligned.score, "aligned_");
    state.counters["turn_deg"] = aligned.alignment.yaw_rad * kDegPerRad;
    set_building_counters(state,
                          pipeline::building_matches(run, hal::sim::load_world(world), world));
  }
}
BENCHMARK(BM_ScanMatching)
    ->ArgsProduct({benchmark::CreateDenseRange(1, 4, 1), {0, 1}, {0, 1}})
    ->ArgNames({"seed", "world", "matched"})
    ->Iterations(1)
    ->Unit(benchmark::kSecond);

// The batch detector on the truth cloud with the project's pose noise (0.5 deg and 5 cm per
// scan), with the corner look off (0) and on (1): docs/planes.md, Robustness.
void BM_PlanesUnderPoseNoise(benchmark::State& state) {
  const char* world = state.range(1) == 0 ? "benning" : "partial";
  planes::PlanesConfig config = planes::city_config();
  config.corner_look = state.range(2) == 1;
  const hal::sim::PoseNoise noise{0.5 / kDegPerRad, 0.05, 0.0};
  for (auto _ : state) {
    set_plane_counters(state,
                       planes::detect_in_world(world, noise, {}, config, seed_of(state)).score);
  }
}
BENCHMARK(BM_PlanesUnderPoseNoise)
    ->ArgsProduct({benchmark::CreateDenseRange(1, 6, 1), {0, 1}, {0, 1}})
    ->ArgNames({"seed", "world", "corner_look"})
    ->Iterations(1)
    ->Unit(benchmark::kSecond);

// Each world (0 usc_block, 1 benning, 2 partial) under each pose noise (0: 0.5 deg, 5 cm per
// scan; 1 and 2: the same drifting over 1 s and 10 s; 3: 0.25 deg, 2.5 cm per scan; 4: 0.5 deg
// and 5 cm per scan on the world tilted 1 and 3 deg): docs/planes.md's table.
void BM_PlanesNoiseTable(benchmark::State& state) {
  constexpr std::array<const char*, 3> kWorlds{"usc_block", "benning", "partial"};
  const std::array<hal::sim::PoseNoise, 5> noises{{{0.5 / kDegPerRad, 0.05, 0.0},
                                                   {0.5 / kDegPerRad, 0.05, 1.0},
                                                   {0.5 / kDegPerRad, 0.05, 10.0},
                                                   {0.25 / kDegPerRad, 0.025, 0.0},
                                                   {0.5 / kDegPerRad, 0.05, 0.0}}};
  const auto row = static_cast<std::size_t>(state.range(1));
  const planes::WorldTilt tilt = row == 4 ? planes::WorldTilt{1.0, 3.0} : planes::WorldTilt{};
  for (auto _ : state) {
    set_plane_counters(state,
                       planes::detect_in_world(kWorlds[static_cast<std::size_t>(state.range(0))],
                                               noises[row], tilt)
                           .score);
  }
}
BENCHMARK(BM_PlanesNoiseTable)
    ->ArgsProduct({{0, 1, 2}, {0, 1, 2, 3, 4}})
    ->ArgNames({"world", "noise"})
    ->Iterations(1)
    ->Unit(benchmark::kSecond);

// Buildings from the batch detector's planes on the truth cloud (partial: world 0, benning: 1):
// docs/buildings.md. completed: the shape right and IoU >= 0.85 (a rect) or 0.8 (an L or a T).
void BM_BatchBuildings(benchmark::State& state) {
  const char* world = state.range(1) == 0 ? "partial" : "benning";
  for (auto _ : state) {
    const std::vector<buildings::BuildingMatch> matches =
        buildings::fit_world(world, seed_of(state));
    std::size_t right = 0;
    std::size_t completed = 0;
    double iou_sum = 0.0;
    for (const buildings::BuildingMatch& match : matches) {
      right += match.shape == match.truth_shape ? 1U : 0U;
      completed += buildings::completed(match) ? 1U : 0U;
      iou_sum += match.iou;
    }
    state.counters["buildings"] = static_cast<double>(matches.size());
    state.counters["shapes_right"] = static_cast<double>(right);
    state.counters["completed"] = static_cast<double>(completed);
    state.counters["mean_iou"] = iou_sum / static_cast<double>(matches.size());
  }
}
BENCHMARK(BM_BatchBuildings)
    ->ArgsProduct({benchmark::CreateDenseRange(1, 10, 1), {0, 1}})
    ->ArgNames({"seed", "world"})
    ->Iterations(1)
    ->Unit(benchmark::kSecond);

}  // namespace
}  // namespace blockmap
