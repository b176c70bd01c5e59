// The maps open in the tools people look at them with: the VRML map in view3dscene
// (Debian's VRML/X3D viewer: its parser must accept every line, and its rendering from the
// map's first viewpoint must show the building in the middle of the picture), and the GeoJSON
// footprints in GDAL (valid polygons whose geodesic area and position, computed by GDAL's own
// geodesy, match the local-frame footprint). scripts/install-deps test installs the tools;
// without them the tests skip, saying which tool is missing.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
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

using testing::read_file;
using testing::run_cli;

struct CommandResult {
  int status = -1;
  std::string output;  // stdout and stderr together
};

CommandResult run_command(const std::string& command) {
  CommandResult result;
  std::FILE* pipe = ::popen((command + " 2>&1").c_str(), "r");
  if (pipe == nullptr) {
    return result;
  }
  char buffer[4096];
  std::size_t n = 0;
  while ((n = std::fread(buffer, 1, sizeof buffer, pipe)) > 0) {
    result.output.append(buffer, n);
  }
  const int status = ::pclose(pipe);
  result.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return result;
}

bool on_path(const std::string& tool) {
  return run_command("command -v " + tool + " > /dev/null").status == 0;
}

// A 24-bit uncompressed BMP (what view3dscene's --screenshot writes for a .bmp name).
struct Picture {
  std::size_t width = 0;
  std::size_t height = 0;
  std::vector<unsigned char> bgr;  // top row first

  [[nodiscard]] const unsigned char* pixel(std::size_t x, std::size_t y) const {
    return &bgr[(y * width + x) * 3];
  }
};

bool read_bmp(const fs::path& path, Picture& picture) {
  const std::string bytes = read_file(path);
  const auto u32 = [&](std::size_t at) {
    return static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[at])) |
           static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[at + 1])) << 8U |
           static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[at + 2])) << 16U |
           static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[at + 3])) << 24U;
  };
  if (bytes.size() < 54 || bytes[0] != 'B' || bytes[1] != 'M' || bytes[28] != 24) {
    return false;
  }
  const std::uint32_t offset = u32(10);
  picture.width = u32(18);
  const auto stored_height = static_cast<std::int32_t>(u32(22));
  picture.height = static_cast<std::size_t>(std::abs(stored_height));
  const std::size_t row_bytes = (picture.width * 3 + 3) / 4 * 4;
  if (bytes.size() < offset + row_bytes * picture.height) {
    return false;
  }
  picture.bgr.resize(picture.width * picture.height * 3);
  for (std::size_t y = 0; y < picture.height; ++y) {
    // Rows are stored bottom-up unless the height is negative.
    const std::size_t stored_row = stored_height > 0 ? picture.height - 1 - y : y;
    const std::size_t from = offset + stored_row * row_bytes;
    const std::size_t to = y * picture.width * 3;
    std::copy_n(bytes.begin() + static_cast<std::ptrdiff_t>(from), picture.width * 3,
                picture.bgr.begin() + static_cast<std::ptrdiff_t>(to));
  }
  return true;
}

// "name (Type) = value" lines of ogrinfo's answer to a SELECT.
std::map<std::string, double> ogr_fields(const std::string& answer) {
  std::map<std::string, double> fields;
  std::istringstream lines(answer);
  std::string line;
  while (std::getline(lines, line)) {
    const std::size_t open = line.find(" (");
    const std::size_t equals = line.find(") = ");
    if (open == std::string::npos || equals == std::string::npos) {
      continue;
    }
    const std::size_t start = line.find_first_not_of(' ');
    fields[line.substr(start, open - start)] = std::strtod(line.c_str() + equals + 4, nullptr);
  }
  return fields;
}

class MapViewers : public ::testing::Test {
 protected:
  void SetUp() override {
    folder_ = fs::temp_directory_path() / ("blockmap_viewers_" + std::to_string(::getpid()));
    fs::create_directories(folder_);
  }
  void TearDown() override { fs::remove_all(folder_); }

  // Two walls of a 20 x 12 m building (the other two never seen) and its roof, `offset_m`
  // east and north of the origin.
  fs::path write_plane_list(const Eigen::Vector2d& offset_m) {
    using ::blockmap::testing::flat_roof;
    using ::blockmap::testing::vertical_plane;
    const Eigen::Vector2d& o = offset_m;
    nlohmann::json list = nlohmann::json::array();
    list.push_back(plane_json(vertical_plane(o + Eigen::Vector2d(0.2, 0.0),
                                             o + Eigen::Vector2d(19.8, 0.0), 0.0, 9.0, 1)));
    list.push_back(plane_json(vertical_plane(o + Eigen::Vector2d(20.0, 0.2),
                                             o + Eigen::Vector2d(20.0, 11.8), 0.0, 9.0, 2)));
    list.push_back(plane_json(
        flat_roof(o + Eigen::Vector2d(1.0, 1.0), o + Eigen::Vector2d(19.0, 11.0), 9.5, 3)));
    fs::path path = folder_ / "planes.json";
    std::ofstream(path) << nlohmann::json{{"planes", list}, {"points", 0}, {"seconds", 0}}.dump();
    return path;
  }

  fs::path folder_;
};

TEST_F(MapViewers, View3dsceneReadsTheMapAndItsFirstViewpointShowsTheBuilding) {
  for (const char* tool : {"view3dscene", "tovrmlx3d", "xvfb-run"}) {
    if (!on_path(tool)) {
      GTEST_SKIP() << tool << " is not installed (scripts/install-deps test installs it)";
    }
  }
  const fs::path map = folder_ / "map.wrl";
  const testing::CliResult made =
      run_cli({"buildings", write_plane_list({40.0, -25.0}).string(), "--vrml", map.string()});
  ASSERT_EQ(made.status, kExitOk) << made.err;

  // The viewer's parser: it reports anything it cannot read ("Warning: VRML/X3D: ...") and
  // writes back what it understood, the viewpoints and both kinds of building wall included.
  const CommandResult parsed =
      run_command("tovrmlx3d " + map.string() + " 2>&1 >" + (folder_ / "parsed.wrl").string());
  EXPECT_EQ(parsed.status, 0);
  EXPECT_EQ(parsed.output, "") << "view3dscene's parser complained";
  const std::string written = read_file(folder_ / "parsed.wrl");
  EXPECT_NE(written.find("\"overview\""), std::string::npos);
  EXPECT_NE(written.find("\"top\""), std::string::npos);

  // A rendering in a virtual X display, from the map's first viewpoint ("overview").
  const fs::path shot = folder_ / "shot.bmp";
  const CommandResult rendered =
      run_command("xvfb-run -a -s '-screen 0 640x480x24' view3dscene " + map.string() +
                  " --screenshot 0 " + shot.string() + " --geometry 320x240");
  ASSERT_EQ(rendered.status, 0) << rendered.output;
  Picture picture;
  ASSERT_TRUE(read_bmp(shot, picture)) << "no 24-bit BMP at " << shot;
  ASSERT_EQ(picture.width, 320u);
  ASSERT_EQ(picture.height, 240u);
  // What is not the background: the building's walls and roof. The viewpoint frames the map,
  // so they are a good part of the picture, around its middle (a viewer's default camera at
  // the origin would see nothing, or the building at the edge).
  const unsigned char* background = picture.pixel(0, 0);
  double drawn = 0.0;
  double sum_x = 0.0;
  double sum_y = 0.0;
  for (std::size_t y = 0; y < picture.height; ++y) {
    for (std::size_t x = 0; x < picture.width; ++x) {
      const unsigned char* p = picture.pixel(x, y);
      const int difference = std::abs(p[0] - background[0]) + std::abs(p[1] - background[1]) +
                             std::abs(p[2] - background[2]);
      if (difference > 24) {
        drawn += 1.0;
        sum_x += static_cast<double>(x);
        sum_y += static_cast<double>(y);
      }
    }
  }
  const auto width = static_cast<double>(picture.width);
  const auto height = static_cast<double>(picture.height);
  const double share = drawn / (width * height);
  EXPECT_GT(share, 0.05) << "the building covers too little of the picture";
  ASSERT_GT(drawn, 0.0);
  EXPECT_NEAR(sum_x / drawn, 0.5 * width, 0.2 * width);
  EXPECT_NEAR(sum_y / drawn, 0.5 * height, 0.2 * height);
}

TEST_F(MapViewers, GdalReadsValidFootprintsWhereTheLocalFrameSays) {
  if (!on_path("ogrinfo")) {
    GTEST_SKIP() << "ogrinfo (gdal-bin) is not installed (scripts/install-deps test installs it)";
  }
  // The building 300 m east and 200 m north of the origin.
  const fs::path geojson = folder_ / "footprints.geojson";
  const testing::CliResult made =
      run_cli({"buildings", write_plane_list({300.0, 200.0}).string(), "--geojson",
               geojson.string(), "--origin", "40.443,-79.943,280"});
  ASSERT_EQ(made.status, kExitOk) << made.err;
  // The footprint in the local frame (the JSON on stdout): its area and centroid.
  const nlohmann::json building = nlohmann::json::parse(made.out)["buildings"][0];
  ASSERT_EQ(building["footprint"].size(), 4u);
  double twice_area = 0.0;
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
  for (std::size_t i = 0; i < 4; ++i) {
    const nlohmann::json& a = building["footprint"][i];
    const nlohmann::json& b = building["footprint"][(i + 1) % 4];
    twice_area += a[0].get<double>() * b[1].get<double>() - b[0].get<double>() * a[1].get<double>();
    centroid += 0.25 * Eigen::Vector2d(a[0].get<double>(), a[1].get<double>());
  }
  ASSERT_GT(twice_area, 0.0);  // counter-clockwise, as RFC 7946 asks of an outer ring

  // GDAL's reading of the file (SQLite dialect, SpatiaLite's functions; 1 = on the ellipsoid).
  const CommandResult answer = run_command(
      "ogrinfo -ro -q -dialect SQLite -sql \"SELECT COUNT(*) AS n, "
      "SUM(ST_IsValid(geometry)) AS valid, SUM(ST_Area(geometry, 1)) AS area_m2, "
      "MAX(ST_Distance(ST_Centroid(geometry), MakePoint(-79.943, 40.443, 4326), 1)) AS from_m, "
      "MAX(ST_X(ST_Centroid(geometry))) AS lon, MAX(ST_Y(ST_Centroid(geometry))) AS lat "
      "FROM footprints\" " +
      geojson.string());
  ASSERT_EQ(answer.status, 0) << answer.output;
  std::map<std::string, double> fields = ogr_fields(answer.output);
  ASSERT_EQ(fields.count("n"), 1u) << answer.output;
  EXPECT_EQ(fields["n"], 1.0);
  EXPECT_EQ(fields["valid"], 1.0) << answer.output;
  EXPECT_NEAR(fields["area_m2"], 0.5 * twice_area, 0.005 * 0.5 * twice_area);
  EXPECT_NEAR(fields["from_m"], centroid.norm(), 0.5);
  EXPECT_GT(fields["lon"], -79.943);  // east of the origin
  EXPECT_GT(fields["lat"], 40.443);   // and north
}

}  // namespace
}  // namespace blockmap::cli
