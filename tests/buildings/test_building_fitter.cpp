// The building fitter on plane lists made by hand: which model it picks, the footprint it
// draws, and which walls it marks virtual (seed, section IV).
#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

#include "blockmap/buildings/building_fitter.hpp"
#include "blockmap/core/arena.hpp"
#include "blockmap/planes/polygon.hpp"
#include "footprint_score.hpp"
#include "synthetic_walls.hpp"

namespace blockmap::buildings {
namespace {

using Eigen::Vector2d;
using testing::kLPlan;
using testing::kRectPlan;
using testing::kTPlan;
using testing::placed;
using testing::vertical_plane;

// The walls of `plan` whose index is in `seen` (the rest were never seen).
std::vector<msg::PlanePatch> seen_walls(const std::vector<Vector2d>& plan,
                                        const std::vector<std::size_t>& seen,
                                        double height_m = 9.0) {
  const std::vector<msg::PlanePatch> all = testing::walls_around(plan, height_m);
  std::vector<msg::PlanePatch> planes;
  planes.reserve(seen.size());
  for (const std::size_t k : seen) {
    planes.push_back(all[k]);
  }
  return planes;
}

class BuildingFitterTest : public ::testing::Test {
 protected:
  void SetUp() override {
    fitter_.init(arena_, config_);
    arena_.seal();
  }

  std::span<const Building> fit(const std::vector<msg::PlanePatch>& planes) {
    return fitter_.fit(planes);
  }

  static std::span<const Vector2d> footprint(const Building& building) {
    return {building.footprint_m.data(), building.footprint_size};
  }

  static std::size_t virtual_walls(const Building& building) {
    std::size_t count = 0;
    for (std::size_t w = 0; w < building.wall_count; ++w) {
      count += building.walls[w].is_virtual ? 1U : 0U;
    }
    return count;
  }

  BuildingsConfig config_;
  Arena arena_{BuildingFitter::arena_bytes(BuildingsConfig{})};
  BuildingFitter fitter_;
};

TEST_F(BuildingFitterTest, FourWallsMakeTheirRectangle) {
  const std::vector<Vector2d> plan = placed(kRectPlan, 30.0, {40.0, -25.0});
  const auto buildings = fit(seen_walls(plan, {0, 1, 2, 3}));
  ASSERT_EQ(buildings.size(), 1u);
  EXPECT_EQ(buildings[0].shape, BuildingShape::kRect);
  EXPECT_GT(testing::footprint_iou(footprint(buildings[0]), plan), 0.98);
  EXPECT_EQ(virtual_walls(buildings[0]), 0u);  // the corners' 0.4 m gaps are closed
  EXPECT_GT(buildings[0].confidence, 0.99);
  EXPECT_NEAR(buildings[0].height_m, 9.0, 1e-9);
  EXPECT_FALSE(buildings[0].height_from_roof);
}

// The paper's figure 3d: two walls of a rectangular building, the other two estimated.
TEST_F(BuildingFitterTest, TwoWallsAtACornerMakeARectangleWithTwoVirtualWalls) {
  const std::vector<Vector2d> plan = placed(kRectPlan, -70.0, {5.0, 5.0});
  const auto buildings = fit(seen_walls(plan, {0, 1}));
  ASSERT_EQ(buildings.size(), 1u);
  const Building& building = buildings[0];
  EXPECT_EQ(building.shape, BuildingShape::kRect);
  EXPECT_GT(testing::footprint_iou(footprint(building), plan), 0.97);
  EXPECT_EQ(virtual_walls(building), 2u);
  EXPECT_NEAR(building.confidence, 0.5, 0.03);
  for (std::size_t w = 0; w < building.wall_count; ++w) {
    const BuildingWall& wall = building.walls[w];
    EXPECT_EQ(wall.plane_id == 0, wall.is_virtual);
    EXPECT_NEAR(wall.z1_m - wall.z0_m, 9.0, 1e-9);  // virtual walls as tall as the seen ones
  }
}

TEST_F(BuildingFitterTest, AWallStoppingShortOfTheCornerMakesAnL) {
  // Seen from the front: the front, the west side whole, the east side up to the notch.
  const std::vector<Vector2d> plan = placed(kLPlan, 12.0, {-30.0, 60.0});
  const auto buildings = fit(seen_walls(plan, {0, 1, 5}));
  ASSERT_EQ(buildings.size(), 1u);
  EXPECT_EQ(buildings[0].shape, BuildingShape::kL);
  // The back wall was never seen: the notch's length comes from symmetry (half the length,
  // against the truth's 8 of 20 m).
  EXPECT_GT(testing::footprint_iou(footprint(buildings[0]), plan), 0.9);
  EXPECT_EQ(buildings[0].footprint_size, 6u);
}

TEST_F(BuildingFitterTest, NotchWallsMakeAnLExactly) {
  const std::vector<Vector2d> plan = placed(kLPlan, 0.0, {0.0, 0.0});
  const auto buildings = fit(seen_walls(plan, {0, 1, 2, 3}));
  ASSERT_EQ(buildings.size(), 1u);
  EXPECT_EQ(buildings[0].shape, BuildingShape::kL);
  // The unseen back and west sides end where the seen walls' extents end, 0.2 m short.
  EXPECT_GT(testing::footprint_iou(footprint(buildings[0]), plan), 0.97);
}

TEST_F(BuildingFitterTest, StemAndBarWallsMakeAT) {
  // Everything but the bar's back.
  const std::vector<Vector2d> plan = placed(kTPlan, 200.0, {100.0, 10.0});
  const auto buildings = fit(seen_walls(plan, {0, 1, 2, 3, 5, 6, 7}));
  ASSERT_EQ(buildings.size(), 1u);
  EXPECT_EQ(buildings[0].shape, BuildingShape::kT);
  EXPECT_GT(testing::footprint_iou(footprint(buildings[0]), plan), 0.97);  // the back 0.2 m short
  EXPECT_EQ(virtual_walls(buildings[0]), 1u);
}

TEST_F(BuildingFitterTest, ARectangleSeenWholeStaysARectangleEvenWithGaps) {
  // A tree hides 3 m of the front, a car 2 m of the side: short virtual walls close the gaps.
  const std::vector<Vector2d> plan = kRectPlan;
  std::vector<msg::PlanePatch> planes = seen_walls(plan, {1, 2, 3});
  planes.push_back(vertical_plane({-9.8, -6.0}, {-1.5, -6.0}, 0.0, 9.0, 10));
  planes.push_back(vertical_plane({1.5, -6.0}, {9.8, -6.0}, 0.0, 9.0, 11));
  const auto buildings = fit(planes);
  ASSERT_EQ(buildings.size(), 1u);
  const Building& building = buildings[0];
  EXPECT_EQ(building.shape, BuildingShape::kRect);
  EXPECT_EQ(virtual_walls(building), 1u);
  for (std::size_t w = 0; w < building.wall_count; ++w) {
    if (building.walls[w].is_virtual) {
      EXPECT_NEAR((building.walls[w].p1_m - building.walls[w].p0_m).norm(), 3.0, 1e-6);
    }
  }
  EXPECT_GT(testing::footprint_iou(footprint(building), plan), 0.98);
}

// With the filter's poses a wall's plane took in a tree's canopy or a parked car standing in
// line with it, 3-5 m past the building's corner (benning, seeds 4 and 6): the rectangle came
// out an L. The front and back span the building, so nothing of it lies beyond them.
TEST_F(BuildingFitterTest, AWallRunningOnPastAFullFrontLeavesARectangle) {
  const std::vector<Vector2d> plan = kRectPlan;
  std::vector<msg::PlanePatch> planes = seen_walls(plan, {0, 1, 2});
  planes.push_back(vertical_plane({-10.0, 6.0}, {-10.0, -11.0}, 0.0, 9.0, 10));  // 5 m past
  const auto buildings = fit(planes);
  ASSERT_EQ(buildings.size(), 1u);
  const Building& building = buildings[0];
  EXPECT_EQ(building.shape, BuildingShape::kRect);
  EXPECT_GT(testing::footprint_iou(footprint(building), plan), 0.98);
  for (std::size_t w = 0; w < building.wall_count; ++w) {
    EXPECT_GT(std::min(building.walls[w].p0_m.y(), building.walls[w].p1_m.y()), -6.5)
        << "wall " << w << " runs on past the front";
  }
}

// An L spans its box across only with its outer walls, one each way: the building is on the
// side that holds its other walls. Here a car parked in line with the front runs it 5 m past
// the west wall (benning seed 1: the L at (70, 40) came out a T).
TEST_F(BuildingFitterTest, AFrontRunningOnPastAnLsOuterWallLeavesTheL) {
  const std::vector<Vector2d> plan = placed(kLPlan, 0.0, {0.0, 0.0});
  std::vector<msg::PlanePatch> planes = seen_walls(plan, {1, 2, 3, 4, 5});
  planes.push_back(vertical_plane({-15.0, -7.0}, {10.0, -7.0}, 0.0, 9.0, 10));
  const auto buildings = fit(planes);
  ASSERT_EQ(buildings.size(), 1u);
  EXPECT_EQ(buildings[0].shape, BuildingShape::kL);
  EXPECT_GT(testing::footprint_iou(footprint(buildings[0]), plan), 0.97);
}

// A car parked against a building's outer wall, its two faces low planes joined to the
// building's walls (benning seed 3: a car beyond the L at (70, 40) made a bump of its
// footprint). Nothing of a building lies beyond a wall that spans it.
TEST_F(BuildingFitterTest, ACarBeyondAnOuterWallIsNoPartOfTheBuilding) {
  const std::vector<Vector2d> plan = kRectPlan;
  std::vector<msg::PlanePatch> planes = seen_walls(plan, {0, 1, 2, 3});
  planes.push_back(vertical_plane({11.0, 3.5}, {15.0, 3.5}, 0.0, 1.6, 20, msg::PlaneKind::kOther));
  planes.push_back(vertical_plane({15.0, 3.5}, {15.0, 5.3}, 0.0, 1.6, 21, msg::PlaneKind::kOther));
  const auto buildings = fit(planes);
  ASSERT_EQ(buildings.size(), 1u);
  EXPECT_EQ(buildings[0].shape, BuildingShape::kRect);
  EXPECT_GT(testing::footprint_iou(footprint(buildings[0]), plan), 0.98);
}

// Two passes of the west wall a little more than parallel_merge_offset_m apart both span the
// building; its front and back run on past both, and are not cut to the gap between them.
TEST_F(BuildingFitterTest, TwoPassesOfOneWallDoNotCutTheBuildingToTheirGap) {
  const std::vector<Vector2d> plan = kRectPlan;
  std::vector<msg::PlanePatch> planes = seen_walls(plan, {0, 1, 2, 3});
  planes.push_back(vertical_plane({-7.8, 6.0}, {-7.8, -6.0}, 0.0, 9.0, 10));
  const auto buildings = fit(planes);
  ASSERT_EQ(buildings.size(), 1u);
  EXPECT_EQ(buildings[0].shape, BuildingShape::kRect);
  EXPECT_GT(testing::footprint_iou(footprint(buildings[0]), plan), 0.98);
}

TEST_F(BuildingFitterTest, TheRoofGivesTheHeight) {
  std::vector<msg::PlanePatch> planes = seen_walls(kRectPlan, {0, 1}, 2.5);  // seen low, from afar
  planes.push_back(testing::flat_roof({-9.0, -5.0}, {9.0, 5.0}, 11.0, 20));
  planes.push_back(testing::flat_roof({30.0, 30.0}, {40.0, 40.0}, 30.0, 21));  // elsewhere
  const auto buildings = fit(planes);
  ASSERT_EQ(buildings.size(), 1u);
  EXPECT_TRUE(buildings[0].height_from_roof);
  EXPECT_NEAR(buildings[0].height_m, 11.0, 1e-9);
}

TEST_F(BuildingFitterTest, BuildingsApartAreApartAndAWallAloneIsNone) {
  std::vector<msg::PlanePatch> planes = seen_walls(kRectPlan, {0, 1});
  for (const msg::PlanePatch& plane : seen_walls(placed(kTPlan, 0.0, {60.0, 0.0}), {0, 1, 2, 3})) {
    planes.push_back(plane);
    planes.back().id += 100;
  }
  planes.push_back(vertical_plane({0.0, 40.0}, {30.0, 40.0}, 0.0, 6.0, 300));  // a lone wall
  // Low planes (a parked car, a fence) make no building on their own.
  planes.push_back(
      vertical_plane({0.0, -30.0}, {4.5, -30.0}, 0.0, 1.5, 301, msg::PlaneKind::kOther));
  planes.push_back(
      vertical_plane({4.5, -30.0}, {4.5, -28.0}, 0.0, 1.5, 302, msg::PlaneKind::kOther));
  const auto buildings = fit(planes);
  ASSERT_EQ(buildings.size(), 2u);
  EXPECT_EQ(buildings[0].id, 1u);
  EXPECT_EQ(buildings[1].id, 2u);
  EXPECT_EQ(buildings[0].shape, BuildingShape::kRect);
  EXPECT_NE(buildings[1].shape, BuildingShape::kUnknown);
}

TEST_F(BuildingFitterTest, ABuildingKeepsItsIdFromFitToFit) {
  // Fit 1: a rectangle seen from two sides (ids 1-2) and an L seen whole (ids 11-16).
  std::vector<msg::PlanePatch> rect = seen_walls(kRectPlan, {0, 1});
  std::vector<msg::PlanePatch> l_walls = seen_walls(placed(kLPlan, 0.0, {60.0, 0.0}), {0, 1, 2});
  for (msg::PlanePatch& plane : l_walls) {
    plane.id += 10;
  }
  std::vector<msg::PlanePatch> planes = rect;
  planes.insert(planes.end(), l_walls.begin(), l_walls.end());
  auto buildings = fit(planes);
  ASSERT_EQ(buildings.size(), 2u);
  EXPECT_EQ(buildings[0].id, 1u);
  EXPECT_EQ(buildings[1].id, 2u);

  // Fit 2: a new building's walls come first in the list, and the rectangle gains a wall: the
  // order of the buildings changes, their ids do not, and the new one gets the next id.
  planes = seen_walls(placed(kRectPlan, 0.0, {0.0, 80.0}), {0, 1});
  for (msg::PlanePatch& plane : planes) {
    plane.id += 20;
  }
  std::vector<msg::PlanePatch> more_rect = seen_walls(kRectPlan, {0, 1, 2});
  planes.insert(planes.end(), more_rect.begin(), more_rect.end());
  planes.insert(planes.end(), l_walls.begin(), l_walls.end());
  buildings = fit(planes);
  ASSERT_EQ(buildings.size(), 3u);
  EXPECT_EQ(buildings[0].id, 3u);  // new
  EXPECT_EQ(buildings[1].id, 1u);  // the rectangle
  EXPECT_EQ(buildings[2].id, 2u);  // the L

  // Fit 3: the L's walls under new plane ids (a registry that replaced them) keep the L's id
  // through its place; the rectangle gone, its id is not given to anyone else.
  for (msg::PlanePatch& plane : l_walls) {
    plane.id += 100;
  }
  planes = l_walls;
  std::vector<msg::PlanePatch> elsewhere = seen_walls(placed(kRectPlan, 0.0, {-80.0, 0.0}), {0, 1});
  for (msg::PlanePatch& plane : elsewhere) {
    plane.id += 40;
  }
  planes.insert(planes.end(), elsewhere.begin(), elsewhere.end());
  buildings = fit(planes);
  ASSERT_EQ(buildings.size(), 2u);
  EXPECT_EQ(buildings[0].id, 2u);
  EXPECT_EQ(buildings[1].id, 4u);
}

TEST_F(BuildingFitterTest, AShortWallAcrossAWallMakesNoFlatBuilding) {
  // The real UAL loop made this: a wall and a 2.1 m piece crossing it near one end. Both box
  // sides across the short piece were within the tolerance of the one wall, and snapping both
  // to it drew a footprint of no width (GDAL: "too few points"). One wall is one side; a
  // footprint thinner than a wall is no building.
  std::vector<msg::PlanePatch> planes;
  planes.push_back(vertical_plane({0.0, 0.0}, {0.0, 12.0}, 0.0, 6.0, 1));
  planes.push_back(vertical_plane({-1.2, 11.0}, {0.9, 11.0}, 0.0, 6.0, 2));
  EXPECT_TRUE(fit(planes).empty());
  // The same with the crossing piece long enough to be a side: a building with width.
  planes[1] = vertical_plane({-1.2, 11.0}, {4.0, 11.0}, 0.0, 6.0, 2);
  const auto buildings = fit(planes);
  ASSERT_EQ(buildings.size(), 1u);
  ASSERT_EQ(buildings[0].footprint_size, 4u);
  EXPECT_GT(planes::polygon_area(footprint(buildings[0])), 10.0);
}

TEST_F(BuildingFitterTest, ACrossShapedBuildingIsUnknownRatherThanInvented) {
  // A plus sign: no rectangle, L or T explains most of its walls.
  const std::vector<Vector2d> plan{{-3, -10}, {3, -10}, {3, -3}, {10, -3}, {10, 3},   {3, 3},
                                   {3, 10},   {-3, 10}, {-3, 3}, {-10, 3}, {-10, -3}, {-3, -3}};
  const auto buildings = fit(testing::walls_around(plan, 8.0));
  ASSERT_EQ(buildings.size(), 1u);
  EXPECT_EQ(buildings[0].shape, BuildingShape::kUnknown);
  EXPECT_EQ(buildings[0].footprint_size, 0u);
  EXPECT_EQ(buildings[0].wall_count, 12u);  // what was seen, as it was seen
  EXPECT_EQ(virtual_walls(buildings[0]), 0u);
}

TEST_F(BuildingFitterTest, TheSameWallsGiveTheSameBuildingsBitForBit) {
  const std::vector<msg::PlanePatch> planes =
      seen_walls(placed(kLPlan, 33.0, {7.0, 8.0}), {0, 1, 5});
  const Building first = fit(planes)[0];
  const Building second = fit(planes)[0];
  EXPECT_EQ(first.shape, second.shape);
  ASSERT_EQ(first.footprint_size, second.footprint_size);
  for (std::size_t k = 0; k < first.footprint_size; ++k) {
    EXPECT_EQ(first.footprint_m[k], second.footprint_m[k]);  // exactly, not nearly
  }
  ASSERT_EQ(first.wall_count, second.wall_count);
  for (std::size_t w = 0; w < first.wall_count; ++w) {
    EXPECT_EQ(first.walls[w].p0_m, second.walls[w].p0_m);
    EXPECT_EQ(first.walls[w].p1_m, second.walls[w].p1_m);
    EXPECT_EQ(first.walls[w].is_virtual, second.walls[w].is_virtual);
    EXPECT_EQ(first.walls[w].plane_id, second.walls[w].plane_id);
  }
}

TEST(BuildingsConfig, EveryMistakeNamesItsKey) {
  EXPECT_EQ(validate(BuildingsConfig{}), "");
  BuildingsConfig config;
  config.fit_tolerance_m = 0.0;
  EXPECT_EQ(validate(config), "fit_tolerance_m: must be > 0");
  config = {};
  config.l_penalty_m = -1.0;
  EXPECT_EQ(validate(config), "l_penalty_m: must be >= 0");
  config = {};
  config.corner_angle_tolerance_deg = 60.0;
  EXPECT_EQ(validate(config), "corner_angle_tolerance_deg: must be in (0, 45)");
  config = {};
  config.max_walls = 0;
  EXPECT_EQ(validate(config), "max_walls: must be in [1, 1048576]");
}

}  // namespace
}  // namespace blockmap::buildings
