// `blockmap simulate` writes a robot's logs and the truth; `blockmap decode` on those logs gives
// back what was simulated, within what each encoding can carry.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "blockmap/hal/cloud/point_cloud_file.hpp"
#include "blockmap/hal/geodesy.hpp"
#include "cli.hpp"
#include "cli_runner.hpp"
#include "scratch.hpp"

namespace blockmap::cli {
namespace {

namespace fs = std::filesystem;

using Result = testing::CliResult;
using blockmap::testing::scratch;
using testing::read_file;
using testing::run_cli;

std::vector<nlohmann::json> json_lines(const std::string& text) {
  std::vector<nlohmann::json> lines;
  std::istringstream stream(text);
  for (std::string line; std::getline(stream, line);) {
    lines.push_back(nlohmann::json::parse(line));
  }
  return lines;
}

std::vector<std::vector<double>> csv_rows(const std::string& text) {
  std::vector<std::vector<double>> rows;
  std::istringstream stream(text);
  std::string line;
  std::getline(stream, line);  // header
  while (std::getline(stream, line)) {
    std::vector<double> row;
    std::istringstream cells(line);
    for (std::string cell; std::getline(cells, cell, ',');) {
      row.push_back(std::stod(cell));
    }
    rows.push_back(row);
  }
  return rows;
}

// One simulated run, shared by the tests of the suite (each only reads it).
class SimulateCommand : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    folder_ = fs::temp_directory_path() / ("blockmap_simulate_" + std::to_string(::getpid()));
    const Result result = run_cli({"simulate", "--world", "usc_block", "--seed", "3",
                                   "--duration-s", "4", "--out", folder_.string()});
    ASSERT_EQ(result.status, kExitOk) << result.err;
    ASSERT_NE(result.err.find("simulate: usc_block seed 3"), std::string::npos) << result.err;
  }
  static void TearDownTestSuite() { fs::remove_all(folder_); }

  static inline fs::path folder_;
};

TEST_F(SimulateCommand, WritesEveryLogTheTruthAndTheConfigurationsItUsed) {
  for (const char* name : {"rmp.candump", "laser_horizontal.bytelog", "laser_vertical.bytelog",
                           "gps.nmea", "truth.json", "truth_gps.csv", "world.toml", "robot.toml"}) {
    EXPECT_TRUE(fs::exists(folder_ / name)) << name;
  }
  const nlohmann::json truth = nlohmann::json::parse(read_file(folder_ / "truth.json"));
  EXPECT_EQ(truth["world"], "usc_block");
  EXPECT_NEAR(static_cast<double>(truth["trajectory"].size()), 400.0, 2.0) << "100 Hz for 4 s";
  for (const char* key : {"t_s", "x_m", "y_m", "z_m", "roll_rad", "pitch_rad", "yaw_rad"}) {
    EXPECT_TRUE(truth["trajectory"][0].contains(key)) << key;
  }
  ASSERT_EQ(truth["buildings"].size(), 1u);
  EXPECT_EQ(truth["buildings"][0]["shape"], "rect");
  int walls = 0;
  for (const nlohmann::json& face : truth["faces"]) {
    walls += face["kind"] == "wall" ? 1 : 0;
    EXPECT_GE(face["corners"].size(), 4u);
  }
  EXPECT_EQ(walls, 4);
  // The configurations replay needs are the ones the run used.
  EXPECT_NE(read_file(folder_ / "world.toml").find("name = \"usc_block\""), std::string::npos);
}

TEST_F(SimulateCommand, TheSameSeedWritesTheSameBytes) {
  const fs::path again = folder_.string() + "_again";
  ASSERT_EQ(run_cli({"simulate", "--world", "usc_block", "--seed", "3", "--duration-s", "4",
                     "--out", again.string()})
                .status,
            kExitOk);
  for (const char* name : {"rmp.candump", "laser_horizontal.bytelog", "laser_vertical.bytelog",
                           "gps.nmea", "truth.json"}) {
    EXPECT_EQ(read_file(folder_ / name), read_file(again / name)) << name;
  }
  fs::remove_all(again);
}

TEST_F(SimulateCommand, TheCloudOptionWritesEveryReturnAndLeavesTheLogsAlone) {
  const fs::path again = folder_.string() + "_cloud";
  const fs::path cloud = again / "cloud.ply";
  fs::create_directories(again);
  ASSERT_EQ(run_cli({"simulate", "--world", "usc_block", "--seed", "3", "--duration-s", "4",
                     "--out", again.string(), "--cloud", cloud.string()})
                .status,
            kExitOk);
  EXPECT_EQ(read_file(folder_ / "laser_vertical.bytelog"),
            read_file(again / "laser_vertical.bytelog"));
  const hal::cloud::PointCloud points = hal::cloud::read_point_cloud(cloud);
  EXPECT_GT(points.points_m.size(), 10000u);  // two lasers, 75 scans a second, 4 s
  // The cloud is one a plane detector reads: the street's ground is in it.
  const Result planes = run_cli({"planes", cloud.string()});
  ASSERT_EQ(planes.status, kExitOk) << planes.err;
  EXPECT_NE(planes.out.find("\"kind\":\"ground\""), std::string::npos);
  fs::remove_all(again);
}

TEST_F(SimulateCommand, DecodedGpsFixesAreTheTruePositionPlusTheReceiversError) {
  const Result decoded = run_cli({"decode", "nmea", (folder_ / "gps.nmea").string()});
  ASSERT_EQ(decoded.status, kExitOk);
  const nlohmann::json truth = nlohmann::json::parse(read_file(folder_ / "truth.json"));
  const hal::LocalEnuFrame frame({truth["origin"]["latitude_deg"], truth["origin"]["longitude_deg"],
                                  truth["origin"]["height_m"]});
  const auto epochs = csv_rows(read_file(folder_ / "truth_gps.csv"));
  std::size_t epoch = 0;
  for (const nlohmann::json& line : json_lines(decoded.out)) {
    if (line["sentence"] != "GGA") {
      continue;
    }
    ASSERT_LT(epoch, epochs.size());
    const std::vector<double>& row = epochs[epoch++];  // t, x, y, z, error e, n, u, ...
    const Eigen::Vector3d enu = frame.to_enu_m({line["lat"], line["lon"], 0.0});
    EXPECT_NEAR(enu.x(), row[1] + row[4], 0.02);
    EXPECT_NEAR(enu.y(), row[2] + row[5], 0.02);
    EXPECT_EQ(line["quality"], 1);
  }
  EXPECT_EQ(epoch, epochs.size());
  EXPECT_EQ(epoch, 16u) << "4 Hz for 4 s";
}

TEST_F(SimulateCommand, DecodedOdometryIsTheTrueMotionWithTheTyreScaleError) {
  const Result decoded = run_cli({"decode", "rmp", (folder_ / "rmp.candump").string()});
  ASSERT_EQ(decoded.status, kExitOk);
  EXPECT_NE(decoded.err.find("400 complete status groups"), std::string::npos) << decoded.err;
  const nlohmann::json truth = nlohmann::json::parse(read_file(folder_ / "truth.json"));
  const nlohmann::json& last = truth["trajectory"].back();
  const nlohmann::json& first = truth["trajectory"].front();
  const double driven =
      std::hypot(static_cast<double>(last["x_m"]) - static_cast<double>(first["x_m"]),
                 static_cast<double>(last["y_m"]) - static_cast<double>(first["y_m"]));
  double fore_aft = 0.0;
  for (const nlohmann::json& line : json_lines(decoded.out)) {
    if (line.contains("fore_aft_distance_m")) {
      fore_aft = line["fore_aft_distance_m"];
    }
  }
  // A straight start: the mean of the two wheels' scale errors (+1.2 % and -0.6 %), and slip.
  EXPECT_NEAR(fore_aft, driven * 1.003, 0.02);
}

TEST_F(SimulateCommand, DecodedScansCarryTheirReceiveTimesAndTheWholeField) {
  const Result decoded =
      run_cli({"decode", "lms2xx", (folder_ / "laser_horizontal.bytelog").string()});
  ASSERT_EQ(decoded.status, kExitOk);
  int scans = 0;
  double previous_t = 0.0;
  for (const nlohmann::json& line : json_lines(decoded.out)) {
    if (!line.contains("ranges_m")) {
      continue;
    }
    ++scans;
    EXPECT_EQ(line["ranges_m"].size(), 181u);
    EXPECT_EQ(line["units"], "cm");
    const double t = line["t_s"];
    if (previous_t > 0.0) {
      EXPECT_NEAR(t - previous_t, 1.0 / 75.0, 0.003) << "75 Hz, read every 2 ms";
    }
    previous_t = t;
  }
  EXPECT_NEAR(scans, 4 * 75, 3);
}

TEST_F(SimulateCommand, ADamagedByteLogDecodesWhatCameBeforeTheDamageAndFails) {
  const fs::path path = folder_ / "laser_horizontal.bytelog";
  const std::string bytes = read_file(path);
  const fs::path cut = folder_ / ("cut_" + std::to_string(::getpid()) + ".bytelog");
  std::ofstream(cut, std::ios::binary) << bytes.substr(0, bytes.size() / 2 + 7);
  const Result decoded = run_cli({"decode", "lms2xx", cut.string()});
  EXPECT_EQ(decoded.status, kExitFailure);
  EXPECT_NE(decoded.err.find("truncated"), std::string::npos) << decoded.err;
  EXPECT_GT(json_lines(decoded.out).size(), 100u);
}

// The receiver's faults for testing what the map keeps through them (issue 54): a silence and
// multipath jumps change the receiver's output and nothing else of the run.
TEST(Simulate, ReceiverFaultsChangeTheFixesAndLeaveTheRestOfTheRunAsItWas) {
  const fs::path plain = scratch("simulate_plain");
  const fs::path faulty = scratch("simulate_faulty");
  ASSERT_EQ(run_cli({"simulate", "--world", "usc_block", "--seed", "4", "--duration-s", "20",
                     "--out", plain.string()})
                .status,
            kExitOk);
  const Result result =
      run_cli({"simulate", "--world", "usc_block", "--seed", "4", "--duration-s", "20", "--out",
               faulty.string(), "--gps-silent", "5,10", "--gps-jumps", "0.2,10"});
  ASSERT_EQ(result.status, kExitOk) << result.err;
  EXPECT_NE(result.err.find("20 not sent"), std::string::npos) << result.err;
  for (const char* name : {"rmp.candump", "laser_horizontal.bytelog", "laser_vertical.bytelog"}) {
    EXPECT_EQ(read_file(plain / name), read_file(faulty / name)) << name;
  }
  EXPECT_NE(read_file(plain / "gps.nmea"), read_file(faulty / "gps.nmea"));
  // About a fifth of the fixes 10 m off (the receiver's own error is 2 m).
  std::istringstream truth(read_file(faulty / "truth_gps.csv"));
  std::string line;
  std::getline(truth, line);
  std::size_t fixes = 0;
  std::size_t jumped = 0;
  while (std::getline(truth, line)) {
    double t = 0.0, x = 0.0, y = 0.0, z = 0.0, east = 0.0, north = 0.0;
    ASSERT_EQ(std::sscanf(line.c_str(), "%lf,%lf,%lf,%lf,%lf,%lf", &t, &x, &y, &z, &east, &north),
              6);
    ++fixes;
    jumped += std::hypot(east, north) > 6.0 ? 1U : 0U;
  }
  EXPECT_EQ(fixes, 80u);
  EXPECT_GT(jumped, 8u);
  EXPECT_LT(jumped, 28u);
  const Result backwards = run_cli(
      {"simulate", "--world", "usc_block", "--out", faulty.string(), "--gps-silent", "10,5"});
  EXPECT_EQ(backwards.status, kExitUsage);
  EXPECT_NE(backwards.err.find("--gps-silent takes FROM_S,TO_S"), std::string::npos);
  fs::remove_all(plain);
  fs::remove_all(faulty);
}

TEST(Simulate, AnUnknownWorldIsOneLineAndAUsageStatus) {
  const Result result = run_cli({"simulate", "--world", "atlantis", "--out", "/tmp/unused"});
  EXPECT_EQ(result.status, kExitUsage);
  EXPECT_EQ(result.err,
            "blockmap: no built-in world 'atlantis' (there are benning, partial, skewed_grid, "
            "triangle, usc_block; or give a .toml file)\n");
}

}  // namespace
}  // namespace blockmap::cli
