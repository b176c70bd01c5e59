// `blockmap decode lms2xx`: one JSON object per telegram of a SICK LMS 200/291 byte stream
// (docs/protocols.md section 2): its offset, address, command and status, the data of generic
// replies, and for a B0 scan the count, units, variant, angles and ranges (null for beams with
// no valid range). ACK/NAK bytes are {"command": "ACK"|"NAK"}; dropped candidates are
// {"error": reason, "offset": N}.
#include <cstdio>
#include <ostream>
#include <span>
#include <string>
#include <utility>

#include "blockmap/hal/protocol/sick_lms2xx.hpp"
#include "cli.hpp"
#include "commands/decoders.hpp"

namespace blockmap::cli {
namespace {

namespace lms = hal::protocol::sick_lms2xx;

std::string hex_byte(std::uint8_t byte) {
  char text[8];
  std::snprintf(text, sizeof text, "0x%02X", static_cast<unsigned>(byte));
  return text;
}

std::string hex_bytes(std::span<const std::uint8_t> bytes) {
  std::string text;
  text.reserve(bytes.size() * 2);
  for (const std::uint8_t byte : bytes) {
    char pair[4];
    std::snprintf(pair, sizeof pair, "%02X", static_cast<unsigned>(byte));
    text += pair;
  }
  return text;
}

const char* severity_name(msg::DeviceSeverity severity) {
  switch (severity) {
    case msg::DeviceSeverity::kOk:
      return "ok";
    case msg::DeviceSeverity::kInfo:
      return "info";
    case msg::DeviceSeverity::kWarning:
      return "warning";
    case msg::DeviceSeverity::kError:
      return "error";
    case msg::DeviceSeverity::kFatal:
      return "fatal";
  }
  return "?";
}

void add_scan(Json& line, const lms::Telegram& telegram) {
  const msg::LaserScan& scan = telegram.scan;
  line["count"] = scan.beam_count;
  line["units"] = lms::to_string(telegram.units);
  line["variant"] = lms::to_string(telegram.variant);
  line["start_angle_rad"] = rounded(scan.start_angle_rad, 9);
  line["angle_increment_rad"] = rounded(scan.angle_increment_rad, 9);
  line["range_max_m"] = scan.range_max_m;
  line["ranges_m"] = ranges_json(scan, 3);  // millimetres at most: three decimals are exact
}

Json telegram_json(const lms::Telegram& telegram, const CaptureReader& capture) {
  Json line;
  add_time(line, capture, telegram.stamp_ns);
  line["offset"] = telegram.start_offset;
  line["address"] = hex_byte(telegram.address);
  line["command"] = hex_byte(telegram.command);
  line["status"] = telegram.has_status ? Json(hex_byte(telegram.status)) : Json();
  line["severity"] = severity_name(telegram.device_status.severity);
  if (telegram.has_scan) {
    add_scan(line, telegram);
  } else {
    line["data"] = hex_bytes(telegram.data);
  }
  return line;
}

// One line for a step with an event; nothing for kNone.
void print_step(const lms::Decoder::Step& step, const CaptureReader& capture, std::ostream& out) {
  using Event = lms::Decoder::Event;
  Json line;
  switch (step.event) {
    case Event::kNone:
      return;
    case Event::kAck:
    case Event::kNak:
      line["command"] = step.event == Event::kAck ? "ACK" : "NAK";
      line["offset"] = step.offset;
      break;
    case Event::kTelegram:
      line = telegram_json(*step.telegram, capture);
      break;
    case Event::kRejected:
      line["error"] = lms::to_string(step.reason);
      line["offset"] = step.offset;
      break;
  }
  out << line.dump() << '\n';
}

}  // namespace

int decode_lms2xx(CaptureReader& capture, std::ostream& out, std::ostream& err) {
  lms::Decoder decoder;
  std::span<const std::uint8_t> piece;
  TimestampNs stamp_ns = 0;
  while (capture.next(piece, stamp_ns)) {
    std::span<const std::uint8_t> rest = piece;
    for (;;) {
      const lms::Decoder::Step step = decoder.push(rest, stamp_ns);
      rest = rest.subspan(step.consumed);
      print_step(step, capture, out);
      if (step.event == lms::Decoder::Event::kNone) {
        break;
      }
    }
  }
  for (;;) {  // the end of the capture: a telegram cut off there is reported as truncated
    const lms::Decoder::Step step = decoder.flush();
    print_step(step, capture, out);
    if (step.event == lms::Decoder::Event::kNone) {
      break;
    }
  }
  err << "lms2xx: " << decoder.telegrams_decoded() << " telegrams decoded ("
      << decoder.scans_decoded() << " scans), " << decoder.acks() << " ACK, " << decoder.naks()
      << " NAK";
  print_drops(err, decoder.drops());
  err << '\n';
  return kExitOk;
}

}  // namespace blockmap::cli
