// `blockmap buildings INPUT`: the buildings (docs/formats.md, buildings) from a plane list or a
// cloud, the VRML map, the SVG picture and GeoJSON footprints; one-line errors and a non-zero
// status for bad input.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "cli.hpp"
#include "cli_runner.hpp"
#include "outputs/plane_json.hpp"
#include "synthetic_walls.hpp"

namespace blockmap::cli {
namespace {

namespace fs = std::filesystem;

using Result = testing::CliResult;
using testing::read_file;
using testing::run_cli;

class BuildingsCommand : public ::testing::Test {
 protected:
  void SetUp() override {
    folder_ = fs::temp_directory_path() / ("blockmap_buildings_" + std::to_string(::getpid()));
    fs::create_directories(folder_);
  }
  void TearDown() override { fs::remove_all(folder_); }

  // A plane list (4.1) with two walls of a 20 x 12 m building and its roof.
  fs::path write_plane_list() {
    nlohmann::json list = nlohmann::json::array();
    list.push_back(
        plane_json(::blockmap::testing::vertical_plane({0.2, 0.0}, {19.8, 0.0}, 0.0, 9.0, 1)));
    list.push_back(
        plane_json(::blockmap::testing::vertical_plane({20.0, 0.2}, {20.0, 11.8}, 0.0, 9.0, 2)));
    list.push_back(plane_json(::blockmap::testing::flat_roof({1.0, 1.0}, {19.0, 11.0}, 9.5, 3)));
    fs::path path = folder_ / "planes.json";
    std::ofstream(path) << nlohmann::json{{"planes", list}, {"points", 0}, {"seconds", 0}}.dump();
    return path;
  }

  fs::path folder_;
};

TEST_F(BuildingsCommand, CompletesARectangleFromTwoWallsWithEveryOutput) {
  const fs::path svg = folder_ / "top.svg";
  const fs::path vrml = folder_ / "map.wrl";
  const fs::path geojson = folder_ / "footprints.geojson";
  const Result result =
      run_cli({"buildings", write_plane_list().string(), "--svg", svg.string(), "--vrml",
               vrml.string(), "--geojson", geojson.string(), "--origin", "40.443,-79.943,280"});
  ASSERT_EQ(result.status, kExitOk) << result.err;
  const nlohmann::json document = nlohmann::json::parse(result.out);
  ASSERT_EQ(document["buildings"].size(), 1u);
  const nlohmann::json& building = document["buildings"][0];
  EXPECT_EQ(building["shape"], "rect");
  EXPECT_EQ(building["footprint"].size(), 4u);
  EXPECT_NEAR(building["height"].get<double>(), 9.5, 1e-9);  // from the roof
  std::size_t virtual_walls = 0;
  for (const nlohmann::json& wall : building["walls"]) {
    for (const char* key : {"p0", "p1", "z0", "z1", "virtual", "plane"}) {
      EXPECT_TRUE(wall.contains(key)) << key;
    }
    virtual_walls += wall["virtual"].get<bool>() ? 1U : 0U;
    EXPECT_EQ(wall["plane"].is_null(), wall["virtual"].get<bool>());
  }
  EXPECT_EQ(virtual_walls, 2u);
  // The VRML map draws the walls (two of each colour) and the SVG the footprint.
  const std::string map = read_file(vrml);
  EXPECT_EQ(map.rfind("#VRML V2.0 utf8\n", 0), 0u);
  EXPECT_NE(map.find("building 1 virtual wall"), std::string::npos);
  EXPECT_NE(read_file(svg).find("<polygon"), std::string::npos);
  // GeoJSON: a closed ring, longitude first, within metres of the origin.
  const nlohmann::json features = nlohmann::json::parse(read_file(geojson));
  ASSERT_EQ(features["features"].size(), 1u);
  const nlohmann::json& ring = features["features"][0]["geometry"]["coordinates"][0];
  ASSERT_EQ(ring.size(), 5u);
  EXPECT_EQ(ring.front(), ring.back());
  for (const nlohmann::json& vertex : ring) {
    EXPECT_NEAR(vertex[0].get<double>(), -79.943, 3e-4);  // 20 m east is 2.4e-4 degrees
    EXPECT_NEAR(vertex[1].get<double>(), 40.443, 2e-4);
  }
}

TEST_F(BuildingsCommand, TakesAPointCloudToo) {
  // Two walls of a building, 10 x 6 m and 5 m high, as an ASCII PLY file.
  std::ostringstream body;
  std::size_t count = 0;
  for (double s = 0.0; s <= 10.0; s += 0.05) {
    for (double z = 0.0; z <= 5.0; z += 0.05) {
      body << s << " 0 " << z << '\n' << "10 " << 0.6 * s << ' ' << z << '\n';
      count += 2;
    }
  }
  const fs::path cloud = folder_ / "walls.ply";
  std::ofstream(cloud) << "ply\nformat ascii 1.0\nelement vertex " << count
                       << "\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
                       << body.str();
  const Result result = run_cli({"buildings", cloud.string()});
  ASSERT_EQ(result.status, kExitOk) << result.err;
  const nlohmann::json document = nlohmann::json::parse(result.out);
  ASSERT_EQ(document["buildings"].size(), 1u);
  EXPECT_EQ(document["buildings"][0]["shape"], "rect");
}

TEST_F(BuildingsCommand, BadInputIsOneLineAndANonZeroStatus) {
  const fs::path not_json = folder_ / "broken.json";
  std::ofstream(not_json) << "{\"planes\": [";
  const fs::path bad_plane = folder_ / "bad_plane.json";
  std::ofstream(bad_plane) << R"({"planes": [{"id": 1, "kind": "wall", "normal": [0, 2, 0],)"
                           << R"( "d": 1, "polygon": []}]})";
  const fs::path bad_kind = folder_ / "bad_kind.json";
  std::ofstream(bad_kind) << R"({"planes": [{"id": 1, "kind": "window"}]})";
  const fs::path bad_config = folder_ / "bad.toml";
  std::ofstream(bad_config) << "[buildings]\nfit_tolerance_ft = 3\n";
  const std::vector<std::vector<std::string>> cases = {
      {"buildings", (folder_ / "missing.json").string()},
      {"buildings", not_json.string()},
      {"buildings", bad_plane.string()},
      {"buildings", bad_kind.string()},
      {"buildings", write_plane_list().string(), "--config", bad_config.string()},
      {"buildings", write_plane_list().string(), "--geojson", (folder_ / "f.geojson").string()},
      {"buildings", write_plane_list().string(), "--out", (folder_ / "no" / "b.json").string()},
  };
  for (const auto& args : cases) {
    const Result result = run_cli(args);
    EXPECT_NE(result.status, 0) << args[1];
    // One line of reason (a statistics line may come before it when the fit ran).
    EXPECT_EQ(result.err.back(), '\n');
    EXPECT_EQ(result.err.find("blockmap: "), result.err.rfind("blockmap: ")) << result.err;
    EXPECT_NE(result.err.find("blockmap: "), std::string::npos) << result.err;
  }
  EXPECT_NE(run_cli({"buildings", bad_plane.string()}).err.find("planes[0].normal"),
            std::string::npos);
  EXPECT_NE(run_cli({"buildings", write_plane_list().string(), "--config", bad_config.string()})
                .err.find("fit_tolerance_ft"),
            std::string::npos);
}

}  // namespace
}  // namespace blockmap::cli
