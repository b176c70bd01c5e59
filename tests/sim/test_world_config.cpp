// World and robot files: the built-in ones load, and every mistake is one error naming the key.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <string>

#include "blockmap/hal/config/config_error.hpp"
#include "blockmap/hal/config/robot.hpp"
#include "blockmap/hal/sim/world.hpp"

namespace blockmap::hal::sim {
namespace {

double signed_area(const std::vector<Vec2>& polygon) {
  double area = 0.0;
  for (std::size_t i = 0; i < polygon.size(); ++i) {
    const Vec2& a = polygon[i];
    const Vec2& b = polygon[(i + 1) % polygon.size()];
    area += a.x() * b.y() - b.x() * a.y();
  }
  return area / 2.0;
}

// The message of the ConfigError that parsing `text` throws ("" when it does not throw).
std::string world_error(const std::string& text) {
  try {
    (void)parse_world(text, "test.toml");
  } catch (const ConfigError& error) {
    return error.what();
  }
  return "";
}

const std::string kMinimalWorld = R"(
name = "tiny"
[site]
latitude_deg = 10.0
longitude_deg = 20.0
start_utc = 2006-05-10T17:00:00Z
[path]
cruise_speed_mps = 1.0
waypoints_m = [[0.0, 0.0], [10.0, 0.0]]
)";

TEST(WorldFiles, EveryBuiltInWorldLoads) {
  ASSERT_GE(builtin_world_names().size(), 3u);
  for (const std::string_view name : builtin_world_names()) {
    SCOPED_TRACE(std::string(name));
    const World world = load_world(name);
    EXPECT_EQ(world.name, name);
    EXPECT_GE(world.path.waypoints_m.size(), 2u);
    for (const Building& building : world.buildings) {
      EXPECT_GT(signed_area(building.footprint_m), 0.0) << "footprints are counter-clockwise";
      EXPECT_GT(building.height_m, 0.0);
    }
  }
}

TEST(WorldFiles, TheWorldsTheIssueAsksFor) {
  const World usc = load_world("usc_block");
  ASSERT_EQ(usc.buildings.size(), 1u);
  EXPECT_NEAR(signed_area(usc.buildings[0].footprint_m), 40.0 * 25.0, 1e-6);
  EXPECT_GE(usc.buildings[0].height_m, 4 * 3.0) << "four storeys";
  EXPECT_FALSE(usc.trees.empty());
  EXPECT_FALSE(usc.bushes.empty());
  EXPECT_EQ(usc.path.waypoints_m.front(), usc.path.waypoints_m.back()) << "a complete loop";

  const World benning = load_world("benning");
  EXPECT_GE(benning.buildings.size(), 6u);
  bool shapes[3] = {false, false, false};
  for (const Building& building : benning.buildings) {
    shapes[static_cast<int>(building.shape)] = true;
  }
  EXPECT_TRUE(shapes[0] && shapes[1] && shapes[2]) << "rect, L and T";
  double length = 0.0;
  for (std::size_t i = 1; i < benning.path.waypoints_m.size(); ++i) {
    length += (benning.path.waypoints_m[i] - benning.path.waypoints_m[i - 1]).norm();
  }
  EXPECT_NEAR(length, 350.0, 10.0);
  EXPECT_NEAR(benning.path.cruise_speed_mps, 1.2, 0.1);
  EXPECT_GT(benning.ground.roughness_m, 0.01) << "rough terrain";

  const World partial = load_world("partial");
  EXPECT_EQ(partial.buildings.size(), 6u);
}

// Issue 54's worlds for the laser SLAM back end: streets that are not axis-aligned, a loop the
// route closes and a dead end it turns in, and buildings of every shape.
TEST(WorldFiles, TheLoopClosingWorldsHaveSkewedStreetsLoopsAndDeadEnds) {
  for (const char* name : {"skewed_grid", "triangle"}) {
    SCOPED_TRACE(name);
    const World world = load_world(name);
    const std::vector<Vec2>& path = world.path.waypoints_m;
    ASSERT_GE(path.size(), 6u);
    bool skewed = false;
    bool dead_end = false;
    double length_m = 0.0;
    for (std::size_t i = 1; i < path.size(); ++i) {
      const Vec2 leg = path[i] - path[i - 1];
      length_m += leg.norm();
      // Along neither axis, by more than 5 degrees.
      const double angle_deg =
          std::atan2(std::abs(leg.y()), std::abs(leg.x())) * 180.0 / std::numbers::pi;
      skewed = skewed || (leg.norm() > 20.0 && angle_deg > 5.0 && angle_deg < 85.0);
      // A long leg driven back along itself after a short turn: a dead end.
      for (std::size_t j = i + 1; j + 1 < path.size() && j <= i + 3; ++j) {
        const Vec2 back = path[j + 1] - path[j];
        dead_end = dead_end || (leg.norm() > 20.0 && back.norm() > 20.0 &&
                                leg.normalized().dot(back.normalized()) < -0.99);
      }
    }
    EXPECT_TRUE(skewed);
    EXPECT_TRUE(dead_end);
    EXPECT_GT(length_m, 350.0);
    // The route comes back past its start: a loop to close.
    bool closes = false;
    double along_m = 0.0;
    for (std::size_t i = 1; i < path.size(); ++i) {
      along_m += (path[i] - path[i - 1]).norm();
      closes = closes || (along_m > 200.0 && (path[i] - path.front()).norm() < 10.0);
    }
    EXPECT_TRUE(closes);
    bool shapes[3] = {false, false, false};
    for (const Building& building : world.buildings) {
      shapes[static_cast<int>(building.shape)] = true;
    }
    EXPECT_TRUE(shapes[0] && shapes[1] && shapes[2]) << "rect, L and T";
  }
}

TEST(WorldFiles, ShapesHaveTheirVertexCountsAndAreas) {
  FootprintParameters l;
  l.shape = BuildingShape::kL;
  l.length_m = 20;
  l.width_m = 10;
  l.notch_length_m = 5;
  l.notch_width_m = 4;
  const std::vector<Vec2> l_footprint = make_footprint(l, Vec2(100, 50), 0.3);
  EXPECT_EQ(l_footprint.size(), 6u);
  EXPECT_NEAR(signed_area(l_footprint), 200.0 - 20.0, 1e-9);

  FootprintParameters t;
  t.shape = BuildingShape::kT;
  t.length_m = 24;
  t.width_m = 16;
  t.bar_width_m = 6;
  t.stem_width_m = 8;
  const std::vector<Vec2> t_footprint = make_footprint(t, Vec2::Zero(), 0.0);
  EXPECT_EQ(t_footprint.size(), 8u);
  EXPECT_NEAR(signed_area(t_footprint), 24.0 * 6.0 + 8.0 * 10.0, 1e-9);

  t.bar_width_m = 16;  // the bar as wide as the building: no stem left
  EXPECT_THROW((void)make_footprint(t, Vec2::Zero(), 0.0), std::invalid_argument);
}

TEST(WorldFiles, AMinimalWorldParses) {
  const World world = parse_world(kMinimalWorld, "tiny.toml");
  EXPECT_EQ(world.name, "tiny");
  EXPECT_DOUBLE_EQ(world.site.start_unix_s, 1147280400.0);
}

TEST(WorldFiles, MistakesNameTheKey) {
  EXPECT_EQ(world_error("colour = \"red\"\n" + kMinimalWorld), "test.toml: colour: unknown key");
  EXPECT_EQ(world_error(kMinimalWorld + "loops = true\n"), "test.toml: path.loops: unknown key");
  EXPECT_EQ(world_error(kMinimalWorld +
                        "[[buildings]]\nshape = \"rect\"\ncentre_m = [0.0, 0.0]\nlength_m = 10.0\n"
                        "width_m = 5.0\nheight_ft = 30.0\n"),
            "test.toml: buildings[0].height_m: missing (a number is required)");
  EXPECT_EQ(world_error(kMinimalWorld +
                        "[[buildings]]\nshape = \"oval\"\ncentre_m = [0.0, 0.0]\nlength_m = 10.0\n"
                        "width_m = 5.0\nheight_m = 3.0\n"),
            "test.toml: buildings[0].shape: expected \"rect\", \"L\" or \"T\", not \"oval\"");
  EXPECT_EQ(
      world_error(kMinimalWorld +
                  "[[buildings]]\nshape = \"L\"\ncentre_m = [0.0, 0.0]\nlength_m = 10.0\n"
                  "width_m = 5.0\nheight_m = 3.0\nnotch_length_m = 12.0\nnotch_width_m = 2.0\n"),
      "test.toml: buildings[0].shape: an L needs 0 < notch_length_m < length_m and "
      "0 < notch_width_m < width_m");
  EXPECT_EQ(world_error(kMinimalWorld + "[[trees]]\nposition_m = [1.0]\n"),
            "test.toml: trees[0].position_m: expected [x, y] (two numbers)");
  EXPECT_EQ(
      world_error(kMinimalWorld + "[[trees]]\nposition_m = [1.0, 2.0]\ntrunk_radius_m = -1\n"),
      "test.toml: trees[0].trunk_radius_m: must be > 0");
  EXPECT_EQ(world_error("name = \"x\"\n[site\n"),
            "test.toml:2:6: Error while parsing table header: expected ']', saw '\\n'");
}

TEST(RobotFiles, ThePapersRobotLoads) {
  const config::RobotSpec robot = config::load_robot("paper_rmp");
  ASSERT_EQ(robot.lasers.size(), 2u);
  EXPECT_EQ(robot.lasers[0].name, "horizontal");
  EXPECT_EQ(robot.lasers[1].name, "vertical");
  EXPECT_NEAR(robot.lasers[1].mount.pitch_rad, -M_PI / 2, 1e-12);
  EXPECT_DOUBLE_EQ(robot.lasers[0].scan_rate_hz, 75.0);
  EXPECT_DOUBLE_EQ(robot.gps.horizontal_error_rms_m, 2.0);
}

TEST(RobotFiles, ThePapersRobotWithAnRtkReceiverDiffersByItsReceiverAlone) {
  const config::RobotSpec paper = config::load_robot("paper_rmp");
  const config::RobotSpec rtk = config::load_robot("paper_rmp_rtk");
  EXPECT_EQ(paper.gps.fix_quality, msg::GpsFixQuality::kGps);
  EXPECT_EQ(rtk.gps.fix_quality, msg::GpsFixQuality::kRtkFixed);
  EXPECT_DOUBLE_EQ(rtk.gps.horizontal_error_rms_m, 0.02);
  EXPECT_EQ(rtk.gps.antenna_m, paper.gps.antenna_m);
  ASSERT_EQ(rtk.lasers.size(), paper.lasers.size());
  for (std::size_t i = 0; i < paper.lasers.size(); ++i) {
    EXPECT_EQ(rtk.lasers[i].name, paper.lasers[i].name);
    EXPECT_EQ(rtk.lasers[i].mount.position_m, paper.lasers[i].mount.position_m);
  }
  EXPECT_DOUBLE_EQ(rtk.base.track_m, paper.base.track_m);
  EXPECT_DOUBLE_EQ(rtk.base.left_scale_error, paper.base.left_scale_error);
}

TEST(RobotFiles, AnUnknownFixQualityIsRefusedWithTheChoices) {
  try {
    (void)config::parse_robot("name = \"r\"\n[gps]\nfix_quality = \"ppp\"\n", "r.toml");
    FAIL() << "ppp is no fix quality the simulated receiver reports";
  } catch (const ConfigError& error) {
    EXPECT_EQ(std::string(error.what()),
              "r.toml: gps.fix_quality: expected gps, dgps, rtk_float or rtk_fixed");
  }
}

TEST(RobotFiles, ALaserTooFastForItsLineIsRefusedWithTheReason) {
  const std::string text = R"(
name = "slow"
[[lasers]]
name = "front"
position_m = [0.0, 0.0, 0.5]
baud = 38400
scan_rate_hz = 75.0
)";
  try {
    (void)config::parse_robot(text, "slow.toml");
    FAIL() << "a 75 Hz scan cannot go over 38400 Bd";
  } catch (const ConfigError& error) {
    EXPECT_EQ(std::string(error.what()),
              "slow.toml: lasers[0].scan_rate_hz: at 38400 Bd a scan takes 97 ms to send, longer "
              "than the scan period of 13 ms: lower scan_rate_hz or raise baud");
  }
  // 75 / 8 Hz fits.
  std::string slower = text;
  slower.replace(slower.find("75.0"), 4, "9.375");
  EXPECT_NO_THROW((void)config::parse_robot(slower, "slow.toml"));
}

TEST(RobotFiles, UnknownBuiltInsAndFilesAreClearErrors) {
  EXPECT_THROW((void)config::load_robot("no_such_robot"), ConfigError);
  EXPECT_THROW((void)load_world("no_such_world"), ConfigError);
  EXPECT_THROW((void)load_world("/nonexistent/world.toml"), ConfigError);
}

}  // namespace
}  // namespace blockmap::hal::sim
