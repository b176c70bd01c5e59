// `blockmap replay` over a simulated run's logs: the CAN and NMEA bytes go through the device
// layer into the localizer, and trajectory.csv follows the truth better than GPS does.
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include "cli.hpp"
#include "cli_runner.hpp"
#include "long_test.hpp"
#include "scratch.hpp"

namespace blockmap::cli {
namespace {

namespace fs = std::filesystem;

using Result = testing::CliResult;
using testing::read_file;
using testing::run_cli;

struct Row {
  double t_s, x_m, y_m, z_m, roll_rad, pitch_rad, yaw_rad;
};

std::vector<Row> trajectory_rows(const std::string& text, std::string& header) {
  std::istringstream stream(text);
  std::getline(stream, header);
  std::vector<Row> rows;
  for (std::string line; std::getline(stream, line);) {
    Row r{};
    EXPECT_EQ(std::sscanf(line.c_str(), "%lf,%lf,%lf,%lf,%lf,%lf,%lf", &r.t_s, &r.x_m, &r.y_m,
                          &r.z_m, &r.roll_rad, &r.pitch_rad, &r.yaw_rad),
              7)
        << line;
    rows.push_back(r);
  }
  return rows;
}

// A folder of this process's own in the temporary directory.
using blockmap::testing::scratch;

// The true pose at t (the truth is at 100 Hz: the nearest sample).
const nlohmann::json& truth_at(const nlohmann::json& trajectory, double t_s) {
  const double t0 = trajectory[0]["t_s"].get<double>();
  const auto index = static_cast<std::size_t>(std::lround((t_s - t0) * 100.0));
  return trajectory[std::min(index, trajectory.size() - 1)];
}

class ReplayCommand : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    std::string err;
    folder_ =
        testing::simulated_logs({"--world", "usc_block", "--seed", "2", "--duration-s", "90"}, err);
    ASSERT_FALSE(folder_.empty()) << err;
    truth_ = nlohmann::json::parse(read_file(folder_ / "truth.json"));
    const nlohmann::json& o = truth_["origin"];
    origin_ = std::to_string(o["latitude_deg"].get<double>()) + "," +
              std::to_string(o["longitude_deg"].get<double>()) + "," +
              std::to_string(o["height_m"].get<double>());
  }
  static inline fs::path folder_;
  static inline nlohmann::json truth_;
  static inline std::string origin_;
};

TEST_F(ReplayCommand, WritesTheSmoothedTrajectoryCloserToTheTruthThanGps) {
  BLOCKMAP_LONG_TEST();
  const fs::path out = scratch("replay_out");
  // 2,000 particles: well inside the bounds. The localizer alone: the planes of such a replay
  // are ReplayMapping's.
  const Result result = run_cli({"replay", folder_.string(), "--out", out.string(), "--origin",
                                 origin_, "--particles", "2000", "--trajectory-only"});
  ASSERT_EQ(result.status, kExitOk) << result.err;
  EXPECT_NE(result.err.find("replay: 9000 base samples"), std::string::npos) << result.err;
  std::string header;
  const std::vector<Row> rows = trajectory_rows(read_file(out / "trajectory.csv"), header);
  EXPECT_EQ(header, "t_s,x_m,y_m,z_m,roll_rad,pitch_rad,yaw_rad");
  // A pose every 0.25 s from the first fix to the end.
  ASSERT_GT(rows.size(), 350u);
  for (std::size_t i = 1; i < rows.size(); ++i) {
    ASSERT_NEAR(rows[i].t_s - rows[i - 1].t_s, 0.25, 0.011) << i;
  }
  // Scored after 45 s, when the heading has been found.
  const nlohmann::json& trajectory = truth_["trajectory"];
  const double t0 = trajectory[0]["t_s"].get<double>();
  double position_sq = 0.0;
  double heading_sq = 0.0;
  double pitch_sq = 0.0;
  double worst_z = 0.0;
  std::size_t n = 0;
  for (const Row& r : rows) {
    if (r.t_s - t0 < 45.0) {
      continue;
    }
    const nlohmann::json& truth = truth_at(trajectory, r.t_s);
    position_sq += std::pow(r.x_m - truth["x_m"].get<double>(), 2) +
                   std::pow(r.y_m - truth["y_m"].get<double>(), 2);
    const double yaw_error =
        std::remainder(r.yaw_rad - truth["yaw_rad"].get<double>(), 2.0 * std::numbers::pi);
    heading_sq += yaw_error * yaw_error;
    pitch_sq += std::pow(r.pitch_rad - truth["pitch_rad"].get<double>(), 2);
    worst_z = std::max(worst_z, std::abs(r.z_m - truth["z_m"].get<double>()));
    ++n;
  }
  // The GPS error of this run, from the simulator's record of it.
  std::istringstream gps(read_file(folder_ / "truth_gps.csv"));
  std::string line;
  std::getline(gps, line);
  double gps_sq = 0.0;
  std::size_t fixes = 0;
  while (std::getline(gps, line)) {
    double t = 0, x = 0, y = 0, z = 0, ee = 0, en = 0;
    if (std::sscanf(line.c_str(), "%lf,%lf,%lf,%lf,%lf,%lf", &t, &x, &y, &z, &ee, &en) == 6 &&
        t - t0 >= 45.0) {
      gps_sq += ee * ee + en * en;
      ++fixes;
    }
  }
  ASSERT_GT(n, 150u);
  const double position_rms = std::sqrt(position_sq / static_cast<double>(n));
  const double gps_rms = std::sqrt(gps_sq / static_cast<double>(fixes));
  const double heading_rms_deg =
      std::sqrt(heading_sq / static_cast<double>(n)) * 180.0 / std::numbers::pi;
  std::printf("position %.2f m (GPS %.2f m), heading %.2f deg, pitch %.4f rad, worst z %.2f m\n",
              position_rms, gps_rms, heading_rms_deg, std::sqrt(pitch_sq / static_cast<double>(n)),
              worst_z);
  EXPECT_LT(position_rms, 0.75 * gps_rms);
  EXPECT_LT(heading_rms_deg, 3.0);
  // Pitch is the base's own (its sensor noise is 0.2 deg); height the first fix's (level).
  EXPECT_LT(std::sqrt(pitch_sq / static_cast<double>(n)), 0.01);
  EXPECT_LT(worst_z, 6.0);
  fs::remove_all(out);
}

TEST_F(ReplayCommand, WithoutOutWritesTheTrajectoryToStdout) {
  BLOCKMAP_LONG_TEST();
  const Result result = run_cli({"replay", folder_.string(), "--particles", "300"});
  ASSERT_EQ(result.status, kExitOk) << result.err;
  EXPECT_EQ(result.out.rfind("t_s,x_m,y_m,z_m,roll_rad,pitch_rad,yaw_rad\n", 0), 0u);
  // Anchored at the first good fix: the first pose is within metres of the origin.
  std::string header;
  const std::vector<Row> rows = trajectory_rows(result.out, header);
  ASSERT_FALSE(rows.empty());
  EXPECT_LT(std::hypot(rows.front().x_m, rows.front().y_m), 10.0);
  EXPECT_NE(result.err.find("origin "), std::string::npos) << result.err;
}

// Mapping replays: 25 s of usc_block, the east side of the building ahead.
class ReplayMapping : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    std::string err;
    folder_ =
        testing::simulated_logs({"--world", "usc_block", "--seed", "2", "--duration-s", "25"}, err);
    ASSERT_FALSE(folder_.empty()) << err;
  }

  static inline fs::path folder_;
};

TEST_F(ReplayMapping, MapsThePlanesWhenTheLogsHaveLasers) {
  BLOCKMAP_LONG_TEST();
  const fs::path out = scratch("replay_planes");
  const Result result =
      run_cli({"replay", folder_.string(), "--out", out.string(), "--particles", "500", "--cloud"});
  ASSERT_EQ(result.status, kExitOk) << result.err;
  EXPECT_NE(result.err.find("scans projected"), std::string::npos) << result.err;
  const nlohmann::json list = nlohmann::json::parse(read_file(out / "planes.json"));
  EXPECT_FALSE(list["planes"].empty());
  EXPECT_GT(list["points"].get<double>(), 50000.0);
  // --cloud: every projected point, as many as the plane list counts.
  const std::string cloud = read_file(out / "cloud.ply");
  const std::string vertices = "element vertex " + std::to_string(list["points"].get<long>());
  EXPECT_NE(cloud.find(vertices), std::string::npos) << cloud.substr(0, 200);
  for (const char* name :
       {"planes.jsonl", "planes.bin", "map.wrl", "trajectory.csv", "buildings.json",
        "buildings.jsonl", "footprints.geojson", "top_view.svg"}) {
    EXPECT_TRUE(fs::exists(out / name)) << name;
  }
  // With --cloud the picture draws the points under the rest.
  EXPECT_NE(read_file(out / "top_view.svg").find("<g fill=\"#9a9a9a\">\n<rect"), std::string::npos);
  fs::remove_all(out);
}

TEST_F(ReplayMapping, ADamagedLaserLogIsMappedUpToTheDamageAndReported) {
  const fs::path logs = scratch("replay_damaged");
  fs::remove_all(logs);
  fs::copy(folder_, logs);
  // Cut the horizontal laser's log in the middle of a record.
  const fs::path laser = logs / "laser_horizontal.bytelog";
  fs::resize_file(laser, fs::file_size(laser) / 2 + 7);
  const fs::path out = logs.string() + "_out";
  const Result result =
      run_cli({"replay", logs.string(), "--out", out.string(), "--particles", "500"});
  EXPECT_EQ(result.status, kExitFailure);
  EXPECT_NE(result.err.find("laser_horizontal.bytelog is damaged at byte"), std::string::npos)
      << result.err;
  EXPECT_TRUE(fs::exists(out / "planes.json")) << "what came before the damage is mapped";
  fs::remove_all(logs);
  fs::remove_all(out);
}

// A simulated run's origin (--origin) and first true pose (--start-pose), from its truth.json.
struct TrueStart {
  std::string origin;
  std::string pose;
};

TrueStart true_start_of(const nlohmann::json& truth) {
  const nlohmann::json& first = truth["trajectory"][0];
  const nlohmann::json& o = truth["origin"];
  char origin[96];
  std::snprintf(origin, sizeof origin, "%.9f,%.9f,%.3f", o["latitude_deg"].get<double>(),
                o["longitude_deg"].get<double>(), o["height_m"].get<double>());
  char pose[96];
  std::snprintf(pose, sizeof pose, "%.3f,%.3f,%.3f", first["x_m"].get<double>(),
                first["y_m"].get<double>(),
                first["yaw_rad"].get<double>() * 180.0 / std::numbers::pi);
  return {origin, pose};
}

TEST_F(ReplayMapping, ARobotWithoutAReceiverStartsWhereItIsToldAndMaps) {
  // The same logs without gps.nmea: the filter starts at --start-pose (the truth's first
  // pose) and dead-reckons; the scans are matched and mapped all the same.
  const fs::path logs = scratch("replay_no_gps");
  fs::remove_all(logs);
  fs::copy(folder_, logs);
  fs::remove(logs / "gps.nmea");
  const nlohmann::json truth = nlohmann::json::parse(read_file(logs / "truth.json"));
  const nlohmann::json& first = truth["trajectory"][0];
  const nlohmann::json& last = truth["trajectory"][truth["trajectory"].size() - 1];
  const TrueStart true_start = true_start_of(truth);
  const std::string& origin = true_start.origin;
  const std::string& start = true_start.pose;
  const fs::path out = logs.string() + "_out";
  const Result result = run_cli({"replay", logs.string(), "--out", out.string(), "--particles",
                                 "500", "--origin", origin, "--start-pose", start});
  ASSERT_EQ(result.status, kExitOk) << result.err;
  EXPECT_NE(result.err.find(" 0 fixes used"), std::string::npos) << result.err;
  std::string header;
  const std::vector<Row> rows = trajectory_rows(read_file(out / "trajectory.csv"), header);
  ASSERT_GT(rows.size(), 50u);
  EXPECT_LT(std::hypot(rows.front().x_m - first["x_m"].get<double>(),
                       rows.front().y_m - first["y_m"].get<double>()),
            0.5);
  // 25 s of dead reckoning from a known start: within a couple of metres at the end.
  EXPECT_LT(std::hypot(rows.back().x_m - last["x_m"].get<double>(),
                       rows.back().y_m - last["y_m"].get<double>()),
            2.0);
  const nlohmann::json planes = nlohmann::json::parse(read_file(out / "planes.json"));
  EXPECT_GT(planes["planes"].size(), 3u);
  // Without --origin there is no frame to start in: refused with one line.
  const Result unplaced =
      run_cli({"replay", logs.string(), "--out", out.string(), "--start-pose", start});
  EXPECT_EQ(unplaced.status, kExitUsage);
  EXPECT_NE(unplaced.err.find("--start-pose takes X,Y,YAW_DEG"), std::string::npos) << unplaced.err;
  fs::remove_all(logs);
  fs::remove_all(out);
}

// --poses truth: the same logs drawn with the simulation's true poses (the ceiling of what
// they map to). trajectory.csv is the truth; without truth.json it is refused with one line.
TEST_F(ReplayMapping, TruePosesDrawTheSameLogsWhereTheRobotWas) {
  const fs::path out = scratch("replay_true_poses");
  const Result result =
      run_cli({"replay", folder_.string(), "--out", out.string(), "--poses", "truth"});
  ASSERT_EQ(result.status, kExitOk) << result.err;
  const nlohmann::json truth = nlohmann::json::parse(read_file(folder_ / "truth.json"));
  const nlohmann::json& trajectory = truth["trajectory"];
  std::string header;
  const std::vector<Row> rows = trajectory_rows(read_file(out / "trajectory.csv"), header);
  ASSERT_EQ(rows.size(), trajectory.size());
  for (std::size_t i = 0; i < rows.size(); i += 97) {
    EXPECT_NEAR(rows[i].t_s, trajectory[i]["t_s"].get<double>(), 1e-6) << i;
    EXPECT_NEAR(rows[i].x_m, trajectory[i]["x_m"].get<double>(), 1e-3) << i;
    EXPECT_NEAR(rows[i].yaw_rad, trajectory[i]["yaw_rad"].get<double>(), 1e-5) << i;
  }
  EXPECT_FALSE(nlohmann::json::parse(read_file(out / "planes.json"))["planes"].empty());
  const fs::path logs = scratch("replay_true_poses_none");
  fs::remove_all(logs);
  fs::copy(folder_, logs);
  fs::remove(logs / "truth.json");
  const Result refused =
      run_cli({"replay", logs.string(), "--out", out.string(), "--poses", "truth"});
  EXPECT_EQ(refused.status, kExitFailure);
  EXPECT_NE(refused.err.find("truth.json cannot be read"), std::string::npos) << refused.err;
  const Result unknown =
      run_cli({"replay", logs.string(), "--out", out.string(), "--poses", "gps"});
  EXPECT_EQ(unknown.status, kExitUsage);
  EXPECT_NE(unknown.err.find("--poses is filter or truth"), std::string::npos) << unknown.err;
  fs::remove_all(logs);
  fs::remove_all(out);
}

// A minute of benning, seed 1 (simulated once, cached), copied into the scratch folder `name`;
// empty when it could not be simulated.
fs::path benning_minute(const std::string& name) {
  std::string err;
  const fs::path simulated =
      testing::simulated_logs({"--world", "benning", "--seed", "1", "--duration-s", "60"}, err);
  if (simulated.empty()) {
    ADD_FAILURE() << err;
    return {};
  }
  fs::path logs = scratch(name);
  fs::remove_all(logs);
  fs::copy(simulated, logs);
  return logs;
}

TEST(ReplayPriorMap, APriorMapPlacesARobotWithoutAReceiver) {
  BLOCKMAP_LONG_TEST();
  // A minute of benning without gps.nmea, started at the truth's first pose, and the world's
  // footprints (simulate's truth_footprints.geojson, WGS-84) as the prior map: the particles
  // weigh the level scans against it, and its placings hold the rigid path.
  const fs::path logs = benning_minute("replay_prior_map");
  ASSERT_FALSE(logs.empty());
  fs::remove(logs / "gps.nmea");
  const nlohmann::json truth = nlohmann::json::parse(read_file(logs / "truth.json"));
  const nlohmann::json& o = truth["origin"];
  const TrueStart true_start = true_start_of(truth);
  const std::string& origin = true_start.origin;
  const std::string& start = true_start.pose;
  const fs::path map = logs / "truth_footprints.geojson";
  ASSERT_TRUE(fs::exists(map));
  const fs::path out = logs.string() + "_out";
  const Result result = run_cli({"replay", logs.string(), "--out", out.string(), "--origin", origin,
                                 "--start-pose", start, "--prior-map", map.string()});
  ASSERT_EQ(result.status, kExitOk) << result.err;
  const std::size_t summary = result.err.find("prior map: 32 walls, ");
  ASSERT_NE(summary, std::string::npos) << result.err;
  const std::size_t placings = result.err.find(" placings", summary);
  const std::size_t count_from = result.err.rfind(' ', placings - 1) + 1;
  EXPECT_GT(std::stoi(result.err.substr(count_from, placings - count_from)), 5)
      << result.err.substr(summary, 200);
  // Scored after the rigid alignment: the path where the map put it, the alignment's shift
  // as small as the shape's error.
  const Result scored = run_cli({"score", out.string(), logs.string(), "--json"});
  ASSERT_EQ(scored.status, kExitOk) << scored.err;
  const nlohmann::json score = nlohmann::json::parse(scored.out);
  EXPECT_LT(score["path"]["rms_m"].get<double>(), 0.1) << scored.out;
  const nlohmann::json& shift = score["path"]["alignment"]["shift_m"];
  EXPECT_LT(std::hypot(shift[0].get<double>(), shift[1].get<double>()), 0.1) << scored.out;
  // The same footprints a metre off (1.0 m east, 0.7 m south), as an earlier run's receiver
  // would have drawn them: the path carries the map's offset and keeps its start's frame.
  nlohmann::json moved = nlohmann::json::parse(read_file(map));
  constexpr double kEarthRadiusM = 6378137.0;
  const double degrees_per_m = 180.0 / (std::numbers::pi * kEarthRadiusM);
  const double latitude_rad = o["latitude_deg"].get<double>() * std::numbers::pi / 180.0;
  for (nlohmann::json& feature : moved["features"]) {
    for (nlohmann::json& ring : feature["geometry"]["coordinates"]) {
      for (nlohmann::json& corner : ring) {
        corner[0] = corner[0].get<double>() + 1.0 * degrees_per_m / std::cos(latitude_rad);
        corner[1] = corner[1].get<double>() - 0.7 * degrees_per_m;
      }
    }
  }
  const fs::path moved_map = logs / "moved_footprints.geojson";
  std::ofstream(moved_map) << moved.dump();
  const Result offset = run_cli({"replay", logs.string(), "--out", out.string(), "--origin", origin,
                                 "--start-pose", start, "--prior-map", moved_map.string()});
  ASSERT_EQ(offset.status, kExitOk) << offset.err;
  const Result offset_scored = run_cli({"score", out.string(), logs.string(), "--json"});
  ASSERT_EQ(offset_scored.status, kExitOk) << offset_scored.err;
  const nlohmann::json offset_score = nlohmann::json::parse(offset_scored.out);
  EXPECT_LT(offset_score["path"]["rms_m"].get<double>(), 0.15) << offset_scored.out;
  const nlohmann::json& offset_shift = offset_score["path"]["alignment"]["shift_m"];
  EXPECT_LT(std::hypot(offset_shift[0].get<double>(), offset_shift[1].get<double>()), 0.3)
      << offset_scored.out;
  // A map needs the frame it is in, and must be a map: one line each.
  Result bad =
      run_cli({"replay", logs.string(), "--out", out.string(), "--prior-map", map.string()});
  EXPECT_EQ(bad.status, kExitUsage);
  EXPECT_NE(bad.err.find("--prior-map needs --origin"), std::string::npos) << bad.err;
  bad = run_cli({"replay", logs.string(), "--out", out.string(), "--origin", origin, "--start-pose",
                 start, "--prior-map", (logs / "robot.toml").string()});
  EXPECT_EQ(bad.status, kExitUsage);
  EXPECT_NE(bad.err.find("is not a JSON object"), std::string::npos) << bad.err;
  std::ofstream(logs / "empty.geojson") << R"({"type": "FeatureCollection", "features": []})";
  bad = run_cli({"replay", logs.string(), "--out", out.string(), "--origin", origin, "--start-pose",
                 start, "--prior-map", (logs / "empty.geojson").string()});
  EXPECT_EQ(bad.status, kExitUsage);
  EXPECT_NE(bad.err.find("holds no wall"), std::string::npos) << bad.err;
  EXPECT_EQ(std::count(bad.err.begin(), bad.err.end(), '\n'), 1) << bad.err;
  fs::remove_all(logs);
  fs::remove_all(out);
}

// The prior-map count a run's summary gives ("prior map: N walls").
int prior_map_walls(const std::string& err) {
  const std::size_t at = err.find("prior map: ");
  return at == std::string::npos ? -1 : std::stoi(err.substr(at + 11));
}

TEST(ReplayPriorMap, AnEarlierRunsWallsSeenJoinItsFootprints) {
  BLOCKMAP_LONG_TEST();
  // An earlier run of the same minute of benning, mapped with its receiver, is the prior map:
  // its footprints, and the vertical planes it saw (planes.json: a wall of 1 m or more, seen
  // with a thousand returns or more). Replayed without the receiver from the true start.
  const fs::path logs = benning_minute("replay_prior_walls");
  ASSERT_FALSE(logs.empty());
  const TrueStart start = true_start_of(nlohmann::json::parse(read_file(logs / "truth.json")));
  const fs::path earlier = logs.string() + "_earlier";
  Result result =
      run_cli({"replay", logs.string(), "--out", earlier.string(), "--origin", start.origin});
  ASSERT_EQ(result.status, kExitOk) << result.err;
  fs::remove(logs / "gps.nmea");
  const nlohmann::json seen = nlohmann::json::parse(read_file(earlier / "planes.json"));
  int walls_seen = 0;
  for (const nlohmann::json& plane : seen["planes"]) {
    const Eigen::Vector2d across(plane["normal"][0].get<double>(),
                                 plane["normal"][1].get<double>());
    const Eigen::Vector2d along = Eigen::Vector2d(-across.y(), across.x()).normalized();
    double first_m = 1e9;
    double last_m = -1e9;
    for (const nlohmann::json& corner : plane["polygon"]) {
      const double at_m =
          along.dot(Eigen::Vector2d(corner[0].get<double>(), corner[1].get<double>()));
      first_m = std::min(first_m, at_m);
      last_m = std::max(last_m, at_m);
    }
    const bool vertical = across.norm() >= std::cos(10.0 * std::numbers::pi / 180.0);
    const bool seen_well = plane["support"].get<double>() >= 1000.0 && last_m - first_m >= 1.0;
    walls_seen += vertical && seen_well ? 1 : 0;
  }
  ASSERT_GT(walls_seen, 5);
  const fs::path out = logs.string() + "_out";
  result = run_cli({"replay", logs.string(), "--out", out.string(), "--origin", start.origin,
                    "--start-pose", start.pose, "--prior-map",
                    (earlier / "footprints.geojson").string()});
  ASSERT_EQ(result.status, kExitOk) << result.err;
  const int footprint_walls = prior_map_walls(result.err);
  result =
      run_cli({"replay", logs.string(), "--out", out.string(), "--origin", start.origin,
               "--start-pose", start.pose, "--prior-map", (earlier / "footprints.geojson").string(),
               "--prior-map", (earlier / "planes.json").string()});
  ASSERT_EQ(result.status, kExitOk) << result.err;
  EXPECT_EQ(prior_map_walls(result.err), footprint_walls + walls_seen) << result.err;
  const Result scored = run_cli({"score", out.string(), logs.string(), "--json"});
  ASSERT_EQ(scored.status, kExitOk) << scored.err;
  const nlohmann::json score = nlohmann::json::parse(scored.out);
  std::printf("%d footprint walls and %d walls seen; path %.3f m, shift %s m\n", footprint_walls,
              walls_seen, score["path"]["rms_m"].get<double>(),
              score["path"]["alignment"]["shift_m"].dump().c_str());
  EXPECT_LT(score["path"]["rms_m"].get<double>(), 0.15) << scored.out;
  const nlohmann::json& shift = score["path"]["alignment"]["shift_m"];
  EXPECT_LT(std::hypot(shift[0].get<double>(), shift[1].get<double>()), 0.3) << scored.out;
  // A plane list with a mistake is refused with one line naming the entry.
  std::ofstream(logs / "bad_planes.json")
      << R"({"planes": [{"id": 1, "kind": "wall", "normal": [2, 0, 0], "d": 1, "polygon": []}]})";
  result =
      run_cli({"replay", logs.string(), "--out", out.string(), "--origin", start.origin,
               "--start-pose", start.pose, "--prior-map", (logs / "bad_planes.json").string()});
  EXPECT_EQ(result.status, kExitUsage);
  EXPECT_NE(result.err.find("planes[0].normal"), std::string::npos) << result.err;
  EXPECT_EQ(std::count(result.err.begin(), result.err.end(), '\n'), 1) << result.err;
  fs::remove_all(logs);
  fs::remove_all(earlier);
  fs::remove_all(out);
}

TEST(ReplayCommandInput, BadInputGetsOneClearLine) {
  const fs::path folder =
      fs::temp_directory_path() / ("blockmap_replay_bad_" + std::to_string(::getpid()));
  Result result = run_cli({"replay", (folder / "no_such_folder").string()});
  EXPECT_EQ(result.status, kExitFailure);
  EXPECT_NE(result.err.find("is not a folder of device logs"), std::string::npos) << result.err;
  fs::create_directories(folder);
  result = run_cli({"replay", folder.string(), "--origin", "95,0,0"});
  EXPECT_EQ(result.status, kExitUsage);
  EXPECT_NE(result.err.find("--origin must be LAT,LON,HEIGHT"), std::string::npos) << result.err;
  // A log folder without its GPS log names the missing file.
  std::ofstream(folder / "rmp.candump") << "(1156255200.010000) can0 400#0000000000000000\n";
  result = run_cli({"replay", folder.string()});
  EXPECT_EQ(result.status, kExitFailure);
  EXPECT_NE(result.err.find("gps.nmea"), std::string::npos) << result.err;
  // A CAN log without a whole status group gives nothing to map from, and says so.
  std::ofstream(folder / "gps.nmea") << "$GPGGA,140000.25,,,,,0,00,99.9,,M,,M,,*5D\r\n";
  result = run_cli({"replay", folder.string()});
  EXPECT_EQ(result.status, kExitFailure);
  EXPECT_NE(result.err.find("no status group of the base"), std::string::npos) << result.err;
  // Odometry without a usable fix gives no pose, and says so.
  std::ofstream(folder / "rmp.candump") << "(1156255200.010000) can0 400#0000000000000000\n"
                                           "(1156255200.010250) can0 401#FFFD0008FFF7FFFF\n"
                                           "(1156255200.010500) can0 402#00010001FFFC0001\n"
                                           "(1156255200.010750) can0 403#0001000000010000\n"
                                           "(1156255200.011000) can0 404#0001000000000000\n"
                                           "(1156255200.011250) can0 405#1483148300000000\n"
                                           "(1156255200.011500) can0 406#0002000001E00124\n"
                                           "(1156255200.011750) can0 407#0000000000000000\n";
  result = run_cli({"replay", folder.string()});
  EXPECT_EQ(result.status, kExitFailure);
  EXPECT_NE(result.err.find("no pose"), std::string::npos) << result.err;
  fs::remove_all(folder);
}

}  // namespace
}  // namespace blockmap::cli
