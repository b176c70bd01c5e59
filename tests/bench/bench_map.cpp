// The streaming map's per-scan work: projecting a scan of the paper's LMS291 (181 beams at
// 1 deg) and of the largest scanner (1,141 beams) through a rolled mount and a moving pose.
#include <benchmark/benchmark.h>

#include <array>
#include <numbers>

#include "blockmap/map/scan_projector.hpp"

namespace blockmap::map {
namespace {

void BM_ProjectScan(benchmark::State& state) {
  const auto beams = static_cast<std::uint16_t>(state.range(0));
  ScanProjector projector(
      SensorMount{Eigen::Vector3d(0.0, 0.0, 1.1), 0.0, -std::numbers::pi / 2.0, 0.0},
      ScanProjectorConfig{});
  msg::LaserScan scan;
  scan.beam_count = beams;
  scan.start_angle_rad = -std::numbers::pi / 2.0;
  scan.angle_increment_rad = std::numbers::pi / static_cast<double>(beams - 1);
  scan.time_increment_s = 1.0 / 75.0 / 360.0;
  for (std::uint16_t i = 0; i < beams; ++i) {
    scan.ranges_m[i] = 4.0f + 0.02f * static_cast<float>(i % 500);
    scan.status[i] = msg::BeamStatus::kValid;
  }
  std::array<Eigen::Vector3f, msg::kMaxLaserBeams> points{};
  localize::Pose3 first;
  first.pitch_rad = 0.03;
  localize::Pose3 last = first;
  last.stamp_ns = ScanProjector::last_beam_stamp_ns(scan);
  last.x_m = 0.016;
  last.yaw_rad = 0.01;
  for (auto _ : state) {
    benchmark::DoNotOptimize(projector.project(scan, first, last, points));
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * beams);
}
BENCHMARK(BM_ProjectScan)->Arg(181)->Arg(1141);

}  // namespace
}  // namespace blockmap::map
