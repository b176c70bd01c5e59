// Building fitting takes everything at init: fitting a plane list, however many walls and
// buildings it holds, allocates nothing, and a list beyond the capacities is cut and counted.
#include <gtest/gtest.h>

#include <vector>

#include "blockmap/buildings/building_fitter.hpp"
#include "blockmap/core/arena.hpp"
#include "memory_assertions.hpp"
#include "synthetic_walls.hpp"

namespace blockmap::buildings {
namespace {

std::vector<msg::PlanePatch> rectangles(std::size_t count) {
  std::vector<msg::PlanePatch> planes;
  for (std::size_t b = 0; b < count; ++b) {
    const double x = 30.0 * static_cast<double>(b);
    const std::vector<msg::PlanePatch> walls =
        testing::walls_around({{x, 0.0}, {x + 20.0, 0.0}, {x + 20.0, 12.0}, {x, 12.0}}, 8.0, 0.2,
                              static_cast<std::uint32_t>(4 * b + 1));
    planes.insert(planes.end(), walls.begin(), walls.end());
  }
  return planes;
}

TEST(BuildingsBudget, FittingAllocatesNothingAfterInitAndFitsItsBudget) {
  BuildingsConfig config;
  config.max_walls = 64;
  config.max_buildings = 8;
  const std::size_t budget = BuildingFitter::arena_bytes(config);
  Arena arena(budget);
  BuildingFitter fitter;
  fitter.init(arena, config);
  arena.seal();
  EXPECT_LE(arena.used_bytes(), budget);
  EXPECT_LE(fitter.memory_bytes(), arena.used_bytes() + sizeof(BuildingFitter));

  const std::vector<msg::PlanePatch> few = rectangles(5);
  const std::vector<msg::PlanePatch> many = rectangles(30);  // 120 walls, 30 buildings
  std::size_t fitted = 0;
  EXPECT_NO_ALLOCATIONS(fitted = fitter.fit(few).size());
  EXPECT_EQ(fitted, 5u);
  EXPECT_NO_ALLOCATIONS(fitted = fitter.fit(many).size());
  // Over capacity: the first 64 walls (16 buildings) are taken, 8 of them kept; both counted.
  EXPECT_EQ(fitted, 8u);
  EXPECT_EQ(fitter.counters().walls_dropped_full, 56u);
  EXPECT_EQ(fitter.counters().buildings_dropped_full, 8u);
  // Buildings come and go over many fits: the ones absent are remembered (for their ids) in
  // fixed room, still without an allocation.
  EXPECT_NO_ALLOCATIONS({
    for (int round = 0; round < 100; ++round) {
      fitted = fitter.fit(round % 3 == 0 ? many : few).size();
    }
  });
  EXPECT_EQ(arena.failed_allocations().value(), 0u);
}

}  // namespace
}  // namespace blockmap::buildings
