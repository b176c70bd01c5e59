// `blockmap buildings INPUT [--config FILE] [--out FILE] [--vrml FILE] [--svg FILE]
// [--points CLOUD] [--geojson FILE --origin LAT,LON,HEIGHT]`: the buildings (docs/formats.md,
// buildings) of a plane list (docs/formats.md, plane list, as `planes` and `run` write it) or of
// a point cloud file (planes detected first).
#include <CLI/CLI.hpp>
#include <chrono>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "blockmap/buildings/building_fitter.hpp"
#include "blockmap/core/arena.hpp"
#include "blockmap/hal/cloud/point_cloud_file.hpp"
#include "blockmap/hal/config/buildings_config.hpp"
#include "blockmap/hal/config/config_error.hpp"
#include "blockmap/hal/config/planes_config.hpp"
#include "blockmap/hal/files.hpp"
#include "cli.hpp"
#include "commands/cloud_planes.hpp"
#include "commands/commands.hpp"
#include "commands/geodetic_option.hpp"
#include "outputs/building_outputs.hpp"
#include "outputs/output_file.hpp"
#include "outputs/plane_json.hpp"
#include "outputs/vrml.hpp"

namespace blockmap::cli {
namespace {

struct BuildingsOptions {
  std::string input;
  std::string config;
  std::string out;
  std::string vrml;
  std::string svg;
  std::string points;  // a cloud drawn under the --svg picture
  std::string geojson;
  std::string origin;
  double budget_mib = kDefaultOfflineBudgetMiB;
};

// Writes `write` into `path`, when one is given; false (and one line on err) when it cannot.
template <typename Write>
bool write_file(const std::string& path, std::ostream& err, Write write) {
  if (path.empty()) {
    return true;
  }
  if (const std::string problem = write_output(path, write); !problem.empty()) {
    err << "blockmap: " << problem << '\n';
    return false;
  }
  return true;
}

bool is_plane_list(const std::string& path) {
  return std::filesystem::path(path).extension() == ".json";
}

// A parsed JSON document takes about ten times its text: the plane list's file is refused
// beyond this share of the budget.
constexpr std::size_t kJsonBytesPerBudgetByte = 16;

// The plane list of a JSON file; throws std::invalid_argument with the file's name.
std::vector<msg::PlanePatch> read_plane_list(const std::string& path, double budget_mib) {
  std::string text;
  try {
    text = hal::read_whole_file(path, mib_bytes(budget_mib) / kJsonBytesPerBudgetByte);
  } catch (const hal::FileError& error) {
    throw std::invalid_argument(error.what());
  }
  try {
    return planes_from_json(nlohmann::json::parse(text));
  } catch (const nlohmann::json::exception& error) {
    throw std::invalid_argument(path + ": not JSON (" + std::string(error.what()) + ")");
  } catch (const std::invalid_argument& error) {
    throw std::invalid_argument(path + ": " + error.what());
  }
}

int fit_buildings(const BuildingsOptions& options, std::ostream& out, std::ostream& err) {
  std::optional<hal::LocalEnuFrame> frame;
  if (!options.geojson.empty()) {
    const std::optional<hal::GeodeticPoint> origin = parse_origin(options.origin);
    if (!origin) {
      err << "blockmap: "
          << (options.origin.empty() ? "--geojson needs --origin LAT,LON,HEIGHT"
                                     : kOriginFormatError)
          << '\n';
      return kExitUsage;
    }
    frame.emplace(*origin);
  }
  buildings::BuildingsConfig config;
  planes::PlanesConfig planes_config;
  if (!options.config.empty()) {
    config = hal::config::load_buildings_config(options.config);
    planes_config = hal::config::load_planes_config(options.config);
  }
  std::vector<msg::PlanePatch> planes;
  hal::cloud::PointCloud cloud;
  if (is_plane_list(options.input)) {
    planes = read_plane_list(options.input, options.budget_mib);
  } else {
    cloud = read_cloud_within(options.input, options.budget_mib);
    planes =
        detect_cloud_planes(cloud, planes_config, options.input, options.budget_mib, err).planes;
  }
  if (!options.points.empty()) {
    cloud = read_cloud_within(options.points, options.budget_mib);
  }

  const std::size_t needed = buildings::BuildingFitter::arena_bytes(config);
  if (needed > mib_bytes(options.budget_mib)) {
    err << "blockmap: " << over_budget(needed, options.budget_mib) << '\n';
    return kExitUsage;
  }
  Arena arena(needed);
  buildings::BuildingFitter fitter;
  fitter.init(arena, config);
  arena.seal();
  const auto start = std::chrono::steady_clock::now();
  const std::span<const buildings::Building> buildings = fitter.fit(planes);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  err << "buildings: " << planes.size() << " planes, " << fitter.counters().walls_used
      << " walls -> " << buildings.size() << " buildings in " << seconds * 1e3 << " ms\n";
  if (fitter.counters().walls_dropped_full + fitter.counters().buildings_dropped_full > 0) {
    err << "buildings: warning: walls or buildings beyond max_walls / max_buildings were left "
           "out\n";
  }

  // The cloud's points are stored relative to its origin; the picture wants them in the
  // planes' frame, as floats near the data.
  std::vector<Eigen::Vector3f> points;
  points.reserve(cloud.points_m.size());
  for (const Eigen::Vector3f& p : cloud.points_m) {
    points.emplace_back((p.cast<double>() + cloud.origin_m).cast<float>());
  }
  const bool written =
      write_file(options.vrml, err,
                 [&](std::ostream& file) { write_vrml(file, planes, {}, buildings); }) &&
      write_file(
          options.svg, err,
          [&](std::ostream& file) { write_buildings_picture(file, points, planes, buildings); }) &&
      write_file(options.geojson, err, [&](std::ostream& file) {
        file << footprints_geojson(buildings, *frame).dump() << '\n';
      });
  if (!written) {
    return kExitFailure;
  }
  const nlohmann::json document = buildings_json(buildings);
  if (options.out.empty()) {
    out << document.dump() << '\n';
    return kExitOk;
  }
  return write_file(options.out, err, [&](std::ostream& file) { file << document.dump() << '\n'; })
             ? kExitOk
             : kExitFailure;
}

}  // namespace

Command add_buildings_command(CLI::App& app) {
  CLI::App* command = app.add_subcommand(
      "buildings",
      "Buildings (JSON) from a plane list (.json) or a point cloud file: walls grouped into "
      "footprints, fitted to rectangle, L and T models, unseen walls added as virtual walls");
  auto options = std::make_shared<BuildingsOptions>();
  command->add_option("INPUT", options->input, "a plane list (.json) or a point cloud file")
      ->required();
  command->add_option("--config", options->config,
                      "a TOML file whose [buildings] (and [planes]) tables set the fitter "
                      "(config/buildings.toml)");
  command->add_option("--out", options->out, "write the buildings here instead of stdout");
  command->add_option("--vrml", options->vrml,
                      "also write a VRML 2.0 map: planes, and walls seen dark, virtual light");
  command->add_option("--svg", options->svg, "also draw a top view of it all into this SVG");
  command->add_option("--points", options->points,
                      "draw this point cloud under the --svg picture (run/replay --cloud "
                      "writes cloud.ply); a cloud INPUT draws its own");
  command->add_option("--geojson", options->geojson,
                      "also write the footprints as GeoJSON in WGS-84 (needs --origin)");
  command->add_option("--origin", options->origin,
                      "where the input's frame is on Earth: LAT,LON,HEIGHT (degrees, metres)");
  add_budget_option(*command, options->budget_mib);
  return {command, [options](std::ostream& out, std::ostream& err) {
            try {
              return fit_buildings(*options, out, err);
            } catch (const hal::ConfigError& error) {
              err << "blockmap: " << error.what() << '\n';
              return kExitUsage;
            } catch (const hal::cloud::CloudFileError& error) {
              err << "blockmap: " << error.what() << '\n';
              return kExitFailure;
            } catch (const std::invalid_argument& error) {
              err << "blockmap: " << error.what() << '\n';
              return kExitFailure;
            }
          }};
}

}  // namespace blockmap::cli
