// libFuzzer target: a folder of device logs as `blockmap replay DIR` reads it, from one input:
// robot.toml (the built-in paper_rmp when empty), rmp.candump, gps.nmea and the bytes of each
// laser's byte log, read through the replay's own device layer (RecordedRun: the log readers,
// SegwayBase, GpsReceiver, Lms2xxScanner). Whatever the bytes, a robot file is taken or
// refused with a ConfigError, the readers come to their end, and what the devices publish is
// what a robot could send.
//
// The input: three little-endian 16-bit lengths (robot.toml, rmp.candump, gps.nmea), those
// parts in that order, and the rest is every laser's byte log.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <span>
#include <string>
#include <string_view>
#include <system_error>

#include "blockmap/hal/config/config_error.hpp"
#include "blockmap/hal/config/robot.hpp"
#include "commands/recorded_run.hpp"
#include "require.hpp"

namespace {

namespace fs = std::filesystem;
using blockmap::msg::GpsFix;
using blockmap::msg::ImuSample;
using blockmap::msg::LaserScan;
using blockmap::msg::OdometrySample;

// The folder the logs are written into, removed when the fuzzer exits.
class Folder {
 public:
  Folder() {
    std::string pattern = (fs::temp_directory_path() / "fuzz_replay_XXXXXX").string();
    path_ = ::mkdtemp(pattern.data());
  }
  Folder(const Folder&) = delete;
  Folder& operator=(const Folder&) = delete;
  ~Folder() {
    std::error_code ignored;
    fs::remove_all(path_, ignored);
  }
  [[nodiscard]] const fs::path& path() const noexcept { return path_; }

 private:
  fs::path path_;
};

const fs::path& folder() {
  static const Folder dir;
  return dir.path();
}

void write(const fs::path& path, std::span<const std::uint8_t> bytes) {
  std::ofstream(path, std::ios::binary | std::ios::trunc)
      .write(reinterpret_cast<const char*>(bytes.data()),
             static_cast<std::streamsize>(bytes.size()));
}

// The next part: a length from the input's head, then that many bytes (or what is left).
std::span<const std::uint8_t> part(std::span<const std::uint8_t> input, std::size_t index,
                                   std::size_t& at) {
  const std::size_t length = index * 2 + 1 < input.size()
                                 ? input[index * 2] | (std::size_t{input[index * 2 + 1]} << 8)
                                 : 0;
  const std::span<const std::uint8_t> bytes = input.subspan(
      std::min(at, input.size()), std::min(length, input.size() - std::min(at, input.size())));
  at += bytes.size();
  return bytes;
}

// A laser's name becomes a file's: only plain names are written (a robot file may say anything).
bool plain(std::string_view name) {
  return !name.empty() && std::all_of(name.begin(), name.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_';
  });
}

using blockmap::fuzz::require;

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace config = blockmap::hal::config;
  const std::span<const std::uint8_t> input(data, size);
  std::size_t at = 6;
  const std::span<const std::uint8_t> robot_file = part(input, 0, at);
  const std::span<const std::uint8_t> can_log = part(input, 1, at);
  const std::span<const std::uint8_t> nmea_log = part(input, 2, at);
  const std::span<const std::uint8_t> laser_log = input.subspan(std::min(at, input.size()));

  config::RobotSpec robot;
  try {
    static const config::RobotSpec paper_rmp = config::load_robot("paper_rmp");
    robot =
        robot_file.empty()
            ? paper_rmp
            : config::parse_robot(std::string_view(reinterpret_cast<const char*>(robot_file.data()),
                                                   robot_file.size()),
                                  "robot.toml");
    config::require_lms2xx_lasers(robot, "the replay of byte logs");
  } catch (const blockmap::hal::ConfigError&) {
    return 0;
  }
  const fs::path& dir = folder();
  for (const fs::directory_entry& entry : fs::directory_iterator(dir)) {
    fs::remove(entry.path());
  }
  write(dir / "rmp.candump", can_log);
  write(dir / "gps.nmea", nmea_log);
  for (const config::LaserSpec& laser : robot.lasers) {
    if (plain(laser.name)) {
      write(dir / ("laser_" + laser.name + ".bytelog"), laser_log);
    }
  }

  blockmap::cli::RecordedRun run(dir, config::segway_base_config_for(robot), robot.lasers);
  if (!run.open_error().empty()) {
    return 0;
  }
  const blockmap::hal::devices::SegwayBaseConfig limits = config::segway_base_config_for(robot);
  OdometrySample odometry;
  ImuSample imu;
  while (run.next_base(odometry, imu)) {
    require(std::abs(imu.yaw_rate_radps) <= limits.max_rate_radps &&
            std::abs(imu.roll_rad) <= limits.max_tilt_rad &&
            std::abs(imu.pitch_rad) <= limits.max_tilt_rad);
  }
  GpsFix fix;
  while (run.next_fix(fix)) {
    require(!fix.has_position ||
            (std::abs(fix.latitude_deg) <= 90.0 && std::abs(fix.longitude_deg) <= 180.0));
  }
  LaserScan scan;
  for (std::size_t i = 0; i < run.laser_count(); ++i) {
    while (run.next_scan(i, scan)) {
      require(scan.beam_count <= blockmap::msg::kMaxLaserBeams);
    }
  }
  return 0;
}
