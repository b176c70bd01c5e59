// `blockmap decode cola`: one JSON object per telegram of a SICK TiM/LMS1xx/LMS5xx CoLa stream
// (docs/protocols.md section 3), CoLa A or CoLa B as detected from the first telegram: its
// offset, dialect, type and command; for an LMDscandata scan the beam count, start and step in
// degrees (scanner frame: x forward, counter-clockwise), scan frequency, the device's counters,
// ranges_m (null for beams without a valid return) and rssi when present; for other telegrams the
// payload (hex for CoLa B, text for CoLa A). Dropped candidates are {"error": reason, "offset": N}.
//
// The capture is raw bytes, or the JSON list of TCP segments that SICK's pcap_json_converter
// writes (a file starting with '['), whose "tcp.payload" hex strings are joined in order; offsets
// then count bytes of the joined payloads.
#include <cctype>
#include <cstdio>
#include <memory>
#include <numbers>
#include <ostream>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "blockmap/core/angles.hpp"
#include "blockmap/hal/protocol/sick_cola.hpp"
#include "cli.hpp"
#include "commands/decoders.hpp"

namespace blockmap::cli {
namespace {

namespace cola = hal::protocol::sick_cola;

bool looks_like_json(const std::vector<std::uint8_t>& bytes) {
  for (const std::uint8_t byte : bytes) {
    if (std::isspace(byte) == 0) {
      return byte == '[';
    }
  }
  return false;
}

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

// "02:02:02:02:00:..." appended to `stream`; false when it is not colon-separated hex.
bool append_hex(const std::string& text, std::vector<std::uint8_t>& stream) {
  for (std::size_t i = 0; i < text.size(); i += 3) {
    const int high = hex_value(text[i]);
    const int low = i + 1 < text.size() ? hex_value(text[i + 1]) : -1;
    if (high < 0 || low < 0 || (i + 2 < text.size() && text[i + 2] != ':')) {
      return false;
    }
    stream.push_back(static_cast<std::uint8_t>(high * 16 + low));
  }
  return true;
}

// The joined "tcp.payload" strings of the list, in order. They are found in the text itself,
// not through a JSON parser, so that a damaged byte costs only the segment it falls in: a
// payload that is not colon-separated hex is left out and counted.
struct Payloads {
  std::size_t segments = 0;
  std::size_t damaged = 0;
  std::size_t first_damaged = 0;  // 1-based, among the segments
};

Payloads payloads_of_json(const Capture& capture, std::vector<std::uint8_t>& stream) {
  const std::string_view text(reinterpret_cast<const char*>(capture.bytes.data()),
                              capture.bytes.size());
  constexpr std::string_view kKey = "\"tcp.payload\"";
  Payloads payloads;
  std::vector<std::uint8_t> piece;
  for (std::size_t at = text.find(kKey); at != std::string_view::npos; at = text.find(kKey, at)) {
    ++payloads.segments;
    at = text.find_first_not_of(" \t\r\n", at + kKey.size());
    const bool colon = at != std::string_view::npos && text[at] == ':';
    const std::size_t open = colon ? text.find_first_not_of(" \t\r\n", at + 1) : at;
    const bool quoted = colon && open != std::string_view::npos && text[open] == '"';
    const std::size_t close = quoted ? text.find('"', open + 1) : std::string_view::npos;
    piece.clear();
    if (close == std::string_view::npos ||
        !append_hex(std::string(text.substr(open + 1, close - open - 1)), piece)) {
      payloads.first_damaged = payloads.damaged == 0 ? payloads.segments : payloads.first_damaged;
      ++payloads.damaged;
      continue;
    }
    stream.insert(stream.end(), piece.begin(), piece.end());
    at = close + 1;
  }
  return payloads;
}

std::string payload_text(const cola::Telegram& telegram) {
  std::string text;
  if (telegram.dialect == cola::Dialect::kColaA) {
    text.assign(telegram.payload.begin(), telegram.payload.end());
    return text;
  }
  text.reserve(telegram.payload.size() * 2);
  for (const std::uint8_t byte : telegram.payload) {
    char pair[4];
    std::snprintf(pair, sizeof pair, "%02X", static_cast<unsigned>(byte));
    text += pair;
  }
  return text;
}

void add_scan(Json& line, const msg::LaserScan& scan, const cola::ScanInfo& info) {
  line["beams"] = scan.beam_count;
  line["start_deg"] = rounded(scan.start_angle_rad * kDegreesPerRadian, 6);
  line["step_deg"] = rounded(scan.angle_increment_rad * kDegreesPerRadian, 6);
  line["scan_hz"] = rounded(static_cast<double>(info.scan_frequency_centihz) / 100.0, 2);
  line["scan_counter"] = info.scan_counter;
  line["telegram_counter"] = info.telegram_counter;
  line["time_since_startup_us"] = info.time_since_startup_us;
  line["ranges_m"] = ranges_json(scan, 4);  // mm at scale 1, and a tenth of a mm more
  if (scan.has_intensities) {
    Json rssi = Json::array();
    for (std::size_t i = 0; i < scan.beam_count; ++i) {
      // Device units, whole numbers as sent.
      rssi.push_back(static_cast<std::int64_t>(scan.intensities[i]));
    }
    line["rssi"] = std::move(rssi);
  }
}

void print_step(const cola::Decoder::Step& step, const Capture& capture, std::ostream& out) {
  Json line;
  if (step.telegram != nullptr) {
    const cola::Telegram& telegram = *step.telegram;
    add_time(line, capture, telegram.stamp_ns);
    line["offset"] = telegram.start_offset;
    line["dialect"] = cola::to_string(telegram.dialect);
    line["type"] = std::string(telegram.type);
    line["command"] = std::string(telegram.command);
    if (step.scan != nullptr) {
      add_scan(line, *step.scan, *step.scan_info);
    } else {
      line["payload"] = payload_text(telegram);
    }
  } else if (step.rejected) {
    line["error"] = cola::to_string(step.reason);
    line["offset"] = step.start_offset;
  } else {
    return;
  }
  out << line.dump() << '\n';
}

}  // namespace

int decode_cola(const Capture& capture, std::ostream& out, std::ostream& err) {
  std::vector<std::uint8_t> joined;
  const bool json = looks_like_json(capture.bytes);
  Payloads payloads;
  if (json) {
    payloads = payloads_of_json(capture, joined);
  }
  const std::vector<std::uint8_t>& bytes = json ? joined : capture.bytes;
  // Offline decoding may allocate: the decoder lives on the heap, not on a small stack.
  auto decoder = std::make_unique<cola::StaticDecoder<>>();
  const std::vector<Chunk> whole = {{0, bytes.size(), 0}};
  for (const Chunk& chunk : json ? whole : capture.chunks) {
    std::span<const std::uint8_t> rest(bytes.data() + chunk.offset, chunk.length);
    for (;;) {
      const cola::Decoder::Step step = decoder->push(rest, chunk.stamp_ns);
      rest = rest.subspan(step.consumed);
      print_step(step, capture, out);
      if (rest.empty() && !step.has_event()) {
        break;
      }
    }
  }
  for (;;) {  // the end of the capture: a telegram cut off there is reported as truncated
    const cola::Decoder::Step step = decoder->flush();
    print_step(step, capture, out);
    if (!step.has_event()) {
      break;
    }
  }
  err << "cola: " << decoder->telegrams_decoded() << " telegrams decoded ("
      << decoder->scans_decoded() << " scans)";
  print_drops(err, decoder->drops());
  err << ", " << decoder->dropped_bytes() << " bytes dropped";
  if (json) {
    err << "; " << payloads.segments << " TCP segments, " << payloads.damaged
        << " damaged and left out";
    if (payloads.damaged > 0) {
      err << " (the first: segment " << payloads.first_damaged << ")";
    }
  }
  err << '\n';
  return kExitOk;
}

}  // namespace blockmap::cli
