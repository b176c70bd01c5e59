// The ray-cast scene: what a beam hits, where, and the shadows objects cast.
#include "blockmap/hal/sim/scene.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace blockmap::hal::sim {
namespace {

World open_field() {
  World world;
  world.name = "field";
  world.site.origin = {40.0, -80.0, 100.0};
  world.path.waypoints_m = {Vec2(-5, 0), Vec2(5, 0)};
  return world;
}

// A long wall facing the laser at y = 10 (the south face of a 60 m x 2 m block).
void add_wall_block(World& world) {
  Building block;
  block.id = 1;
  block.height_m = 6.0;
  FootprintParameters p;
  p.length_m = 60.0;
  p.width_m = 2.0;
  block.footprint_m = make_footprint(p, Vec2(0.0, 11.0), 0.0);
  world.buildings.push_back(block);
}

TEST(Scene, AWallIsHitAtItsDistanceAndCountedAsItsFace) {
  World world = open_field();
  add_wall_block(world);
  Scene scene(world, 1);
  SimRandom random(1, "test");
  const Vec3 origin(0.0, 0.0, 0.5);
  scene.begin_scan(origin, Vec3::UnitZ(), 80.0, 0.0);
  const Hit hit = scene.cast(origin, Vec3(0.0, 1.0, 0.0), 80.0, random);
  ASSERT_EQ(hit.kind, SurfaceKind::kWall);
  EXPECT_NEAR(hit.range_m, 10.0, 1e-9);
  const TruthFace& face = scene.faces()[static_cast<std::size_t>(hit.face)];
  EXPECT_EQ(face.building_id, 1);
  EXPECT_NEAR(face.normal.dot(Vec3(0, -1, 0)), 1.0, 1e-12) << "the south wall faces south";
  EXPECT_NEAR(face.d_m, -10.0, 1e-9);
  // Slanted: 10 / cos(30 deg).
  const double slant = std::numbers::pi / 6;
  const Hit oblique = scene.cast(origin, Vec3(std::sin(slant), std::cos(slant), 0.0), 80.0, random);
  EXPECT_NEAR(oblique.range_m, 10.0 / std::cos(slant), 1e-9);
}

TEST(Scene, ATreeTrunkCastsAShadowOfTheRightWidthOnTheWallBehindIt) {
  // Trunk of radius r at distance a, wall at distance b: the shadow is 2 b tan(asin(r / a)).
  World world = open_field();
  add_wall_block(world);
  Tree tree;
  tree.position_m = Vec2(0.0, 5.0);
  tree.trunk_radius_m = 0.3;
  tree.trunk_height_m = 8.0;
  tree.canopy_radius_m = 0.0;
  world.trees.push_back(tree);
  Scene scene(world, 1);
  SimRandom random(1, "test");
  const Vec3 origin(0.0, 0.0, 0.5);
  scene.begin_scan(origin, Vec3::UnitZ(), 80.0, 0.0);
  double shadow_min_x = 1e9;
  double shadow_max_x = -1e9;
  double step_x = 0.0;
  for (int i = -2000; i <= 2000; ++i) {
    const double angle = i * 1e-4;  // from straight ahead (north)
    const Hit hit = scene.cast(origin, Vec3(std::sin(angle), std::cos(angle), 0.0), 80.0, random);
    const double wall_x = 10.0 * std::tan(angle);
    step_x = std::max(step_x, 10.0 * (std::tan(angle + 1e-4) - std::tan(angle)));
    if (hit.kind == SurfaceKind::kTrunk) {
      shadow_min_x = std::min(shadow_min_x, wall_x);
      shadow_max_x = std::max(shadow_max_x, wall_x);
    } else {
      EXPECT_EQ(hit.kind, SurfaceKind::kWall);
    }
  }
  const double expected = 2.0 * 10.0 * std::tan(std::asin(0.3 / 5.0));
  EXPECT_NEAR(shadow_max_x - shadow_min_x, expected, 2 * step_x);
  EXPECT_NEAR(shadow_min_x + shadow_max_x, 0.0, 2 * step_x) << "centred behind the trunk";
}

TEST(Scene, FoliageStopsBeamsAsOftenAsItsDensitySays) {
  World world = open_field();
  Tree tree;
  tree.position_m = Vec2(0.0, 10.0);
  tree.trunk_height_m = 1.0;
  tree.canopy_radius_m = 2.0;
  tree.canopy_centre_height_m = 0.5;  // centred at the laser's height
  tree.canopy_density_per_m = 0.3;
  world.trees.push_back(tree);
  Scene scene(world, 1);
  SimRandom random(7, "test");
  const Vec3 origin(0.0, 0.0, 0.5 + 0.0);
  scene.begin_scan(origin, Vec3::UnitZ(), 80.0, 0.0);
  int stopped = 0;
  const int beams = 20000;
  for (int i = 0; i < beams; ++i) {
    // Through the canopy's centre: a 4 m chord, above the trunk.
    const Vec3 direction = (Vec3(0.0, 10.0, 0.5 + 0.6) - origin).normalized();
    const Hit hit = scene.cast(origin, direction, 80.0, random);
    if (hit.kind == SurfaceKind::kFoliage) {
      ++stopped;
      EXPECT_GT(hit.range_m, 7.9);
      EXPECT_LT(hit.range_m, 12.1);
    }
  }
  const double chord = 2.0 * std::sqrt(4.0 - 0.36);
  const double expected = 1.0 - std::exp(-0.3 * chord);
  EXPECT_NEAR(static_cast<double>(stopped) / beams, expected, 0.015);
}

TEST(Scene, RoofsAreTheFootprintsPolygonNotItsBoundingBox) {
  World world = open_field();
  Building l;
  l.id = 7;
  l.shape = BuildingShape::kL;
  l.height_m = 5.0;
  FootprintParameters p;
  p.shape = BuildingShape::kL;
  p.length_m = 10;
  p.width_m = 10;
  p.notch_length_m = 4;
  p.notch_width_m = 4;
  l.footprint_m = make_footprint(p, Vec2::Zero(), 0.0);
  world.buildings.push_back(l);
  Scene scene(world, 1);
  SimRandom random(1, "test");
  const Vec3 down(0.0, 0.0, -1.0);
  // From 20 m up: over the building, and over the notch (+x, +y corner).
  for (const auto& [x, y, roof] : {std::tuple{-2.0, -2.0, true}, std::tuple{3.5, 3.5, false}}) {
    const Vec3 origin(x, y, 20.0);
    scene.begin_scan(origin, Vec3::UnitX(), 80.0, 0.0);
    const Hit hit = scene.cast(origin, down, 80.0, random);
    if (roof) {
      EXPECT_EQ(hit.kind, SurfaceKind::kRoof);
      EXPECT_NEAR(hit.range_m, 15.0, 1e-9);
    } else {
      EXPECT_EQ(hit.kind, SurfaceKind::kGround);
      EXPECT_NEAR(hit.range_m, 20.0, 0.01);
    }
  }
}

TEST(Scene, TheGroundFollowsItsBumpsAndKerbs) {
  World world = open_field();
  world.ground.kerbs.push_back({Vec2(-10, 2), Vec2(10, 2), 0.15, 3.0});  // raised north of y = 2
  world.ground.bumps.push_back({Vec2(0, -2), 0.5, 0.1});
  Scene scene(world, 1);
  const Terrain& terrain = scene.terrain();
  EXPECT_NEAR(terrain.height_m(0.0, 3.0), 0.15, 1e-3);
  EXPECT_NEAR(terrain.height_m(0.0, 1.0), 0.0, 1e-3);
  EXPECT_NEAR(terrain.height_m(0.0, -2.0), 0.1, 2e-3);
  SimRandom random(1, "test");
  const Vec3 origin(0.0, 3.0, 1.0);
  scene.begin_scan(origin, Vec3::UnitX(), 80.0, 0.0);
  const Hit hit = scene.cast(origin, Vec3(0, 0, -1), 80.0, random);
  EXPECT_EQ(hit.kind, SurfaceKind::kGround);
  EXPECT_NEAR(hit.range_m, 0.85, 1e-3);
}

TEST(Scene, AScanSelectsOnlyWhatItsPlaneCanReach) {
  World world = open_field();
  add_wall_block(world);
  Scene scene(world, 1);
  SimRandom random(1, "test");
  // A horizontal scan above the building's top sees no wall; one below it does.
  const Vec3 high(0.0, 0.0, 8.0);
  scene.begin_scan(high, Vec3::UnitZ(), 80.0, 0.0);
  EXPECT_EQ(scene.cast(high, Vec3::UnitY(), 80.0, random).kind, SurfaceKind::kNone);
  const Vec3 low(0.0, 0.0, 5.0);
  scene.begin_scan(low, Vec3::UnitZ(), 80.0, 0.0);
  EXPECT_EQ(scene.cast(low, Vec3::UnitY(), 80.0, random).kind, SurfaceKind::kWall);
}

}  // namespace
}  // namespace blockmap::hal::sim
