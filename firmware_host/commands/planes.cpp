// `blockmap planes CLOUD [--config FILE] [--out FILE] [--svg FILE [--top]]`: the plane list
// (docs/formats.md, plane list) of a point cloud file, and optionally a picture of the planes
// over the points. "seconds" is the detection alone: voxelizing, Hough transform, refinement
// and merging, not reading the file.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <nlohmann/json.hpp>
#include <ostream>
#include <string>
#include <vector>

#include "blockmap/core/arena.hpp"
#include "blockmap/hal/cloud/point_cloud_file.hpp"
#include "blockmap/hal/config/config_error.hpp"
#include "blockmap/hal/config/planes_config.hpp"
#include "blockmap/planes/plane_detector.hpp"
#include "cli.hpp"
#include "commands/cloud_planes.hpp"
#include "commands/commands.hpp"
#include "outputs/output_file.hpp"
#include "outputs/plane_json.hpp"
#include "outputs/plane_picture.hpp"

namespace blockmap::cli {
namespace {

struct PlanesOptions {
  std::string cloud;
  std::string config;
  std::string out;
  std::string svg;
  bool top_view = false;
  double budget_mib = kDefaultOfflineBudgetMiB;
};

// The picture, when asked for; false (and one line on err) when it cannot be written.
bool write_picture(const PlanesOptions& options, const hal::cloud::PointCloud& cloud,
                   std::span<const msg::PlanePatch> planes, std::ostream& err) {
  if (options.svg.empty()) {
    return true;
  }
  PictureView view;
  if (options.top_view) {
    view.azimuth_deg = -90.0;
    view.elevation_deg = 90.0;
  }
  // The points are stored relative to the cloud's origin: the planes join them there.
  std::vector<msg::PlanePatch> relative(planes.begin(), planes.end());
  for (msg::PlanePatch& plane : relative) {
    plane.d_m -= plane.normal.dot(cloud.origin_m);
    plane.centroid_m -= cloud.origin_m;
    for (std::size_t i = 0; i < plane.polygon_size; ++i) {
      plane.polygon_m[i] -= cloud.origin_m;
    }
  }
  const std::string problem = write_output(options.svg, [&](std::ostream& file) {
    write_plane_picture(file, cloud.points_m, relative, view);
  });
  if (!problem.empty()) {
    err << "blockmap: " << problem << '\n';
    return false;
  }
  return true;
}

}  // namespace

hal::cloud::PointCloud read_cloud_within(const std::string& path, double budget_mib) {
  return hal::cloud::read_point_cloud(path, mib_bytes(budget_mib));
}

CloudPlanes detect_cloud_planes(const hal::cloud::PointCloud& cloud, planes::PlanesConfig config,
                                const std::string& name, double budget_mib, std::ostream& err) {
  // Capacities no larger than this cloud needs: its samples are counted before the arena is
  // made (a city scan has about one sample per ten points).
  std::size_t samples = 0;
  {
    std::vector<planes::CellKey> keys(cloud.points_m.size());
    samples = planes::VoxelGrid::count_voxels(cloud.points_m, config.sample_size_m, keys);
  }
  config.max_samples = std::clamp<std::size_t>(samples, 1024, config.max_samples);
  config.max_patches =
      std::max(config.max_planes, std::min(config.max_patches, config.max_samples));

  const std::size_t needed = planes::PlaneDetector::arena_budget_bytes(config);
  if (needed > mib_bytes(budget_mib)) {
    throw hal::ConfigError(over_budget(needed, budget_mib));
  }
  Arena arena(needed);
  planes::PlaneDetector detector;
  detector.init(arena, config);
  arena.seal();
  const auto start = std::chrono::steady_clock::now();
  detector.add_points(cloud.points_m);
  const std::span<const msg::PlanePatch> detected = detector.detect();
  CloudPlanes result;
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  // Back into the file's frame (the detector worked relative to the cloud's origin).
  for (msg::PlanePatch plane : detected) {
    plane.d_m += plane.normal.dot(cloud.origin_m);
    plane.centroid_m += cloud.origin_m;
    for (std::size_t i = 0; i < plane.polygon_size; ++i) {
      plane.polygon_m[i] += cloud.origin_m;
    }
    result.planes.push_back(plane);
  }
  const planes::DetectionStats& stats = detector.stats();
  err << "planes: " << name << " (" << cloud.format << "): " << cloud.points_m.size() << " points";
  if (cloud.skipped_nonfinite + cloud.skipped_no_return > 0) {
    err << " (" << cloud.skipped_nonfinite << " non-finite and " << cloud.skipped_no_return
        << " no-return skipped)";
  }
  err << ", " << stats.samples << " samples, " << stats.sections << " sections, "
      << stats.section_planes << " section planes";
  if (stats.corner_walls > 0) {
    err << " and " << stats.corner_walls << " walls from the corner look";
  }
  err << " -> " << detected.size() << " planes in " << result.seconds * 1e3 << " ms; surfaces "
      << std::lround(stats.surface_noise_m * 1e3) << " mm thick (RMS); "
      << (arena.used_bytes() >> 20) << " MiB\n";
  if (stats.overflows > 0) {
    err << "planes: warning: " << stats.overflows
        << " sections, samples or planes beyond a capacity were left out (raise max_* in the "
           "config)\n";
  }
  if (stats.points_dropped > 0) {
    err << "planes: warning: " << stats.points_dropped
        << " points found no sample (raise max_samples)\n";
  }
  return result;
}

namespace {

int detect_planes(const PlanesOptions& options, std::ostream& out, std::ostream& err) {
  planes::PlanesConfig config;
  if (!options.config.empty()) {
    config = hal::config::load_planes_config(options.config);
  }
  const hal::cloud::PointCloud cloud = read_cloud_within(options.cloud, options.budget_mib);
  const CloudPlanes detected =
      detect_cloud_planes(cloud, config, options.cloud, options.budget_mib, err);
  const std::vector<msg::PlanePatch>& planes = detected.planes;
  nlohmann::json list = nlohmann::json::array();
  for (const msg::PlanePatch& plane : planes) {
    list.push_back(plane_json(plane));
  }
  const nlohmann::json document = {{"planes", list},
                                   {"points", cloud.points_m.size()},
                                   {"seconds", rounded_to(detected.seconds, 1e-6)}};
  if (!write_picture(options, cloud, planes, err)) {
    return kExitFailure;
  }
  if (options.out.empty()) {
    out << document.dump() << '\n';
    return kExitOk;
  }
  const std::string problem =
      write_output(options.out, [&](std::ostream& file) { file << document.dump() << '\n'; });
  if (!problem.empty()) {
    err << "blockmap: " << problem << '\n';
    return kExitFailure;
  }
  return kExitOk;
}

}  // namespace

Command add_planes_command(CLI::App& app) {
  CLI::App* command = app.add_subcommand(
      "planes",
      "The plane list (JSON) of a point cloud file: .ply, .pcd, .xyz, .bin (KITTI), .3d (3DTK)");
  auto options = std::make_shared<PlanesOptions>();
  command->add_option("CLOUD", options->cloud, "the point cloud file")->required();
  command->add_option("--config", options->config,
                      "a TOML file whose [planes] table sets the detector (config/planes.toml)");
  command->add_option("--out", options->out, "write the plane list here instead of stdout");
  command->add_option("--svg", options->svg,
                      "also draw the planes over the points into this SVG file (an oblique view)");
  command->add_flag("--top", options->top_view, "draw the SVG from straight above");
  add_budget_option(*command, options->budget_mib);
  return {command, [options](std::ostream& out, std::ostream& err) {
            try {
              return detect_planes(*options, out, err);
            } catch (const hal::ConfigError& error) {
              err << "blockmap: " << error.what() << '\n';
              return kExitUsage;
            } catch (const hal::cloud::CloudFileError& error) {
              err << "blockmap: " << error.what() << '\n';
              return kExitFailure;
            }
          }};
}

}  // namespace blockmap::cli
