#include "blockmap/hal/devices/laser_scanners.hpp"

#include <string_view>

namespace blockmap::hal::devices {

namespace lms = protocol::sick_lms2xx;
namespace scip2 = protocol::hokuyo_scip2;

namespace {

// Writes a whole command or reports why it could not.
IoStatus write_all(ByteStream& port, std::span<const std::uint8_t> bytes) {
  const WriteResult result = port.write(bytes, kNanosecondsPerSecond / 10);
  if (result.status != IoStatus::kOk) {
    return result.status;
  }
  return result.bytes == bytes.size() ? IoStatus::kOk : IoStatus::kTimedOut;
}

IoStatus write_text(ByteStream& port, std::string_view text) {
  return write_all(port, std::span<const std::uint8_t>(
                             reinterpret_cast<const std::uint8_t*>(text.data()), text.size()));
}

}  // namespace

void ScanPublisher::publish(const msg::LaserScan& scan) {
  stamped_ = scan;
  stamped_.header.stamp_ns -= latency_ns_;
  if (stamped_.time_increment_s == 0.0) {
    stamped_.time_increment_s = beam_interval_s_;
  }
  if (scans_.try_push(stamped_)) {
    published_.increment();
  } else {
    rejected_.increment();
  }
}

Lms2xxScanner::Lms2xxScanner(ByteStream& port, SpscQueueRef<msg::LaserScan>& scans,
                             const Lms2xxScannerConfig& config)
    : ScanPublisher(scans, config.latency_ns, config.beam_interval_s),
      port_(port),
      config_(config),
      decoder_(config.codec) {}

Lms2xxScannerConfig lms2xx_single_turn_timing(double field_deg, double resolution_deg,
                                              double processing_s) {
  constexpr double kMirrorTurnS = 1.0 / 75.0;
  Lms2xxScannerConfig config;
  config.beam_interval_s = resolution_deg / 360.0 * kMirrorTurnS;
  // From the first beam to the end of the half turn: (180 + field) / 720 of a turn.
  config.latency_ns = ns_from_seconds((180.0 + field_deg) / 720.0 * kMirrorTurnS + processing_s);
  return config;
}

IoStatus Lms2xxScanner::request(std::span<const std::uint8_t> bytes) {
  return write_all(port_, bytes);
}

bool Lms2xxScanner::request_answered(std::span<const std::uint8_t> bytes) {
  const std::uint64_t switches = mode_switches();
  const std::uint64_t scans = scans_published();
  if (request(bytes) != IoStatus::kOk) {
    return false;
  }
  // The reply-time budget, spent in reads of at most 20 ms.
  for (TimestampNs waited_ns = 0; waited_ns < config_.reply_timeout_ns; waited_ns += 20'000'000) {
    const IoStatus status = poll(20'000'000);
    if (mode_switches() != switches || scans_published() != scans) {
      return true;
    }
    if (status != IoStatus::kOk && status != IoStatus::kTimedOut &&
        status != IoStatus::kWouldBlock) {
      return false;
    }
  }
  return false;
}

IoStatus Lms2xxScanner::start() {
  std::array<std::uint8_t, lms::kRequestBufferBytes> continuous{};
  const std::span<const std::uint8_t> continuous_request(continuous.data(),
                                                         lms::encode_continuous_output(continuous));
  if (config_.power_up_baud == 0 || config_.line_baud == 0 ||
      config_.power_up_baud == config_.line_baud) {
    return request(continuous_request);
  }
  // Already at the line's rate (it kept it since the last start)?
  if (port_.set_baud(config_.line_baud) == IoStatus::kOk && request_answered(continuous_request)) {
    return IoStatus::kOk;
  }
  // At its power-up rate: asked for the line's rate, it answers at the old one, then switches.
  std::array<std::uint8_t, lms::kRequestBufferBytes> set_baud{};
  const std::size_t length = lms::encode_set_baud(set_baud, config_.line_baud);
  if (length == 0 || port_.set_baud(config_.power_up_baud) != IoStatus::kOk ||
      !request_answered(std::span<const std::uint8_t>(set_baud.data(), length))) {
    static_cast<void>(port_.set_baud(config_.line_baud));
    return IoStatus::kTimedOut;
  }
  if (port_.set_baud(config_.line_baud) != IoStatus::kOk) {
    return IoStatus::kIoError;
  }
  return request_answered(continuous_request) ? IoStatus::kOk : IoStatus::kTimedOut;
}

IoStatus Lms2xxScanner::poll(TimestampNs timeout_ns) {
  const ReadResult read = port_.read(read_buffer_, timeout_ns);
  std::span<const std::uint8_t> rest(read_buffer_.data(), read.bytes);
  // The codec may hand out events from bytes it had kept (after a false start byte), so it is
  // called until it says there is nothing more, even with no new bytes.
  for (;;) {
    const lms::Decoder::Step step = decoder_.push(rest, read.stamp_ns);
    rest = rest.subspan(step.consumed);
    if (step.event == lms::Decoder::Event::kNone) {
      break;
    }
    handle(step);
  }
  return read.status;
}

void Lms2xxScanner::handle(const lms::Decoder::Step& step) {
  if (step.event != lms::Decoder::Event::kTelegram) {
    return;
  }
  const lms::Telegram& telegram = *step.telegram;
  if (telegram.has_scan) {
    publish(telegram.scan);
  } else if (telegram.command == lms::command::kSwitchModeReply && !telegram.data.empty() &&
             telegram.data[0] == 0x00) {
    mode_switches_.increment();
  }
}

UrgScanner::UrgScanner(ByteStream& port, SpscQueueRef<msg::LaserScan>& scans,
                       const UrgScannerConfig& config)
    : ScanPublisher(scans, config.latency_ns),
      port_(port),
      config_(config),
      decoder_(config.codec) {}

IoStatus UrgScanner::start() {
  // A sensor may boot in SCIP 1.1; "SCIP2.0" switches it and is harmless when already there.
  for (std::string_view command : {"SCIP2.0\n", "PP\n", "BM\n"}) {
    if (const IoStatus status = write_text(port_, command); status != IoStatus::kOk) {
      return status;
    }
  }
  const scip2::SensorParameters& sensor = decoder_.sensor();
  std::array<char, 24> command{};
  const std::size_t length = scip2::encode_continuous_request(
      command, sensor.first_step, sensor.last_step, config_.cluster, 0, 0);
  if (length == 0) {
    return IoStatus::kInvalidArgument;
  }
  return write_text(port_, std::string_view(command.data(), length));
}

IoStatus UrgScanner::poll(TimestampNs timeout_ns) {
  const ReadResult read = port_.read(read_buffer_, timeout_ns);
  std::span<const std::uint8_t> rest(read_buffer_.data(), read.bytes);
  while (!rest.empty()) {
    const scip2::Decoder::Step step = decoder_.push(rest, read.stamp_ns);
    rest = rest.subspan(step.consumed);
    if (step.scan != nullptr) {
      publish(*step.scan);
    } else if (step.reply != nullptr && step.reply->status != "00" && step.reply->status != "99" &&
               step.reply->status.size() == 2) {
      error_replies_.increment();
    }
  }
  return read.status;
}

TimScanner::TimScanner(UsbBulk& usb, SpscQueueRef<msg::LaserScan>& scans,
                       const TimScannerConfig& config)
    : ScanPublisher(scans, config.latency_ns), usb_(usb), config_(config), decoder_(config.codec) {}

IoStatus TimScanner::start() {
  std::array<std::uint8_t, 64> command{};
  const std::size_t length =
      protocol::sick_cola::encode_scan_events(config_.dialect, true, command);
  if (length == 0) {
    return IoStatus::kInvalidArgument;
  }
  const WriteResult written = usb_.transfer_out(
      std::span<const std::uint8_t>(command.data(), length), config_.transfer_timeout_ns);
  if (written.status != IoStatus::kOk) {
    return written.status;
  }
  return written.bytes == length ? IoStatus::kOk : IoStatus::kTimedOut;
}

IoStatus TimScanner::poll(TimestampNs timeout_ns) {
  const ReadResult read = usb_.transfer_in(transfer_buffer_, timeout_ns);
  if (read.status == IoStatus::kDeviceLost) {
    while (decoder_.flush().has_event()) {
    }
    return read.status;
  }
  std::span<const std::uint8_t> rest(transfer_buffer_.data(), read.bytes);
  for (;;) {
    const protocol::sick_cola::Decoder::Step step = decoder_.push(rest, read.stamp_ns);
    rest = rest.subspan(step.consumed);
    if (step.scan != nullptr) {
      publish(*step.scan);
    }
    if (!step.has_event() && rest.empty()) {
      break;
    }
  }
  return read.status;
}

}  // namespace blockmap::hal::devices
