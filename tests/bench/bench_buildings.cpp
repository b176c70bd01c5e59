// Building fitting per update (the target: <= 1 ms for a block of ten buildings). The plane list
// is what a mapper's registry holds for a city block: ten buildings (rect, L and T, some sides
// never seen, some walls broken by occlusion), their roofs, the ground, and clutter (cars,
// hedges, posts: small vertical planes the fitter must look at and leave).
#include <benchmark/benchmark.h>

#include <vector>

#include "blockmap/buildings/building_fitter.hpp"
#include "blockmap/core/arena.hpp"
#include "synthetic_walls.hpp"

namespace {

using blockmap::msg::PlanePatch;
using Eigen::Vector2d;

std::vector<PlanePatch> city_block(std::size_t buildings, std::size_t clutter) {
  std::vector<PlanePatch> planes;
  std::uint32_t id = 1;
  for (std::size_t b = 0; b < buildings; ++b) {
    const std::vector<Vector2d>& plan =
        b % 3 == 0 ? blockmap::testing::kRectPlan
                   : (b % 3 == 1 ? blockmap::testing::kLPlan : blockmap::testing::kTPlan);
    const std::size_t row = b / 5;  // two rows of five
    const Vector2d centre(40.0 * static_cast<double>(b % 5), 45.0 * static_cast<double>(row));
    const std::vector<Vector2d> corners =
        blockmap::testing::placed(plan, 7.0 * static_cast<double>(b), centre);
    std::vector<PlanePatch> walls = blockmap::testing::walls_around(corners, 9.0, 0.2, id);
    id += static_cast<std::uint32_t>(walls.size());
    // The back wall never seen; the front broken in two by a tree.
    walls.pop_back();
    const PlanePatch front = walls.front();
    const Vector2d a = front.polygon_m[0].head<2>();
    const Vector2d c = front.polygon_m[1].head<2>();
    walls.front() = blockmap::testing::vertical_plane(a, a + 0.4 * (c - a), 0.0, 9.0, front.id);
    walls.push_back(blockmap::testing::vertical_plane(a + 0.6 * (c - a), c, 0.0, 9.0, id++));
    planes.insert(planes.end(), walls.begin(), walls.end());
    planes.push_back(
        blockmap::testing::flat_roof(centre - Vector2d(5, 3), centre + Vector2d(5, 3), 9.0, id++));
  }
  for (std::size_t k = 0; k < clutter; ++k) {  // cars along the streets
    const std::size_t street = k / 60;         // sixty cars a street
    const Vector2d at(3.0 * static_cast<double>(k % 60),
                      -15.0 + 45.0 * static_cast<double>(street));
    planes.push_back(blockmap::testing::vertical_plane(at, at + Vector2d(4.5, 0.0), 0.0, 1.5, id++,
                                                       blockmap::msg::PlaneKind::kOther));
  }
  return planes;
}

void BM_FitTenBuildings(benchmark::State& state) {
  const std::vector<PlanePatch> planes = city_block(10, static_cast<std::size_t>(state.range(0)));
  blockmap::buildings::BuildingsConfig config;
  blockmap::Arena arena(blockmap::buildings::BuildingFitter::arena_bytes(config));
  blockmap::buildings::BuildingFitter fitter;
  fitter.init(arena, config);
  arena.seal();
  std::size_t fitted = 0;
  for (auto _ : state) {
    fitted = fitter.fit(planes).size();
    benchmark::DoNotOptimize(fitted);
  }
  state.counters["planes"] = static_cast<double>(planes.size());
  state.counters["buildings"] = static_cast<double>(fitted);
}
BENCHMARK(BM_FitTenBuildings)->Arg(0)->Arg(100)->Arg(400)->Unit(benchmark::kMicrosecond);

}  // namespace
