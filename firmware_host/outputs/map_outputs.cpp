#include "outputs/map_outputs.hpp"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <vector>

#include <nlohmann/json.hpp>

#include "blockmap/hal/protocol/plane_stream.hpp"
#include "outputs/building_outputs.hpp"
#include "outputs/output_file.hpp"
#include "outputs/plane_json.hpp"
#include "outputs/vrml.hpp"

namespace blockmap::cli {
namespace {

namespace fs = std::filesystem;
namespace stream = hal::protocol::plane_stream;

// The VRML map's path: every 10th pose (2.5 s at the filter's 4 Hz), and never more than
// kMaxPathPoses of them: a long run's path is thinned to every other point when it fills, so
// that the outputs' memory does not grow with the run (a day's run keeps a point every few
// tens of metres, plenty for a picture).
constexpr std::size_t kPathDecimation = 10;
constexpr std::size_t kMaxPathPoses = 8192;
constexpr const char* kTrajectoryHeader = "t_s,x_m,y_m,z_m,roll_rad,pitch_rad,yaw_rad\n";

std::uintmax_t whole_lines_bytes(const fs::path& path) {
  std::ifstream file(path, std::ios::binary);
  const std::string text((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
  const std::size_t last = text.rfind('\n');
  return last == std::string::npos ? 0 : last + 1;
}

std::uintmax_t whole_records_bytes(const fs::path& path) {
  std::ifstream file(path, std::ios::binary);
  const std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(file)),
                                        std::istreambuf_iterator<char>());
  if (bytes.size() < stream::kMagic.size() ||
      !std::equal(stream::kMagic.begin(), stream::kMagic.end(), bytes.begin())) {
    return 0;
  }
  std::size_t offset = stream::kMagic.size();
  stream::UpdateHeader header;
  while (stream::decode_update(std::span(bytes).subspan(offset), header,
                               [](const stream::PlaneChange& /*change*/) {}) ==
         stream::ParseError::kNone) {
    offset += header.length;
  }
  return offset;
}

}  // namespace

std::string MapOutputs::open(const fs::path& dir, std::size_t max_changes,
                             const std::string& udp_destination, bool append) {
  dir_ = dir;
  std::error_code error;
  fs::create_directories(dir, error);
  if (error) {
    return "cannot create " + dir.string() + ": " + error.message();
  }
  // What a run before wrote, up to its last whole line or record (0: nothing to carry on).
  const std::uintmax_t jsonl_kept = append ? whole_lines_bytes(dir / "planes.jsonl") : 0;
  const std::uintmax_t buildings_kept = append ? whole_lines_bytes(dir / "buildings.jsonl") : 0;
  const std::uintmax_t trajectory_kept = append ? whole_lines_bytes(dir / "trajectory.csv") : 0;
  const std::uintmax_t binary_kept = append ? whole_records_bytes(dir / "planes.bin") : 0;
  const auto open_file = [&](std::ofstream& file, const char* name, std::uintmax_t kept,
                             std::ios::openmode mode) {
    if (kept > 0) {
      fs::resize_file(dir / name, kept, error);
      mode |= std::ios::app;
    }
    file.open(dir / name, mode);
    return !error && static_cast<bool>(file);
  };
  if (!open_file(jsonl_, "planes.jsonl", jsonl_kept, std::ios::out) ||
      !open_file(buildings_jsonl_, "buildings.jsonl", buildings_kept, std::ios::out) ||
      !open_file(binary_, "planes.bin", binary_kept, std::ios::out | std::ios::binary) ||
      !open_file(trajectory_, "trajectory.csv", trajectory_kept, std::ios::out)) {
    return "cannot write into " + dir.string();
  }
  if (binary_kept == 0) {
    binary_.write(reinterpret_cast<const char*>(stream::kMagic.data()), stream::kMagic.size());
    binary_bytes_ = stream::kMagic.size();
  }
  trajectory_out_ = &trajectory_;
  files_ = true;
  path_.reserve(kMaxPathPoses);
  if (trajectory_kept == 0) {
    *trajectory_out_ << kTrajectoryHeader;
  }
  record_.resize(stream::kRecordHeaderBytes + max_changes * stream::kMaxEntryBytes);
  if (!udp_destination.empty()) {
    return udp_.open(udp_destination);
  }
  return {};
}

void MapOutputs::open_trajectory_only(std::ostream& trajectory) {
  trajectory_out_ = &trajectory;
  *trajectory_out_ << kTrajectoryHeader;
}

std::string MapOutputs::open_trajectory_only(const fs::path& dir) {
  dir_ = dir;
  std::error_code error;
  fs::create_directories(dir, error);
  trajectory_.open(dir / "trajectory.csv");
  if (error || !trajectory_) {
    return "cannot write " + (dir / "trajectory.csv").string();
  }
  open_trajectory_only(trajectory_);
  return {};
}

void MapOutputs::write_update(TimestampNs stamp_ns, std::span<const msg::PlaneChange> changes) {
  if (changes.empty() || !files_) {
    return;
  }
  ++updates_;
  jsonl_ << plane_update_json(stamp_ns, changes).dump() << '\n';
  const std::size_t bytes = stream::encode_update(stamp_ns, changes, record_);
  binary_.write(reinterpret_cast<const char*>(record_.data()), static_cast<std::streamsize>(bytes));
  binary_bytes_ += bytes;
  if (udp_.is_open()) {
    static_cast<void>(udp_.send(std::span<const std::uint8_t>(record_.data(), bytes)));
  }
}

void MapOutputs::write_buildings(TimestampNs stamp_ns,
                                 std::span<const buildings::Building> buildings) {
  if (!files_) {
    return;
  }
  std::string list = buildings_json(buildings).dump();
  if (list == last_buildings_) {
    return;
  }
  ++building_updates_;
  // {"t_s": ..., "buildings": [...]}: the list's own object with the time put in front.
  buildings_jsonl_ << "{\"t_s\":"
                   << nlohmann::json(rounded_to(seconds_from_ns(stamp_ns), 1e-6)).dump() << ','
                   << list.substr(1) << '\n';
  last_buildings_ = std::move(list);
}

void MapOutputs::write_poses(std::span<const localize::Pose3> poses) {
  for (const localize::Pose3& p : poses) {
    char line[160];
    const int n = std::snprintf(line, sizeof line, "%.6f,%.4f,%.4f,%.4f,%.6f,%.6f,%.6f\n",
                                seconds_from_ns(p.stamp_ns), p.x_m, p.y_m, p.z_m, p.roll_rad,
                                p.pitch_rad, p.yaw_rad);
    trajectory_out_->write(line, n);
    if (trajectory_rows_ % (kPathDecimation * path_stride_) == 0) {
      if (path_.size() == kMaxPathPoses) {
        thin_path();
      }
      path_.push_back(p);
    }
    ++trajectory_rows_;
  }
}

void MapOutputs::thin_path() {
  for (std::size_t i = 0; 2 * i < path_.size(); ++i) {
    path_[i] = path_[2 * i];
  }
  path_.resize((path_.size() + 1) / 2);
  path_stride_ *= 2;
}

std::string MapOutputs::write_map_path(const localize::PathSmoother& path) const {
  if (!files_ || path.keyframe_count() == 0) {
    return {};
  }
  return write_output(dir_ / "path.csv", [&](std::ostream& file) {
    file << "t_s,x_m,y_m,yaw_rad,matched_x_m,matched_y_m,matched_yaw_rad\n";
    for (std::size_t i = 0; i < path.keyframe_count(); ++i) {
      const localize::Pose2 solved = path.pose(i);
      const localize::Pose2& matched = path.odometry(i);
      char line[160];
      const int n = std::snprintf(line, sizeof line, "%.6f,%.4f,%.4f,%.6f,%.4f,%.4f,%.6f\n",
                                  seconds_from_ns(solved.stamp_ns), solved.x_m, solved.y_m,
                                  solved.yaw_rad, matched.x_m, matched.y_m, matched.yaw_rad);
      file.write(line, n);
    }
  });
}

std::string MapOutputs::finish(std::span<const msg::PlanePatch> planes,
                               std::span<const buildings::Building> buildings,
                               const std::optional<hal::GeodeticPoint>& origin,
                               std::uint64_t points, double seconds,
                               std::span<const Eigen::Vector3f> cloud_m) {
  if (!files_) {
    trajectory_out_->flush();
    return *trajectory_out_ ? std::string() : std::string("writing the trajectory failed");
  }
  // The final list by id: the order in which the planes were first seen.
  std::vector<msg::PlanePatch> sorted(planes.begin(), planes.end());
  std::sort(sorted.begin(), sorted.end(),
            [](const msg::PlanePatch& a, const msg::PlanePatch& b) { return a.id < b.id; });
  nlohmann::json list = nlohmann::json::array();
  for (const msg::PlanePatch& plane : sorted) {
    list.push_back(plane_json(plane));
  }
  const nlohmann::json document = {
      {"planes", list}, {"points", points}, {"seconds", rounded_to(seconds, 1e-4)}};
  // The streams first: what was written as the run went is whole before the lists are.
  if (std::string problem = close_streams(); !problem.empty()) {
    return problem;
  }
  std::string problem = write_output(dir_ / "planes.json",
                                     [&](std::ostream& file) { file << document.dump(1) << '\n'; });
  const auto next = [&problem](std::string outcome) {
    if (problem.empty()) {
      problem = std::move(outcome);
    }
  };
  next(write_output(dir_ / "buildings.json", [&](std::ostream& file) {
    file << buildings_json(buildings).dump(1) << '\n';
  }));
  next(write_output(dir_ / "map.wrl",
                    [&](std::ostream& file) { write_vrml(file, sorted, path_, buildings); }));
  next(write_output(dir_ / "top_view.svg", [&](std::ostream& file) {
    write_buildings_picture(file, cloud_m, sorted, buildings, path_);
  }));
  if (origin) {
    next(write_output(dir_ / "footprints.geojson", [&](std::ostream& file) {
      file << footprints_geojson(buildings, hal::LocalEnuFrame(*origin)).dump(1) << '\n';
    }));
  }
  return problem;
}

std::string MapOutputs::close_streams() {
  const std::pair<std::ofstream*, const char*> streams[] = {{&jsonl_, "planes.jsonl"},
                                                            {&binary_, "planes.bin"},
                                                            {&trajectory_, "trajectory.csv"},
                                                            {&buildings_jsonl_, "buildings.jsonl"}};
  for (const auto& [file, name] : streams) {
    file->close();
    if (file->fail()) {
      return (dir_ / name).string() + ": write failed (the disk full, or the file gone?)";
    }
  }
  return {};
}

}  // namespace blockmap::cli
