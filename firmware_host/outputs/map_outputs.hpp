// What `run` and `replay` write into their --out folder (ARCHITECTURE.md 4.4), as the run goes:
//   planes.jsonl    one JSON object per plane-list update (plane_json.hpp)
//   planes.bin      the same updates as the binary plane stream (docs/log-formats.md)
//   trajectory.csv  the smoothed poses, as they leave the localizer's smoothing window
// and at the end: planes.json (the final plane list, 4.1) and map.wrl (VRML 2.0). With a UDP
// destination, each binary record also goes out as one datagram.
#pragma once

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <span>
#include <string>
#include <vector>

#include "blockmap/hal/linux/udp_sender.hpp"
#include "blockmap/localize/localizer.hpp"
#include "blockmap/msg/plane_patch.hpp"

namespace blockmap::cli {

class MapOutputs {
 public:
  // Creates `dir` and opens the stream files; `max_changes` bounds one update (the binary
  // record buffer is sized for it here, once). Empty when it worked, otherwise why not.
  [[nodiscard]] std::string open(const std::filesystem::path& dir, std::size_t max_changes,
                                 const std::string& udp_destination);
  // Only the trajectory, to `trajectory` (replay without --out) or into dir/trajectory.csv.
  void open_trajectory_only(std::ostream& trajectory);
  [[nodiscard]] std::string open_trajectory_only(const std::filesystem::path& dir);

  void write_update(TimestampNs stamp_ns, std::span<const msg::PlaneChange> changes);
  void write_poses(std::span<const localize::Pose3> poses);
  // planes.json and map.wrl; flushes everything. Empty when it worked, otherwise why not.
  [[nodiscard]] std::string finish(std::span<const msg::PlanePatch> planes, std::uint64_t points,
                                   double seconds);

  [[nodiscard]] std::uint64_t updates() const noexcept { return updates_; }
  [[nodiscard]] std::uint64_t binary_bytes() const noexcept { return binary_bytes_; }
  [[nodiscard]] std::size_t trajectory_rows() const noexcept { return trajectory_rows_; }
  [[nodiscard]] const std::filesystem::path& dir() const noexcept { return dir_; }

 private:
  std::filesystem::path dir_;
  std::ofstream jsonl_;
  std::ofstream binary_;
  std::ofstream trajectory_;
  std::ostream* trajectory_out_ = nullptr;  // trajectory_ or the caller's stream
  bool files_ = false;
  std::vector<std::uint8_t> record_;
  hal::linux_backend::UdpSender udp_;
  std::vector<localize::Pose3> path_;  // every 10th pose, for the VRML map's path
  std::uint64_t updates_ = 0;
  std::uint64_t binary_bytes_ = 0;
  std::size_t trajectory_rows_ = 0;
};

}  // namespace blockmap::cli
