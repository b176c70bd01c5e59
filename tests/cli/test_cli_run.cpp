// `blockmap run`: the onboard mapper on the built-in simulated city block writes what
// docs/formats.md (run outputs) lists, reports its memory against the budget first, takes its
// window and ranges from --config, and refuses bad options and configs in one line.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "cli.hpp"
#include "cli_runner.hpp"
#include "long_test.hpp"
#include "scratch.hpp"

namespace blockmap::cli {
namespace {

namespace fs = std::filesystem;
using testing::read_file;
using testing::run_cli;

using blockmap::testing::scratch;

TEST(RunCommand, MapsTheSimulatedBlockAndWritesEveryOutput) {
  const fs::path out = scratch("out");
  const testing::CliResult result = run_cli({"run", "--duration-s", "12", "--out", out.string()});
  ASSERT_EQ(result.status, kExitOk) << result.err;
  EXPECT_EQ(result.err.rfind("memory: ", 0), 0u) << "the memory report comes first";
  EXPECT_NE(result.err.find("of the 64.0 MiB budget"), std::string::npos) << result.err;
  EXPECT_NE(result.err.find("map.wrl"), std::string::npos) << "it says where to look";
  // The final plane list (4.1).
  const nlohmann::json list = nlohmann::json::parse(read_file(out / "planes.json"));
  ASSERT_TRUE(list["planes"].is_array());
  ASSERT_FALSE(list["planes"].empty());
  for (const nlohmann::json& plane : list["planes"]) {
    for (const char* key :
         {"id", "kind", "normal", "d", "support", "rmse", "centroid", "polygon"}) {
      EXPECT_TRUE(plane.contains(key)) << key;
    }
  }
  EXPECT_GT(list["points"].get<double>(), 10000.0);
  // The stream: a line per update, every plane of the final list finalized in it.
  std::istringstream lines(read_file(out / "planes.jsonl"));
  std::size_t updates = 0;
  std::size_t finalized = 0;
  for (std::string line; std::getline(lines, line);) {
    const nlohmann::json update = nlohmann::json::parse(line);
    ASSERT_TRUE(update.contains("t_s"));
    finalized += update["finalized"].size();
    ++updates;
  }
  EXPECT_GT(updates, 5u);
  EXPECT_GE(finalized, list["planes"].size());
  const std::string binary = read_file(out / "planes.bin");
  EXPECT_EQ(binary.substr(0, 8), "BMPLANE1");
  EXPECT_EQ(read_file(out / "map.wrl").rfind("#VRML V2.0 utf8\n", 0), 0u);
  // Buildings (4.2), their stream, and the footprints in WGS-84 at the world's site.
  const nlohmann::json buildings = nlohmann::json::parse(read_file(out / "buildings.json"));
  ASSERT_TRUE(buildings["buildings"].is_array());
  // The picture from above: the path, the wall planes, a polygon per footprint.
  const std::string picture = read_file(out / "top_view.svg");
  EXPECT_EQ(picture.rfind("<svg ", 0), 0u);
  EXPECT_NE(picture.find("<polyline"), std::string::npos) << "the path";
  EXPECT_NE(picture.find("</svg>"), std::string::npos);
  std::size_t footprints_drawn = 0;
  for (std::size_t at = picture.find("<polygon"); at != std::string::npos;
       at = picture.find("<polygon", at + 1)) {
    ++footprints_drawn;
  }
  std::size_t footprints_listed = 0;
  for (const nlohmann::json& building : buildings["buildings"]) {
    footprints_listed += building["footprint"].size() >= 3 ? 1U : 0U;
  }
  EXPECT_EQ(footprints_drawn, footprints_listed);
  const nlohmann::json footprints = nlohmann::json::parse(read_file(out / "footprints.geojson"));
  EXPECT_EQ(footprints["type"], "FeatureCollection");
  EXPECT_TRUE(fs::exists(out / "buildings.jsonl"));
  EXPECT_EQ(
      read_file(out / "trajectory.csv").rfind("t_s,x_m,y_m,z_m,roll_rad,pitch_rad,yaw_rad\n", 0),
      0u);
  fs::remove_all(out);
}

TEST(RunCommand, BadOptionsGetOneClearLine) {
  const fs::path out = scratch("bad");
  testing::CliResult result =
      run_cli({"run", "--duration-s", "1", "--budget-mib", "8", "--out", out.string()});
  EXPECT_EQ(result.status, kExitUsage);
  EXPECT_NE(result.err.find("over the 8.0 MiB budget"), std::string::npos) << result.err;
  result = run_cli({"run", "--poses", "guessed", "--out", out.string()});
  EXPECT_EQ(result.status, kExitUsage);
  EXPECT_NE(result.err.find("--poses is filter or truth"), std::string::npos) << result.err;
  result = run_cli({"run", "--world", "atlantis", "--out", out.string()});
  EXPECT_NE(result.status, kExitOk);
  EXPECT_NE(result.err.find("atlantis"), std::string::npos) << result.err;
  fs::remove_all(out);
}

// Scans drawn 4 s late with the smoothed path: every scan still projected, the last 4 s at
// the end of the input.
TEST(RunCommand, APoseLagDrawsEveryScanLate) {
  BLOCKMAP_LONG_TEST();
  const fs::path out = scratch("lag");
  fs::create_directories(out);
  const auto projected = [](const std::string& err) {
    const std::size_t at = err.find(" scans projected");
    const std::size_t first = err.rfind(' ', at - 1) + 1;
    return at == std::string::npos ? -1 : std::stoi(err.substr(first, at - first));
  };
  testing::CliResult live =
      run_cli({"run", "--duration-s", "10", "--out", (out / "live").string()});
  ASSERT_EQ(live.status, kExitOk) << live.err;
  const std::string lag = (out / "lag.toml").string();
  std::ofstream(lag) << "[mapper]\npose_lag_s = 4.0\n";
  testing::CliResult lagged =
      run_cli({"run", "--config", lag, "--duration-s", "10", "--out", (out / "lag").string()});
  ASSERT_EQ(lagged.status, kExitOk) << lagged.err;
  EXPECT_GT(projected(live.err), 1000);
  EXPECT_EQ(projected(lagged.err), projected(live.err)) << lagged.err;
  // Nothing refused: the queue grew to hold the lag's scans.
  EXPECT_TRUE(lagged.err.find("scans refused") == std::string::npos ||
              lagged.err.find("mapper: 0 scans refused (queue full), 0 with too many beams") !=
                  std::string::npos)
      << lagged.err;
  fs::remove_all(out);
}

// [rigid_path]: the whole run's path solved, the planes shown where it puts them as the run
// goes, and the final planes moved with it. On by default
// where the scans are matched (a pose lag above leaves none and runs without it); `enabled =
// false` turns it off. Its mistakes (asked for where it cannot run) are in the table below.
TEST(RunCommand, TheRigidPathMovesTheFinalPlanesUnlessTurnedOff) {
  const fs::path out = scratch("rigid");
  fs::create_directories(out);
  const testing::CliResult by_default =
      run_cli({"run", "--duration-s", "12", "--out", (out / "default").string()});
  ASSERT_EQ(by_default.status, kExitOk) << by_default.err;
  EXPECT_NE(by_default.err.find("rigid path: "), std::string::npos) << by_default.err;
  EXPECT_EQ(by_default.err.find(" 0 final planes moved"), std::string::npos) << by_default.err;
  // The stream shows the planes where each solve puts them; `view = false`, as drawn.
  EXPECT_EQ(by_default.err.find(" 0 times a plane was shown again"), std::string::npos)
      << by_default.err;
  const std::string drawn = (out / "drawn.toml").string();
  std::ofstream(drawn) << "[rigid_path]\nview = false\n";
  const testing::CliResult as_drawn =
      run_cli({"run", "--config", drawn, "--duration-s", "12", "--out", (out / "drawn").string()});
  ASSERT_EQ(as_drawn.status, kExitOk) << as_drawn.err;
  EXPECT_NE(as_drawn.err.find(" 0 times a plane was shown again"), std::string::npos)
      << as_drawn.err;
  EXPECT_EQ(as_drawn.err.find(" 0 final planes moved"), std::string::npos) << as_drawn.err;
  const std::string off = (out / "off.toml").string();
  std::ofstream(off) << "[rigid_path]\nenabled = false\n";
  const testing::CliResult turned_off =
      run_cli({"run", "--config", off, "--duration-s", "12", "--out", (out / "off").string()});
  ASSERT_EQ(turned_off.status, kExitOk) << turned_off.err;
  EXPECT_EQ(turned_off.err.find("rigid path: "), std::string::npos) << turned_off.err;
  EXPECT_EQ(turned_off.err.find("localize.path_keyframes"), std::string::npos)
      << "nothing taken for it: " << turned_off.err;
  fs::remove_all(out);
}

TEST(RunCommand, TheConfigSetsTheWindowAndTheExtractionsAndEveryMistakeNamesItsKey) {
  const fs::path out = scratch("window");
  fs::create_directories(out);
  const auto config_with = [&](const std::string& name, const std::string& text) {
    const fs::path path = out / name;
    std::ofstream(path) << text;
    return path.string();
  };
  const std::string wide =
      config_with("wide.toml",
                  "[window]\ntiles_across = 9\nmax_samples = 40960\n[projection]\n"
                  "max_range_m = 50.0\n[mapper]\nextract_every_s = 0.25\n[free_space]\n"
                  "tiles_across = 4\ncell_size_m = 1.0\n[registry]\nmax_live_planes = 64\n"
                  "max_final_planes = 300\n");
  testing::CliResult result =
      run_cli({"run", "--config", wide, "--duration-s", "2", "--out", (out / "run").string()});
  ASSERT_EQ(result.status, kExitOk) << result.err;
  EXPECT_NE(result.err.find("samples of 40960"), std::string::npos) << result.err;
  EXPECT_NE(result.err.find("free_space.cells 0.03,"), std::string::npos) << "4 x 4 tiles of 2 KiB";
  EXPECT_NE(result.err.find("live planes "), std::string::npos) << result.err;
  EXPECT_NE(result.err.find(" of 64, changes of an update "), std::string::npos) << result.err;
  EXPECT_NE(result.err.find(" of 300\n"), std::string::npos) << "final planes: " << result.err;
  // Two seconds at a quarter second each: several extractions, where the default's 1 s
  // makes one or two.
  const std::size_t at = result.err.find(" extractions (");
  ASSERT_NE(at, std::string::npos) << result.err;
  const std::size_t first = result.err.rfind(' ', at - 1) + 1;
  EXPECT_GE(std::stoi(result.err.substr(first, at - first)), 5) << result.err;

  // The far-reaching window as shipped; and one whose pool is too small for its ring, whose
  // outer tiles leave early and say so.
  for (const char* shipped : {"far_reach.toml", "far_reach_rtk.toml"}) {
    result =
        run_cli({"run", "--config", (fs::path(BLOCKMAP_PROJECT_DIR) / "config" / shipped).string(),
                 "--duration-s", "1", "--out", (out / "far").string()});
    ASSERT_EQ(result.status, kExitOk) << shipped << ": " << result.err;
  }
  const std::string crowded =
      config_with("crowded.toml",
                  "[window]\ntiles_across = 9\ncore_tiles_across = 3\nmax_samples = 4096\n"
                  "reserve_samples = 512\n[projection]\nmax_range_m = 40.0\n");
  result = run_cli(
      {"run", "--config", crowded, "--duration-s", "6", "--out", (out / "crowded").string()});
  ASSERT_EQ(result.status, kExitOk) << result.err;
  EXPECT_NE(result.err.find("left early for room"), std::string::npos) << result.err;

  const std::vector<std::pair<std::string, std::string>> mistakes = {
      {"[window]\ntiles_across = 8\n", "window.tiles_across: must be odd"},
      {"[window]\ntile_size_ft = 8\n", "window.tile_size_ft: unknown key"},
      {"[window]\ntile_size_m = 7.0\n", "tile_size_m must be a whole number of 4-voxel blocks"},
      {"[window]\ncore_tiles_across = 4\n",
       "window.core_tiles_across: must be 0 (every tile) or odd"},
      {"[window]\ncore_tiles_across = 9\n",
       "window.core_tiles_across: must be 0 (every tile) or odd"},
      {"[window]\ncore_tiles_across = 3\nreserve_samples = 81920\n",
       "reserve_samples must be less than max_samples"},
      {"[projection]\nmax_range_m = -1.0\n", "projection.max_range_m: must be > 0"},
      {"[projection]\nmin_range_m = 5.0\nmax_range_m = 4.0\n",
       "projection.max_range_m: must be more than min_range_m"},
      {"[mapper]\nextract_every_s = 0\n", "mapper.extract_every_s: must be > 0"},
      {"[mapper]\nextract_every = 2\n", "mapper.extract_every: unknown key"},
      {"[mapper]\npose_lag_s = 59\n", "mapper.pose_lag_s: map_pose_lag_s must be >= 0 and 2 s"},
      {"[free_space]\ntiles_across = 65\n", "free_space.tiles_across: must be from 0 (off) to 64"},
      {"[free_space]\ncell_size_m = 0\n", "free_space.cell_size_m: must be > 0"},
      {"[free_space]\ncell_size_m = 9\n", "free_space: cell_size_m must be from 0.05 to 5"},
      {"[free_space]\ncells = 9\n", "free_space.cells: unknown key"},
      {"[rigid_path]\nenabled = true\nfix_sigma = 3\n", "rigid_path.fix_sigma: unknown key"},
      {"[rigid_path]\nview_change_m = 0\n", "rigid_path.view_change_m: must be > 0"},
      {"[rigid_path]\nrtk_fixed_sigma_m = -0.1\n", "rigid_path.rtk_fixed_sigma_m: must be > 0"},
      {"[registry]\nmax_final_planes = 0\n", "registry.max_final_planes: must be"},
      {"[registry]\nmax_live = 9\n", "registry.max_live: unknown key"},
      {"[rigid_path]\nenabled = true\n[mapper]\npose_lag_s = 4.0\n",
       "rigid_path needs scan matching"},
      {"[rigid_path]\nenabled = true\n[free_space]\ntiles_across = 16\n",
       "rigid_path would move the walls off the free-space grid"},
  };
  for (const auto& [text, expected] : mistakes) {
    result = run_cli({"run", "--config", config_with("bad.toml", text), "--duration-s", "1",
                      "--out", (out / "bad").string()});
    EXPECT_EQ(result.status, kExitUsage) << text;
    EXPECT_NE(result.err.find(expected), std::string::npos) << result.err;
    EXPECT_EQ(std::count(result.err.begin(), result.err.end(), '\n'), 1) << result.err;
  }
  fs::remove_all(out);
}

}  // namespace
}  // namespace blockmap::cli
