// `blockmap score`: a replay's map of a simulated run against the run's truth.json, after the
// estimated path is laid onto the true one.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "cli.hpp"
#include "cli_runner.hpp"
#include "long_test.hpp"
#include "scratch.hpp"

namespace blockmap::cli {
namespace {

namespace fs = std::filesystem;

using blockmap::testing::scratch;
using testing::read_file;
using testing::run_cli;

class ScoreCommand : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    std::string err;
    logs_ =
        testing::simulated_logs({"--world", "usc_block", "--seed", "2", "--duration-s", "60"}, err);
    ASSERT_FALSE(logs_.empty()) << err;
    const nlohmann::json truth = nlohmann::json::parse(read_file(logs_ / "truth.json"));
    const nlohmann::json& o = truth["origin"];
    map_ = scratch("score_map");
    const testing::CliResult replay =
        run_cli({"replay", logs_.string(), "--out", map_.string(), "--origin",
                 std::to_string(o["latitude_deg"].get<double>()) + "," +
                     std::to_string(o["longitude_deg"].get<double>()) + "," +
                     std::to_string(o["height_m"].get<double>())});
    ASSERT_EQ(replay.status, kExitOk) << replay.err;
  }
  static void TearDownTestSuite() { fs::remove_all(map_); }
  static inline fs::path logs_;
  static inline fs::path map_;
};

TEST_F(ScoreCommand, ScoresAReplaysMapAfterLayingItsPathOntoTheTruth) {
  const testing::CliResult result = run_cli({"score", map_.string(), logs_.string(), "--json"});
  ASSERT_EQ(result.status, kExitOk) << result.err;
  const nlohmann::json score = nlohmann::json::parse(result.out);
  // The path the planes were laid with: the rigid path's keyframes, one per fix (4 Hz); laid
  // onto the truth it keeps the true shape to decimetres, and its worst is no better than its
  // median. The scan matcher's own path is scored beside it.
  EXPECT_EQ(score["path"]["file"], "path.csv");
  EXPECT_GT(score["path"]["poses"].get<int>(), 150);
  EXPECT_LT(score["path"]["rms_m"].get<double>(), 0.5);
  EXPECT_EQ(score["matched_path"]["poses"], score["path"]["poses"]);
  EXPECT_LT(score["matched_path"]["rms_m"].get<double>(), 1.0);
  EXPECT_GE(score["path"]["max_m"].get<double>(), score["path"]["median_m"].get<double>());
  EXPECT_LT(std::abs(score["path"]["alignment"]["yaw_deg"].get<double>()), 10.0);
  // Where the map sits, against the receiver's mean error over the run (truth_gps.csv): the
  // rigid path sits where its fixes put it on average, whatever the origin.
  const nlohmann::json& offset = score["path"]["alignment"]["offset_m"];
  const nlohmann::json& mean_error = score["receiver"]["mean_error_m"];
  EXPECT_GT(score["receiver"]["fixes"].get<int>(), 200);  // 4 Hz over a minute
  EXPECT_LT(std::hypot(offset[0].get<double>() - mean_error[0].get<double>(),
                       offset[1].get<double>() - mean_error[1].get<double>()),
            0.5)
      << result.out;
  EXPECT_EQ(score["receiver"]["offset_within"].get<bool>(),
            std::hypot(offset[0].get<double>(), offset[1].get<double>()) <=
                std::hypot(mean_error[0].get<double>(), mean_error[1].get<double>()) + 0.3);
  // The first minute sees the ground and the first walls.
  EXPECT_GE(score["planes"]["faces"].get<int>(), 2);
  EXPECT_LE(score["planes"]["walls_found"].get<int>(), score["planes"]["walls"].get<int>());
  EXPECT_LE(score["planes"]["structural_real"].get<int>(),
            score["planes"]["structural"].get<int>());
  EXPECT_EQ(score["buildings"]["buildings"].get<int>(), 1);  // usc_block's one building
  const nlohmann::json& each = score["buildings"]["each"];
  ASSERT_EQ(each.size(), 1u);
  EXPECT_EQ(each[0]["shape"], "rect");
  EXPECT_DOUBLE_EQ(each[0]["iou"].get<double>(), score["buildings"]["mean_iou"].get<double>());
  // The same in three lines.
  const testing::CliResult lines =
      run_cli({"score", map_.string(), (logs_ / "truth.json").string()});
  ASSERT_EQ(lines.status, kExitOk) << lines.err;
  EXPECT_NE(lines.out.find("path (path.csv): "), std::string::npos);
  EXPECT_NE(lines.out.find("where the map sits: its path "), std::string::npos);
  EXPECT_NE(lines.out.find("the receiver's mean error "), std::string::npos);
  EXPECT_NE(lines.out.find("matched path (the scan matcher's"), std::string::npos);
  EXPECT_NE(lines.out.find("planes: walls found "), std::string::npos);
  EXPECT_NE(lines.out.find("buildings: mean footprint IoU "), std::string::npos);
}

TEST_F(ScoreCommand, AMapWithoutASolvedPathIsScoredOnItsTrajectory) {
  // A map made without the rigid path (or before path.csv) has only the smoothed poses.
  const fs::path map = scratch("score_trajectory_only");
  fs::remove_all(map);
  fs::create_directories(map);
  for (const char* name : {"trajectory.csv", "planes.json", "buildings.json"}) {
    fs::copy_file(map_ / name, map / name);
  }
  const testing::CliResult result = run_cli({"score", map.string(), logs_.string(), "--json"});
  ASSERT_EQ(result.status, kExitOk) << result.err;
  const nlohmann::json score = nlohmann::json::parse(result.out);
  EXPECT_EQ(score["path"]["file"], "trajectory.csv");
  EXPECT_GT(score["path"]["poses"].get<int>(), 150);
  EXPECT_LT(score["path"]["rms_m"].get<double>(), 2.0);
  EXPECT_EQ(score["matched_path"]["poses"].get<int>(), 0);
  fs::remove_all(map);
  // A truth.json alone (no truth_gps.csv beside it) has no receiver to compare with.
  const fs::path truth_alone = scratch("score_truth_alone");
  fs::create_directories(truth_alone);
  fs::copy_file(logs_ / "truth.json", truth_alone / "truth.json",
                fs::copy_options::overwrite_existing);
  const testing::CliResult alone =
      run_cli({"score", map_.string(), truth_alone.string(), "--json"});
  ASSERT_EQ(alone.status, kExitOk) << alone.err;
  EXPECT_TRUE(nlohmann::json::parse(alone.out)["receiver"].is_null());
  fs::remove_all(truth_alone);
}

TEST_F(ScoreCommand, AMissingOrDamagedFileIsOneLineAndAFailure) {
  const fs::path empty = scratch("score_empty");
  fs::create_directories(empty);
  const testing::CliResult no_map = run_cli({"score", empty.string(), logs_.string()});
  EXPECT_EQ(no_map.status, kExitFailure);
  EXPECT_NE(no_map.err.find("trajectory.csv: cannot open"), std::string::npos) << no_map.err;
  EXPECT_EQ(std::count(no_map.err.begin(), no_map.err.end(), '\n'), 1);
  const fs::path bad_truth = scratch("score_bad_truth") / "truth.json";
  fs::create_directories(bad_truth.parent_path());
  std::ofstream(bad_truth) << "{\"trajectory\": []";
  const testing::CliResult damaged = run_cli({"score", map_.string(), bad_truth.string()});
  EXPECT_EQ(damaged.status, kExitFailure);
  EXPECT_NE(damaged.err.find("not JSON"), std::string::npos) << damaged.err;
  EXPECT_EQ(std::count(damaged.err.begin(), damaged.err.end(), '\n'), 1);
  fs::remove_all(empty);
  fs::remove_all(bad_truth.parent_path());
}

}  // namespace
}  // namespace blockmap::cli
