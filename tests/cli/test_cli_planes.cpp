// `blockmap planes CLOUD`: the plane list (docs/formats.md, plane list) from a file, one-line
// errors and a non-zero status for bad files and bad configurations.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "cli.hpp"
#include "cli_runner.hpp"

namespace blockmap::cli {
namespace {

namespace fs = std::filesystem;

using Result = testing::CliResult;
using testing::run_cli;

class PlanesCommand : public ::testing::Test {
 protected:
  void SetUp() override {
    folder_ = fs::temp_directory_path() / ("blockmap_planes_" + std::to_string(::getpid()));
    fs::create_directories(folder_);
  }
  void TearDown() override { fs::remove_all(folder_); }

  // A floor (z = 0) and a wall (x = 3, 4 m high), as an ASCII PLY file.
  fs::path write_scene() {
    std::ostringstream body;
    std::size_t count = 0;
    for (double a = -3.0; a <= 3.0; a += 0.05) {
      for (double b = -3.0; b <= 3.0; b += 0.05) {
        body << a << ' ' << b << " 0\n";
        ++count;
      }
      for (double z = 0.05; z <= 4.0; z += 0.05) {
        body << "3 " << a << ' ' << z << '\n';
        ++count;
      }
    }
    fs::path path = folder_ / "scene.ply";
    std::ofstream file(path);
    file << "ply\nformat ascii 1.0\nelement vertex " << count
         << "\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
         << body.str();
    return path;
  }

  fs::path folder_;
};

TEST_F(PlanesCommand, PrintsThePlaneListContract) {
  const Result result = run_cli({"planes", write_scene().string()});
  ASSERT_EQ(result.status, 0) << result.err;
  const nlohmann::json list = nlohmann::json::parse(result.out);
  EXPECT_GT(list.at("points").get<int>(), 20000);
  EXPECT_GE(list.at("seconds").get<double>(), 0.0);
  ASSERT_EQ(list.at("planes").size(), 2u) << result.out;
  bool ground = false;
  bool wall = false;
  for (const nlohmann::json& plane : list.at("planes")) {
    const std::vector<double> n = plane.at("normal");
    EXPECT_NEAR(std::hypot(n[0], n[1], n[2]), 1.0, 1e-5);
    EXPECT_GE(plane.at("polygon").size(), 4u);
    EXPECT_GT(plane.at("support").get<double>(), 5000.0);
    EXPECT_LT(plane.at("rmse").get<double>(), 0.01);
    EXPECT_EQ(plane.at("centroid").size(), 3u);
    EXPECT_GE(plane.at("id").get<int>(), 1);
    const std::string kind = plane.at("kind");
    if (kind == "ground") {
      ground = std::abs(n[2]) > 0.999 && std::abs(plane.at("d").get<double>()) < 0.01;
    }
    if (kind == "wall") {
      wall = std::abs(n[0]) > 0.999 && std::abs(std::abs(plane.at("d").get<double>()) - 3.0) < 0.01;
    }
  }
  EXPECT_TRUE(ground);
  EXPECT_TRUE(wall);
}

TEST_F(PlanesCommand, WritesToOutAndReadsAConfig) {
  const fs::path config = folder_ / "planes.toml";
  std::ofstream(config) << "[planes]\nd_bin_m = 0.04\nmin_votes = 40\n";
  const fs::path out = folder_ / "planes.json";
  const Result result = run_cli(
      {"planes", write_scene().string(), "--config", config.string(), "--out", out.string()});
  ASSERT_EQ(result.status, 0) << result.err;
  EXPECT_TRUE(result.out.empty());
  std::ifstream file(out);
  EXPECT_EQ(nlohmann::json::parse(file).at("planes").size(), 2u);
}

std::size_t count_of(const std::string& text, const std::string& part) {
  std::size_t count = 0;
  for (std::size_t at = text.find(part); at != std::string::npos; at = text.find(part, at + 1)) {
    ++count;
  }
  return count;
}

TEST_F(PlanesCommand, DrawsThePlanesOverThePointsAsSvg) {
  const fs::path picture = folder_ / "planes.svg";
  const Result result = run_cli({"planes", write_scene().string(), "--svg", picture.string()});
  ASSERT_EQ(result.status, 0) << result.err;
  std::ifstream file(picture);
  const std::string svg((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
  EXPECT_EQ(svg.rfind("<svg xmlns='http://www.w3.org/2000/svg'", 0), 0u);
  EXPECT_EQ(svg.substr(svg.size() - 7), "</svg>\n");
  // One polygon per plane of the list, labelled by kind; the points as dots.
  EXPECT_EQ(count_of(svg, "<polygon"), nlohmann::json::parse(result.out).at("planes").size());
  EXPECT_EQ(count_of(svg, "<polygon class='wall'"), 1u);
  EXPECT_EQ(count_of(svg, "<polygon class='ground'"), 1u);
  EXPECT_GE(count_of(svg, "h1"), 20000u);  // every point of this 30,000-point budget
  // From above, the wall (x = 3, seen with +x to the right) is a line: its polygon's screen x
  // coordinates are all the same.
  const Result top =
      run_cli({"planes", write_scene().string(), "--svg", picture.string(), "--top"});
  ASSERT_EQ(top.status, 0) << top.err;
  std::ifstream top_file(picture);
  const std::string top_svg((std::istreambuf_iterator<char>(top_file)),
                            std::istreambuf_iterator<char>());
  const std::size_t wall = top_svg.find("<polygon class='wall'");
  ASSERT_NE(wall, std::string::npos);
  const std::size_t from = top_svg.find("points='", wall) + 8;
  std::istringstream pairs(top_svg.substr(from, top_svg.find('\'', from) - from));
  std::vector<double> xs;
  double x = 0.0;
  double y = 0.0;
  char comma = 0;
  while (pairs >> x >> comma >> y) {
    xs.push_back(x);
  }
  ASSERT_GE(xs.size(), 2u);
  EXPECT_LT(*std::max_element(xs.begin(), xs.end()) - *std::min_element(xs.begin(), xs.end()), 0.5);
  EXPECT_EQ(
      run_cli({"planes", write_scene().string(), "--svg", (folder_ / "missing" / "p.svg").string()})
          .status,
      1);
}

TEST_F(PlanesCommand, TheShippedConfigurationIsTheDefault) {
  const Result shipped =
      run_cli({"planes", write_scene().string(), "--config",
               (fs::path(BLOCKMAP_PROJECT_DIR) / "config/planes.toml").string()});
  const Result defaults = run_cli({"planes", write_scene().string()});
  ASSERT_EQ(shipped.status, 0) << shipped.err;
  nlohmann::json a = nlohmann::json::parse(shipped.out);
  nlohmann::json b = nlohmann::json::parse(defaults.out);
  EXPECT_EQ(a.at("planes"), b.at("planes"));
}

TEST_F(PlanesCommand, BadFilesAndConfigsAreOneLineAndANonZeroStatus) {
  const fs::path truncated = folder_ / "cut.bin";
  std::ofstream(truncated) << "0123456789";
  const fs::path bad_key = folder_ / "bad.toml";
  std::ofstream(bad_key) << "[planes]\nd_bin_ft = 0.1\n";
  const fs::path bad_value = folder_ / "bad_value.toml";
  std::ofstream(bad_value) << "[planes]\nsection_stride_m = 0.5\n";
  const std::vector<std::vector<std::string>> cases = {
      {"planes", truncated.string()},
      {"planes", (folder_ / "missing.ply").string()},
      {"planes", (folder_ / "cloud.las").string()},
      {"planes", write_scene().string(), "--config", bad_key.string()},
      {"planes", write_scene().string(), "--config", bad_value.string()},
  };
  for (const auto& args : cases) {
    const Result result = run_cli(args);
    EXPECT_NE(result.status, 0) << args[1];
    EXPECT_TRUE(result.out.empty());
    EXPECT_EQ(std::count(result.err.begin(), result.err.end(), '\n'), 1) << result.err;
    EXPECT_EQ(result.err.rfind("blockmap: ", 0), 0u) << result.err;
  }
}

}  // namespace
}  // namespace blockmap::cli
