// What `run` and `replay` write into their --out folder (docs/formats.md, run outputs), as the
// run goes:
//   planes.jsonl    one JSON object per plane-list update (plane_json.hpp)
//   planes.bin      the same updates as the binary plane stream (docs/log-formats.md)
//   trajectory.csv  the smoothed poses, as they leave the localizer's smoothing window
//   buildings.jsonl the buildings whenever a refit changed them: {"t_s", "buildings": [...]}
// and at the end: planes.json (the final plane list), path.csv (the path the planes were laid
// with, when the mapper solved one), buildings.json, map.wrl (VRML
// 2.0, buildings' walls seen dark and virtual light) and footprints.geojson (WGS-84, when the
// local frame's place on Earth is known). With a UDP
// destination, each binary record also goes out as one datagram.
#pragma once

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "blockmap/buildings/building.hpp"
#include "blockmap/hal/geodesy.hpp"
#include "blockmap/hal/linux/udp_sender.hpp"
#include "blockmap/localize/localizer.hpp"
#include "blockmap/localize/path_smoother.hpp"
#include "blockmap/msg/plane_patch.hpp"

namespace blockmap::cli {

class MapOutputs {
 public:
  // Creates `dir` and opens the stream files; `max_changes` bounds one update (the binary
  // record buffer is sized for it here, once). With `append` (a resumed map), the streams a
  // run before left in `dir` are carried on: each is cut after its last whole line or record
  // (a crash may have torn the last one) and written on from there. Empty when it worked,
  // otherwise why not.
  [[nodiscard]] std::string open(const std::filesystem::path& dir, std::size_t max_changes,
                                 const std::string& udp_destination, bool append = false);
  // Only the trajectory, to `trajectory` (replay without --out) or into dir/trajectory.csv.
  void open_trajectory_only(std::ostream& trajectory);
  [[nodiscard]] std::string open_trajectory_only(const std::filesystem::path& dir);

  void write_update(TimestampNs stamp_ns, std::span<const msg::PlaneChange> changes);
  void write_poses(std::span<const localize::Pose3> poses);
  // A line of buildings.jsonl when they differ from the last line written.
  void write_buildings(TimestampNs stamp_ns, std::span<const buildings::Building> buildings);
  // Closes the streams, then writes planes.json, buildings.json, map.wrl, top_view.svg (the
  // picture from above, over `cloud_m` when the cloud was kept) and (with an origin)
  // footprints.geojson, each whole or not at all. Empty when it worked, otherwise the first
  // file that could not be written, named.
  [[nodiscard]] std::string finish(std::span<const msg::PlanePatch> planes,
                                   std::span<const buildings::Building> buildings,
                                   const std::optional<hal::GeodeticPoint>& origin,
                                   std::uint64_t points, double seconds,
                                   std::span<const Eigen::Vector3f> cloud_m = {});

  // path.csv: the rigid path's keyframes as solved at the end, each with the scan matcher's
  // pose of its time (the local SLAM's path, before the fixes placed it). Nothing without
  // keyframes. Empty when it worked, otherwise why not.
  [[nodiscard]] std::string write_map_path(const localize::PathSmoother& path) const;

  [[nodiscard]] std::uint64_t updates() const noexcept { return updates_; }
  [[nodiscard]] std::uint64_t binary_bytes() const noexcept { return binary_bytes_; }
  [[nodiscard]] std::uint64_t building_updates() const noexcept { return building_updates_; }
  [[nodiscard]] std::size_t trajectory_rows() const noexcept { return trajectory_rows_; }
  [[nodiscard]] const std::filesystem::path& dir() const noexcept { return dir_; }

 private:
  std::filesystem::path dir_;
  std::ofstream jsonl_;
  std::ofstream binary_;
  std::ofstream trajectory_;
  std::ofstream buildings_jsonl_;
  std::string last_buildings_;  // the last buildings line's list, to write changes only
  std::uint64_t building_updates_ = 0;
  std::ostream* trajectory_out_ = nullptr;  // trajectory_ or the caller's stream
  bool files_ = false;
  std::vector<std::uint8_t> record_;
  hal::linux_backend::UdpSender udp_;
  void thin_path();
  // Closes the streams written as the run went; the first that lost a write, named.
  [[nodiscard]] std::string close_streams();
  std::vector<localize::Pose3> path_;  // every 10th pose (thinned when full), for map.wrl
  std::size_t path_stride_ = 1;        // path_ keeps every (10 x this)th pose
  std::uint64_t updates_ = 0;
  std::uint64_t binary_bytes_ = 0;
  std::size_t trajectory_rows_ = 0;
};

}  // namespace blockmap::cli
