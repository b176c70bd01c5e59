// `blockmap score MAP TRUTH [--json]`: a map made from a simulated run against the run's truth
// (docs/formats.md, truth.json). MAP is what `replay --out` wrote (path.csv or trajectory.csv,
// planes.json, buildings.json), TRUTH what `simulate --out` wrote (truth.json). The estimated path
// is laid onto the true one by the least-squares rigid motion (hal/sim/truth_score.hpp); the path
// error, the planes and the footprints are scored after it, and its shift is reported beside.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <nlohmann/json.hpp>
#include <ostream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "blockmap/core/angles.hpp"
#include "blockmap/hal/sim/truth_score.hpp"
#include "cli.hpp"
#include "commands/commands.hpp"
#include "commands/truth_trajectory.hpp"
#include "outputs/plane_json.hpp"

namespace blockmap::cli {
namespace {

namespace fs = std::filesystem;
using hal::sim::TimedPosition;

struct ScoreOptions {
  std::string map;
  std::string truth;
  bool json = false;
};

// A footprint with its shape's name, from buildings.json or truth.json.
struct Footprint {
  int id = 0;
  std::string shape;
  std::vector<Eigen::Vector2d> corners_m;
};

struct Truth {
  std::vector<TimedPosition> path;
  std::vector<hal::sim::TruthFace> faces;
  std::vector<Footprint> buildings;
};

struct Estimate {
  // The path the planes were laid with: path.csv's solved keyframes when the mapper solved a
  // rigid path, otherwise trajectory.csv's smoothed poses; and the scan matcher's own path
  // (path.csv's matched columns; empty without them), the local SLAM's shape before the
  // fixes placed it.
  std::vector<TimedPosition> path;
  std::vector<TimedPosition> matched;
  std::string path_file;
  std::vector<msg::PlanePatch> planes;
  std::vector<Footprint> buildings;
};

nlohmann::json read_json(const fs::path& path) {
  std::ifstream file(path);
  if (!file) {
    throw std::runtime_error(path.string() + ": cannot open");
  }
  try {
    return nlohmann::json::parse(file);
  } catch (const nlohmann::json::exception& error) {
    throw std::runtime_error(path.string() + ": not JSON (" + error.what() + ")");
  }
}

Eigen::Vector3d vec3_of(const nlohmann::json& value) {
  return {value.at(0).get<double>(), value.at(1).get<double>(), value.at(2).get<double>()};
}

std::vector<Eigen::Vector2d> footprint_of(const nlohmann::json& corners) {
  std::vector<Eigen::Vector2d> out;
  for (const nlohmann::json& corner : corners) {
    out.emplace_back(corner.at(0).get<double>(), corner.at(1).get<double>());
  }
  return out;
}

hal::sim::SurfaceKind surface_of(const std::string& kind) {
  if (kind == "wall") {
    return hal::sim::SurfaceKind::kWall;
  }
  return kind == "roof" ? hal::sim::SurfaceKind::kRoof : hal::sim::SurfaceKind::kGround;
}

Truth read_truth(const fs::path& path) {
  const nlohmann::json document = read_json(path);
  Truth truth;
  try {
    for (const localize::Pose3& pose : true_poses_of(document)) {
      truth.path.push_back({seconds_from_ns(pose.stamp_ns), {pose.x_m, pose.y_m, pose.z_m}});
    }
    for (const nlohmann::json& face : document.at("faces")) {
      hal::sim::TruthFace out;
      out.id = face.at("id").get<int>();
      out.kind = surface_of(face.at("kind").get<std::string>());
      out.normal = vec3_of(face.at("normal"));
      out.d_m = face.at("d").get<double>();
      for (const nlohmann::json& corner : face.at("corners")) {
        out.corners_m.push_back(vec3_of(corner));
      }
      out.returns = face.at("returns").get<std::uint64_t>();
      truth.faces.push_back(out);
    }
    for (const nlohmann::json& building : document.at("buildings")) {
      truth.buildings.push_back({building.at("id").get<int>(),
                                 building.at("shape").get<std::string>(),
                                 footprint_of(building.at("footprint"))});
    }
  } catch (const nlohmann::json::exception& error) {
    throw std::runtime_error(path.string() + ": not a truth.json (" + error.what() + ")");
  }
  return truth;
}

// trajectory.csv: t_s,x_m,y_m,z_m,roll_rad,pitch_rad,yaw_rad.
std::vector<TimedPosition> read_trajectory(const fs::path& path) {
  std::ifstream file(path);
  if (!file) {
    throw std::runtime_error(path.string() + ": cannot open");
  }
  std::vector<TimedPosition> path_m;
  std::string line;
  std::getline(file, line);  // the header
  for (std::size_t row = 2; std::getline(file, line); ++row) {
    std::istringstream fields(line);
    TimedPosition pose;
    char comma = 0;
    if (!(fields >> pose.t_s >> comma >> pose.position_m.x() >> comma >> pose.position_m.y() >>
          comma >> pose.position_m.z())) {
      throw std::runtime_error(path.string() + ":" + std::to_string(row) + ": not a pose row");
    }
    path_m.push_back(pose);
  }
  return path_m;
}

// The receiver's mean horizontal error over the run (truth_gps.csv beside truth.json: every
// epoch with a fix), and how many fixes; none when the file is not there.
struct ReceiverError {
  std::size_t fixes = 0;
  Eigen::Vector2d mean_m = Eigen::Vector2d::Zero();
};

ReceiverError read_receiver_error(const fs::path& path) {
  ReceiverError receiver;
  std::ifstream file(path);
  if (!file) {
    return receiver;
  }
  std::string line;
  std::getline(file, line);  // the header
  Eigen::Vector2d sum_m = Eigen::Vector2d::Zero();
  for (std::size_t row = 2; std::getline(file, line); ++row) {
    std::istringstream fields(line);
    double t_s = 0.0;
    Eigen::Vector3d antenna_m;
    Eigen::Vector3d error_m;
    double satellites = 0.0;
    double hdop = 0.0;
    int fix = 0;
    char comma = 0;
    if (!(fields >> t_s >> comma >> antenna_m.x() >> comma >> antenna_m.y() >> comma >>
          antenna_m.z() >> comma >> error_m.x() >> comma >> error_m.y() >> comma >> error_m.z() >>
          comma >> satellites >> comma >> hdop >> comma >> fix)) {
      throw std::runtime_error(path.string() + ":" + std::to_string(row) + ": not an epoch row");
    }
    if (fix == 1) {
      sum_m += error_m.head<2>();
      ++receiver.fixes;
    }
  }
  if (receiver.fixes > 0) {
    receiver.mean_m = sum_m / static_cast<double>(receiver.fixes);
  }
  return receiver;
}

// The height of `path_m` at `t_s`, linearly between its poses (its ends beyond them).
double height_at(const std::vector<TimedPosition>& path_m, double t_s) {
  const auto later =
      std::lower_bound(path_m.begin(), path_m.end(), t_s,
                       [](const TimedPosition& pose, double t) { return pose.t_s < t; });
  if (later == path_m.begin()) {
    return later->position_m.z();
  }
  if (later == path_m.end()) {
    return path_m.back().position_m.z();
  }
  const auto earlier = std::prev(later);
  const double span_s = later->t_s - earlier->t_s;
  const double f = span_s > 0.0 ? (t_s - earlier->t_s) / span_s : 0.0;
  return earlier->position_m.z() + f * (later->position_m.z() - earlier->position_m.z());
}

// path.csv: t_s,x_m,y_m,yaw_rad,matched_x_m,matched_y_m,matched_yaw_rad, its heights those of
// the trajectory at the same times (the planes were drawn at them).
void read_map_path(const fs::path& path, const std::vector<TimedPosition>& trajectory,
                   Estimate& estimate) {
  std::ifstream file(path);
  if (!file) {
    throw std::runtime_error(path.string() + ": cannot open");
  }
  std::string line;
  std::getline(file, line);  // the header
  for (std::size_t row = 2; std::getline(file, line); ++row) {
    std::istringstream fields(line);
    TimedPosition solved;
    TimedPosition matched;
    double yaw_rad = 0.0;
    char comma = 0;
    if (!(fields >> solved.t_s >> comma >> solved.position_m.x() >> comma >>
          solved.position_m.y() >> comma >> yaw_rad >> comma >> matched.position_m.x() >> comma >>
          matched.position_m.y())) {
      throw std::runtime_error(path.string() + ":" + std::to_string(row) + ": not a path row");
    }
    matched.t_s = solved.t_s;
    solved.position_m.z() = height_at(trajectory, solved.t_s);
    matched.position_m.z() = solved.position_m.z();
    estimate.path.push_back(solved);
    estimate.matched.push_back(matched);
  }
}

Estimate read_estimate(const fs::path& folder) {
  Estimate estimate;
  std::vector<TimedPosition> trajectory = read_trajectory(folder / "trajectory.csv");
  if (fs::exists(folder / "path.csv") && !trajectory.empty()) {
    estimate.path_file = "path.csv";
    read_map_path(folder / "path.csv", trajectory, estimate);
  } else {
    estimate.path_file = "trajectory.csv";
    estimate.path = std::move(trajectory);
  }
  try {
    estimate.planes = planes_from_json(read_json(folder / "planes.json"));
  } catch (const std::invalid_argument& error) {
    throw std::runtime_error((folder / "planes.json").string() + ": " + error.what());
  }
  const nlohmann::json buildings = read_json(folder / "buildings.json");
  try {
    for (const nlohmann::json& building : buildings.at("buildings")) {
      estimate.buildings.push_back({building.at("id").get<int>(),
                                    building.at("shape").get<std::string>(),
                                    footprint_of(building.at("footprint"))});
    }
  } catch (const nlohmann::json::exception& error) {
    throw std::runtime_error((folder / "buildings.json").string() + ": " + error.what());
  }
  return estimate;
}

// One true building against the footprint that overlaps it most ("" and 0 when none does).
struct BuildingMatch {
  int id = 0;
  std::string shape;
  std::string mapped_shape;
  double iou = 0.0;
};

struct BuildingScore {
  std::size_t buildings = 0;
  std::size_t shapes_right = 0;
  double mean_iou = 0.0;
  std::vector<BuildingMatch> each;
};

// Each true building against the estimated footprint that overlaps it most, laid onto the
// truth by the path's motion.
BuildingScore score_buildings(const Truth& truth, const Estimate& estimate,
                              const hal::sim::PathAlignment& alignment) {
  BuildingScore score;
  double iou_sum = 0.0;
  for (const Footprint& building : truth.buildings) {
    double best_iou = 0.0;
    std::string best_shape;
    for (const Footprint& mapped : estimate.buildings) {
      std::vector<Eigen::Vector2d> moved;
      for (const Eigen::Vector2d& corner_m : mapped.corners_m) {
        moved.push_back(alignment.apply(corner_m));
      }
      const double iou = hal::sim::footprint_iou(moved, building.corners_m);
      if (iou > best_iou) {
        best_iou = iou;
        best_shape = mapped.shape;
      }
    }
    ++score.buildings;
    score.shapes_right += best_shape == building.shape ? 1U : 0U;
    iou_sum += best_iou;
    score.each.push_back({building.id, building.shape, best_shape, best_iou});
  }
  score.mean_iou = score.buildings == 0 ? 0.0 : iou_sum / static_cast<double>(score.buildings);
  return score;
}

// A path's error after its alignment.
nlohmann::json path_error_json(const hal::sim::PathAlignment& path) {
  return {{"poses", path.pairs},
          {"rms_m", path.rms_m},
          {"median_m", path.median_m},
          {"max_m", path.max_m}};
}

// Everything scored, for one line each or one JSON object.
struct Score {
  std::string path_file;
  hal::sim::PathAlignment path;
  hal::sim::PathAlignment matched;
  ReceiverError receiver;
  hal::sim::PlaneScore planes;
  BuildingScore buildings;
};

// Issue 54's bound on where the map sits: no farther off than the receiver's mean error over
// the run, plus this.
constexpr double kOffsetAllowanceM = 0.3;

nlohmann::json score_json(const Score& score) {
  const hal::sim::PathAlignment& path = score.path;
  const hal::sim::PlaneScore& planes = score.planes;
  const BuildingScore& buildings = score.buildings;
  nlohmann::json path_json = path_error_json(path);
  path_json["file"] = score.path_file;
  path_json["alignment"] = {{"yaw_deg", path.yaw_rad / kRadiansPerDegree},
                            {"shift_m", {path.shift_m.x(), path.shift_m.y(), path.shift_m.z()}},
                            {"offset_m", {path.offset_m.x(), path.offset_m.y()}}};
  nlohmann::json receiver_json = nullptr;
  if (score.receiver.fixes > 0) {
    receiver_json = {{"fixes", score.receiver.fixes},
                     {"mean_error_m", {score.receiver.mean_m.x(), score.receiver.mean_m.y()}},
                     {"offset_within",
                      path.offset_m.norm() <= score.receiver.mean_m.norm() + kOffsetAllowanceM}};
  }
  nlohmann::json each = nlohmann::json::array();
  for (const BuildingMatch& match : buildings.each) {
    each.push_back({{"id", match.id},
                    {"shape", match.shape},
                    {"mapped_shape", match.mapped_shape},
                    {"iou", match.iou}});
  }
  return {{"path", path_json},
          {"receiver", receiver_json},
          {"matched_path", path_error_json(score.matched)},
          {"planes",
           {{"walls_found", planes.walls_found},
            {"walls", planes.walls_considered},
            {"faces_found", planes.faces_found},
            {"faces", planes.faces_considered},
            {"structural_real", planes.structural_real},
            {"structural", planes.structural_planes},
            {"faces_found_twice", planes.faces_reported_twice}}},
          {"buildings",
           {{"buildings", buildings.buildings},
            {"shapes_right", buildings.shapes_right},
            {"mean_iou", buildings.mean_iou},
            {"each", each}}}};
}

void print_score(std::ostream& out, const Score& score) {
  const hal::sim::PathAlignment& path = score.path;
  const hal::sim::PathAlignment& matched = score.matched;
  const hal::sim::PlaneScore& planes = score.planes;
  const BuildingScore& buildings = score.buildings;
  char line[240];
  std::snprintf(line, sizeof line,
                "path (%s): %zu poses; laid onto the truth by %.2f deg and (%.2f %.2f %.2f) m; "
                "after it %.3f m RMS, median %.3f m, worst %.3f m\n",
                score.path_file.c_str(), path.pairs, path.yaw_rad / kRadiansPerDegree,
                path.shift_m.x(), path.shift_m.y(), path.shift_m.z(), path.rms_m, path.median_m,
                path.max_m);
  out << line;
  std::snprintf(line, sizeof line, "where the map sits: its path %.2f m (%.2f %.2f) from the truth",
                path.offset_m.norm(), path.offset_m.x(), path.offset_m.y());
  out << line;
  if (score.receiver.fixes > 0) {
    const double mean_m = score.receiver.mean_m.norm();
    std::snprintf(line, sizeof line,
                  "; the receiver's mean error %.2f m (%.2f %.2f) over %zu fixes: %s\n", mean_m,
                  score.receiver.mean_m.x(), score.receiver.mean_m.y(), score.receiver.fixes,
                  path.offset_m.norm() <= mean_m + kOffsetAllowanceM ? "within it + 0.3 m"
                                                                     : "beyond it + 0.3 m");
    out << line;
  } else {
    out << '\n';
  }
  if (matched.pairs > 0) {
    std::snprintf(line, sizeof line,
                  "matched path (the scan matcher's, laid on by itself): %.3f m RMS, median "
                  "%.3f m, worst %.3f m\n",
                  matched.rms_m, matched.median_m, matched.max_m);
    out << line;
  }
  std::snprintf(line, sizeof line,
                "planes: walls found %zu of %zu, faces found %zu of %zu (3 deg, 0.15 m, faces "
                "with 200 returns); wall, roof and ground planes real %zu of %zu; faces found "
                "twice %zu\n",
                planes.walls_found, planes.walls_considered, planes.faces_found,
                planes.faces_considered, planes.structural_real, planes.structural_planes,
                planes.faces_reported_twice);
  out << line;
  std::snprintf(
      line, sizeof line, "buildings: mean footprint IoU %.3f over %zu, shapes right %zu of %zu\n",
      buildings.mean_iou, buildings.buildings, buildings.shapes_right, buildings.buildings);
  out << line;
}

int run_score(const ScoreOptions& options, std::ostream& out, std::ostream& err) {
  try {
    fs::path truth_path(options.truth);
    if (fs::is_directory(truth_path)) {
      truth_path /= "truth.json";
    }
    const Truth truth = read_truth(truth_path);
    const Estimate estimate = read_estimate(options.map);
    Score score;
    score.path_file = estimate.path_file;
    score.path = hal::sim::align_path(estimate.path, truth.path);
    const hal::sim::PathAlignment& path = score.path;
    if (path.pairs == 0) {
      err << "blockmap: score: " << options.map << '/' << estimate.path_file
          << " has no pose within the truth's time span\n";
      return kExitFailure;
    }
    std::vector<msg::PlanePatch> moved;
    for (const msg::PlanePatch& plane : estimate.planes) {
      moved.push_back(path.apply(plane));
    }
    score.planes = hal::sim::score_planes(truth.faces, moved);
    score.buildings = score_buildings(truth, estimate, path);
    if (!estimate.matched.empty()) {
      score.matched = hal::sim::align_path(estimate.matched, truth.path);
    }
    score.receiver = read_receiver_error(truth_path.parent_path() / "truth_gps.csv");
    if (options.json) {
      out << score_json(score).dump() << '\n';
    } else {
      print_score(out, score);
    }
    return kExitOk;
  } catch (const std::exception& error) {
    err << "blockmap: score: " << error.what() << '\n';
    return kExitFailure;
  }
}

}  // namespace

Command add_score_command(CLI::App& app) {
  auto options = std::make_shared<ScoreOptions>();
  CLI::App* sub = app.add_subcommand(
      "score",
      "Score a map made from a simulated run against the run's truth.json, after laying "
      "its path onto the true one (docs/formats.md, blockmap score)");
  sub->add_option("map", options->map,
                  "what replay --out wrote: path.csv (or trajectory.csv), planes.json, "
                  "buildings.json")
      ->required()
      ->check(CLI::ExistingDirectory);
  sub->add_option("truth", options->truth, "what simulate --out wrote (truth.json), or the file")
      ->required()
      ->check(CLI::ExistingPath);
  sub->add_flag("--json", options->json, "one JSON object instead of three lines");
  return {sub, [options](std::ostream& out, std::ostream& err) {
            return run_score(*options, out, err);
          }};
}

}  // namespace blockmap::cli
