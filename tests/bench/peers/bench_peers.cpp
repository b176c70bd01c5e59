// blockmap against the plane detectors users would otherwise pick (PCL, CGAL, Open3D), on
// the same simulated city cloud, on one core, each scored against the world's truth faces
// the way blockmap is scored (tests/support/plane_truth.hpp).
//
//   scripts/bench-peers            (installs the peers, builds this, runs it on one core)
//   bench_peers [--world W] [--seconds S] [--only NAMES] [--time-limit S]
//
// The cloud: every return of the simulated run along the true trajectory for S seconds
// (usc_block, 100 s: about a million points). Times are from points in memory to planes,
// normals included where a peer needs them; the conversion of a peer's labels into planes
// for scoring is not timed.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include <unistd.h>

#include "blockmap/core/arena.hpp"
#include "blockmap/hal/config/robot.hpp"
#include "blockmap/hal/sim/truth_cloud.hpp"
#include "blockmap/hal/sim/world.hpp"
#include "blockmap/planes/plane_detector.hpp"
#include "peers.hpp"
#include "plane_truth.hpp"

namespace blockmap::bench {
namespace {

struct Options {
  std::string world = "usc_block";
  double seconds = 100.0;
  std::string only;  // comma-separated peer keys; empty: all
  double time_limit_s = 300.0;
};

Options parse(int argc, char** argv) {
  Options options;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const bool has_value = i + 1 < argc;
    if (arg == "--world" && has_value) {
      options.world = argv[++i];
    } else if (arg == "--seconds" && has_value) {
      options.seconds = std::stod(argv[++i]);
    } else if (arg == "--only" && has_value) {
      options.only = argv[++i];
    } else if (arg == "--time-limit" && has_value) {
      options.time_limit_s = std::stod(argv[++i]);
    } else {
      std::fprintf(stderr,
                   "usage: bench_peers [--world W] [--seconds S] [--only "
                   "blockmap,pcl_ransac,pcl_region,cgal,open3d] [--time-limit S]\n");
      std::exit(2);
    }
  }
  return options;
}

bool wanted(const Options& options, const char* key) {
  return options.only.empty() ||
         ("," + options.only + ",").find("," + std::string(key) + ",") != std::string::npos;
}

PeerRun run_blockmap(std::span<const Eigen::Vector3f> points) {
  planes::PlanesConfig config;
  // Room for the samples of a city drive of a million points or so (benning's first 100 s:
  // 1.12 M points, 208,000 samples); the note says when it was not enough.
  config.max_samples = std::size_t{1} << 19;
  Arena arena(planes::PlaneDetector::arena_budget_bytes(config));
  planes::PlaneDetector detector;
  detector.init(arena, config);
  arena.seal();
  // The median of five runs (the others are not this noisy: seconds, not milliseconds).
  std::vector<double> seconds;
  std::span<const msg::PlanePatch> found;
  for (int run = 0; run < 5; ++run) {
    const Stopwatch watch;
    detector.clear();
    detector.add_points(points);
    found = detector.detect();
    seconds.push_back(watch.seconds());
  }
  std::sort(seconds.begin(), seconds.end());
  std::string note = "median of 5 runs; default [planes] configuration, " +
                     std::to_string(detector.stats().samples) + " samples";
  if (detector.stats().points_dropped > 0 || detector.stats().overflows > 0) {
    note += "; CAPACITY EXCEEDED: " + std::to_string(detector.stats().points_dropped) +
            " points dropped";
  }
  return PeerRun{"blockmap planes", seconds[2], {found.begin(), found.end()}, note};
}

void print_row(const PeerRun& run, const testing::PlaneScore& score, std::size_t points,
               double blockmap_seconds) {
  std::size_t structural = 0;
  for (const msg::PlanePatch& plane : run.planes) {
    structural += testing::structural(plane.kind) ? 1 : 0;
  }
  std::printf(
      "| %s | %.3f s | %.2f M/s | %zu (%zu) | %zu/%zu = %.0f %% | %zu/%zu = %.0f %% | %zu | "
      "%.2f deg | %.3f m | %.0fx | %s |\n",
      run.name.c_str(), run.seconds, static_cast<double>(points) / run.seconds * 1e-6, structural,
      run.planes.size(), score.faces_found, score.faces_considered, 100.0 * score.recall(),
      score.structural_real, score.structural_planes, 100.0 * score.precision(),
      score.faces_reported_twice, score.median_angle_deg, score.median_offset_m,
      run.seconds / blockmap_seconds, run.note.c_str());
  std::fflush(stdout);
}

}  // namespace
}  // namespace blockmap::bench

int main(int argc, char** argv) {
  using namespace blockmap;
  const bench::Options options = bench::parse(argc, argv);
  hal::sim::SimOptions sim;
  sim.seed = 3;
  sim.max_duration_s = options.seconds;
  const hal::sim::TruthCloud cloud = hal::sim::simulate_truth_cloud(
      hal::sim::load_world(options.world), hal::config::load_robot("paper_rmp"), sim);
  const std::span<const Eigen::Vector3f> points(cloud.points_m);
  bench::PeerParameters parameters;
  parameters.time_limit_s = options.time_limit_s;
  std::printf("%s, first %.0f s: %zu points, %zu faces with >= 200 returns\n\n",
              options.world.c_str(), options.seconds, points.size(),
              testing::score_planes(cloud.faces, {}).faces_considered);
  std::printf(
      "| detector | time | points/s | walls/roofs/ground (all) | faces found | real | "
      "twice | median angle | median offset | time / blockmap's | how |\n"
      "|---|---|---|---|---|---|---|---|---|---|---|\n");
  const bench::PeerRun ours = bench::run_blockmap(points);
  const auto report = [&](const bench::PeerRun& run) {
    bench::print_row(run, testing::score_planes(cloud.faces, run.planes), points.size(),
                     ours.seconds);
  };
  report(ours);
  if (bench::wanted(options, "cgal")) {
    report(bench::run_cgal_efficient_ransac(points, parameters));
  }
  if (bench::wanted(options, "pcl_region")) {
    report(bench::run_pcl_region_growing(points, parameters));
  }
  if (bench::wanted(options, "open3d")) {
    const std::filesystem::path scratch =
        std::filesystem::temp_directory_path() / ("blockmap_peers_" + std::to_string(::getpid()));
    report(bench::run_open3d_segment_plane(points, parameters, scratch, BLOCKMAP_OPEN3D_SCRIPT));
    std::filesystem::remove_all(scratch);
  }
  if (bench::wanted(options, "pcl_ransac")) {
    report(bench::run_pcl_ransac(points, parameters));
  }
  return 0;
}
