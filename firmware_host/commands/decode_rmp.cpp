// `blockmap decode rmp`: a Segway RMP CAN log (candump format, or Orca's "id:0401 FF F9 ..."
// lines) as one JSON object per RMP frame, in SI units; unparsable lines and rejected frames as
// {"error": reason, "line": N}.
#include <algorithm>
#include <cstdio>
#include <ostream>
#include <span>
#include <string>
#include <string_view>

#include "blockmap/hal/protocol/candump.hpp"
#include "blockmap/hal/protocol/segway_rmp.hpp"
#include "cli.hpp"
#include "commands/decoders.hpp"

namespace blockmap::cli {
namespace {

namespace rmp = hal::protocol::segway_rmp;
namespace candump = hal::protocol::candump;

// The fields frame `id` carries, from the decoder's latest values.
void add_frame_fields(std::uint32_t id, const rmp::StatusCycle& v, Json& line) {
  switch (id) {
    case 0x401:
      line["pitch_rad"] = rounded(v.imu.pitch_rad, 6);
      line["pitch_rate_radps"] = rounded(v.imu.pitch_rate_radps, 6);
      line["roll_rad"] = rounded(v.imu.roll_rad, 6);
      line["roll_rate_radps"] = rounded(v.imu.roll_rate_radps, 6);
      break;
    case 0x402:
      line["left_wheel_velocity_mps"] = rounded(v.odometry.left_wheel_velocity_mps, 6);
      line["right_wheel_velocity_mps"] = rounded(v.odometry.right_wheel_velocity_mps, 6);
      line["yaw_rate_radps"] = rounded(v.imu.yaw_rate_radps, 6);
      line["servo_frames"] = v.odometry.servo_frame_count;
      break;
    case 0x403:
      line["left_wheel_distance_m"] = rounded(v.odometry.left_wheel_distance_m, 7);
      line["right_wheel_distance_m"] = rounded(v.odometry.right_wheel_distance_m, 7);
      break;
    case 0x404:
      line["fore_aft_distance_m"] = rounded(v.odometry.fore_aft_distance_m, 7);
      line["yaw_displacement_rad"] = rounded(v.odometry.yaw_displacement_rad, 7);
      break;
    case 0x405:
      line["left_motor_torque_nm"] = rounded(v.left_motor_torque_nm, 6);
      line["right_motor_torque_nm"] = rounded(v.right_motor_torque_nm, 6);
      break;
    case 0x406:
      line["operational_mode"] = v.status.operational_mode;
      line["gain_schedule"] = v.gain_schedule;
      line["ui_battery_v"] = rounded(v.status.ui_battery_v, 4);
      line["powerbase_battery_v"] = rounded(v.status.powerbase_battery_v, 2);
      break;
    case 0x407:
      line["velocity_command_counts"] = v.velocity_command_counts;
      line["turn_command_counts"] = v.turn_command_counts;
      break;
    case rmp::kCuStatusId:
      line["motors_enabled"] = v.status.motors_enabled;
      break;
    default:
      break;
  }
}

candump::ParseError parse_any_line(std::string_view text, candump::Record& record) {
  if (text.substr(0, 3) == "id:") {
    record.stamp_ns = 0;
    return candump::parse_id_bytes_line(text, record);
  }
  return candump::parse_line(text, record);
}

// A capture's lines, read piece by piece: each once, the last one even without its newline;
// a line is kept up to kMaxLineBytes (a candump line is under a hundred).
class Lines {
 public:
  explicit Lines(CaptureReader& capture) : capture_(capture) {}
  bool next(std::string_view& line) {
    line_.clear();
    for (;;) {
      if (rest_.empty()) {
        TimestampNs unused_ns = 0;
        if (ended_ || !capture_.next(rest_, unused_ns)) {
          ended_ = true;
          line = line_;
          return !line_.empty();
        }
      }
      const auto newline = std::find(rest_.begin(), rest_.end(), '\n');
      const bool whole = newline != rest_.end();
      const auto length = static_cast<std::size_t>(newline - rest_.begin());
      const std::size_t room = kMaxLineBytes - std::min(kMaxLineBytes, line_.size());
      line_.append(reinterpret_cast<const char*>(rest_.data()), std::min(length, room));
      rest_ = rest_.subspan(whole ? length + 1 : length);
      if (whole) {
        line = line_;
        return true;
      }
    }
  }

 private:
  static constexpr std::size_t kMaxLineBytes = std::size_t{1} << 16;
  CaptureReader& capture_;
  std::span<const std::uint8_t> rest_;
  std::string line_;
  bool ended_ = false;
};

}  // namespace

int decode_rmp(CaptureReader& capture, std::ostream& out, std::ostream& err) {
  rmp::Decoder decoder;
  Lines lines(capture);
  std::size_t line_number = 0;
  std::size_t frames = 0;
  for (std::string_view line_text; lines.next(line_text);) {
    ++line_number;
    candump::Record record;
    const candump::ParseError parsed = parse_any_line(line_text, record);
    if (parsed == candump::ParseError::kNotAFrame) {
      continue;
    }
    Json line;
    if (parsed != candump::ParseError::kNone) {
      line["error"] = candump::to_string(parsed);
      line["line"] = line_number;
      out << line.dump() << '\n';
      continue;
    }
    ++frames;
    const rmp::Decoder::Step step = decoder.push(record.frame, record.stamp_ns);
    if (step.kind == rmp::Decoder::FrameKind::kIgnored) {
      continue;
    }
    if (step.kind == rmp::Decoder::FrameKind::kRejected) {
      line["error"] = rmp::to_string(step.reason);
      line["line"] = line_number;
      out << line.dump() << '\n';
      continue;
    }
    char id[8];
    std::snprintf(id, sizeof id, "0x%03X", static_cast<unsigned>(record.frame.id));
    line["t_s"] = rounded(seconds_from_ns(record.stamp_ns), 6);
    line["id"] = id;
    add_frame_fields(record.frame.id, decoder.latest(), line);
    if (step.cycle != nullptr) {
      line["cycle_complete"] = true;
    }
    out << line.dump() << '\n';
  }
  err << "rmp: " << frames << " frames, " << decoder.cycles_decoded() << " complete status groups";
  print_drops(err, decoder.drops());
  err << '\n';
  return kExitOk;
}

}  // namespace blockmap::cli
