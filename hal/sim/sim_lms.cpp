// The simulated SICK LMS2xx: after the host's request for continuous output (20 24) it
// acknowledges (06, then an A0 reply) and sends a B0 telegram for every scan the serial line has
// room for (docs/protocols.md 2.5, 2.6). The mirror turns at 75 Hz; a 180 deg scan takes half a
// turn, beam by beam, and a 0.5 deg scan interlaces two turns. Every beam is cast into the scene
// from the sensor's pose at the instant it was measured, so the robot's motion and pitch during a
// scan are in the data, as they are on the real robot.
#include <algorithm>
#include <cmath>
#include <numbers>

#include "blockmap/core/angles.hpp"
#include "sim_devices.hpp"

namespace blockmap::hal::sim::detail {
namespace {

namespace lms = protocol::sick_lms2xx;

constexpr double kMirrorTurnS = 1.0 / config::kLms2xxMirrorRateHz;
constexpr double kProcessingS = 0.001;      // from the last beam to the telegram's first byte
constexpr double kRequestAtS = 0.001;       // the host's request, 1 ms into the run
constexpr double kReplyDelayS = 0.002;      // the scanner's ACK after the request
constexpr std::uint8_t kStatusByte = 0x10;  // bit 4 is set in every real reply (2.7)
constexpr double kRadPerCentideg = std::numbers::pi / 18000.0;

}  // namespace

SimLms::SimLms(const config::LaserSpec& spec, std::size_t device, std::uint64_t seed)
    : spec_(spec),
      device_(device),
      random_(seed, "laser_" + spec.name),
      wire_(spec.baud, static_cast<TimestampNs>(spec.read_interval_s * 1e9),
            4 * lms::kMaxTelegramBytes),
      geometry_(lms::geometry(spec.variant)) {
  turns_per_scan_ = config::mirror_turns_per_scan(spec.variant);
  const double max_rate = config::kLms2xxMirrorRateHz / turns_per_scan_;
  turns_between_scans_ = static_cast<std::uint64_t>(std::lround(max_rate / spec.scan_rate_hz)) *
                         static_cast<std::uint64_t>(turns_per_scan_);
  // The mirror's phase is not tied to the run's start; the first scan follows the handshake.
  first_turn_s_ = 0.02 + random_.uniform(0.0, kMirrorTurnS);
  range_max_m_ = lms::range_max_m(spec.units, spec.range_bits);
  const double start_angle = -geometry_.field_deg * std::numbers::pi / 360.0;
  for (std::uint16_t i = 0; i < geometry_.value_count; ++i) {
    const double angle = start_angle + i * geometry_.resolution_centideg * kRadPerCentideg;
    beam_directions_[i] = Vec3(std::cos(angle), std::sin(angle), 0.0);
  }
}

TimestampNs SimLms::scan_start_ns(const SimContext& context, std::uint64_t scan) const {
  return context.stamp(first_turn_s_ +
                       static_cast<double>(scan * turns_between_scans_) * kMirrorTurnS);
}

double SimLms::scan_span_s() const noexcept {
  // The last beam is measured half a turn into the last of the scan's turns.
  return (turns_per_scan_ - 1 + 0.5) * kMirrorTurnS;
}

TimestampNs SimLms::scan_ready_ns(const SimContext& context, std::uint64_t scan) const {
  return scan_start_ns(context, scan) +
         static_cast<TimestampNs>((scan_span_s() + kProcessingS) * 1e9);
}

TimestampNs SimLms::next_event_ns(const SimContext& context) const noexcept {
  if (!started_) {
    return context.stamp(kRequestAtS);
  }
  TimestampNs next = wire_.next_read_ns();
  const TimestampNs scan_ns = scan_ready_ns(context, next_scan_);
  if (scan_ns <= context.end_ns) {
    next = std::min(next, scan_ns);
  }
  return next;
}

void SimLms::start_handshake(const SimContext& context, SimSink& sink) {
  std::array<std::uint8_t, lms::kRequestBufferBytes> request{};
  const std::size_t request_length = lms::encode_continuous_output(request);
  const TimestampNs request_ns = context.stamp(kRequestAtS);
  sink.on_serial(device_, request_ns, protocol::byte_log::Direction::kToDevice,
                 std::span<const std::uint8_t>(request.data(), request_length));
  const std::array<std::uint8_t, 1> ack = {lms::kAckByte};
  const TimestampNs reply_ns = context.stamp(kRequestAtS + kReplyDelayS);
  (void)wire_.send(ack, reply_ns);
  const std::array<std::uint8_t, 1> accepted = {0x00};
  const std::size_t length =
      lms::encode_reply(telegram_, lms::command::kSwitchModeReply, accepted, kStatusByte);
  (void)wire_.send(std::span<const std::uint8_t>(telegram_.data(), length), reply_ns);
  started_ = true;
}

void SimLms::fire(SimContext& context, SimSink& sink, SimStats& stats) {
  if (!started_) {
    start_handshake(context, sink);
    return;
  }
  const TimestampNs scan_ns = scan_ready_ns(context, next_scan_);
  if (scan_ns <= wire_.next_read_ns() && scan_ns <= context.end_ns) {
    if (wire_.busy_until_ns() <= scan_ns) {
      measure_scan(context, sink, stats);
    } else {
      ++stats.scans_skipped[device_];  // the line still carries the previous telegram
    }
    ++next_scan_;
    return;
  }
  TimestampNs stamp_ns = 0;
  const std::span<const std::uint8_t> bytes = wire_.read(stamp_ns);
  sink.on_serial(device_, stamp_ns, protocol::byte_log::Direction::kFromDevice, bytes);
}

void SimLms::measure_scan(SimContext& context, SimSink& sink, SimStats& stats) {
  const double start_s = context.seconds(scan_start_ns(context, next_scan_));
  const double end_s = start_s + scan_span_s();
  context.motion.advance_to(end_s + kProcessingS);
  const RobotState first = context.motion.state_at(start_s);
  const RobotState last = context.motion.state_at(end_s);
  const Eigen::Matrix3d mount = map::mount_rotation(spec_.mount);
  const Eigen::Matrix3d rotation_first = first.rotation() * mount;
  const Eigen::Matrix3d rotation_last = last.rotation() * mount;
  const Vec3 origin_first = first.position_m + first.rotation() * spec_.mount.position_m;
  const Vec3 origin_last = last.position_m + last.rotation() * spec_.mount.position_m;
  // Everything the scan can reach, with room for the sensor's motion during the scan.
  const double margin = (origin_last - origin_first).norm() +
                        (rotation_last.col(2) - rotation_first.col(2)).norm() * range_max_m_ + 0.05;
  context.scene.begin_scan(0.5 * (origin_first + origin_last),
                           (rotation_first.col(2) + rotation_last.col(2)).normalized(),
                           range_max_m_ + margin, 0.5 * (start_s + end_s));

  const double field_rad = radians_from_degrees(geometry_.field_deg);
  const double start_angle = -field_rad / 2.0;
  const double span_s = end_s - start_s;
  BeamTruth truth;
  truth.scan = static_cast<std::uint32_t>(next_scan_);
  std::uint64_t returned = 0;
  for (std::uint16_t i = 0; i < geometry_.value_count; ++i) {
    const double angle = start_angle + i * geometry_.resolution_centideg * kRadPerCentideg;
    // When the mirror pointed there: its turn within an interlaced scan, then its angle.
    const double t_s = start_s + (i % turns_per_scan_) * kMirrorTurnS +
                       (angle + std::numbers::pi / 2.0) / (2.0 * std::numbers::pi) * kMirrorTurnS;
    const double f = span_s > 0.0 ? std::clamp((t_s - start_s) / span_s, 0.0, 1.0) : 0.0;
    const Vec3& beam_sensor = beam_directions_[i];
    const Vec3 origin = origin_first + f * (origin_last - origin_first);
    const Vec3 direction =
        (rotation_first * beam_sensor + f * (rotation_last - rotation_first) * beam_sensor)
            .normalized();
    truth.stamp_ns = context.stamp(t_s);
    truth.beam = i;
    truth.origin_m = origin;
    truth.direction = direction;
    truth.hit = context.scene.cast(origin, direction, range_max_m_ + margin, random_);
    truth.returned = false;
    truth.measured_range_m = 0.0;
    msg::BeamStatus status = msg::BeamStatus::kNoReturn;
    double range = 0.0;
    if (truth.hit.kind != SurfaceKind::kNone && truth.hit.range_m <= range_max_m_ &&
        !random_.chance(spec_.missing_return_probability)) {
      range = std::max(0.0, truth.hit.range_m + random_.gaussian(spec_.range_noise_m));
      status = msg::BeamStatus::kValid;
      truth.returned = true;
      truth.measured_range_m = range;
      ++returned;
      if (truth.hit.face >= 0) {
        context.scene.count_return(truth.hit.face);
      }
    }
    values_[i] = lms::encode_beam(range, status, spec_.units, spec_.range_bits);
    sink.on_beam(device_, truth);
  }
  const std::size_t length = lms::encode_measured_values(
      telegram_, std::span<const std::uint16_t>(values_.data(), geometry_.value_count), spec_.units,
      kStatusByte);
  const TimestampNs ready_ns = context.stamp(end_s + kProcessingS);
  if (wire_.send(std::span<const std::uint8_t>(telegram_.data(), length), ready_ns)) {
    ++stats.scans_sent[device_];
    stats.beams_returned[device_] += returned;
  } else {
    ++stats.scans_skipped[device_];
  }
}

std::size_t SimLms::memory_bytes() const noexcept {
  return sizeof(*this) + wire_.memory_bytes();
}

}  // namespace blockmap::hal::sim::detail
