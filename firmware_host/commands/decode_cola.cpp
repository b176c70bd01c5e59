// `blockmap decode cola`: one JSON object per telegram of a SICK TiM/LMS1xx/LMS5xx CoLa stream
// (docs/protocols.md section 3), CoLa A or CoLa B as detected from the first telegram: its
// offset, dialect, type and command; for an LMDscandata scan the beam count, start and step in
// degrees (scanner frame: x forward, counter-clockwise), scan frequency, the device's counters,
// ranges_m (null for beams without a valid return) and rssi when present; for other telegrams the
// payload (hex for CoLa B, text for CoLa A). Dropped candidates are {"error": reason, "offset": N}.
//
// The capture is raw bytes, or the JSON list of TCP segments that SICK's pcap_json_converter
// writes (its first byte that is not a space is '['), whose "tcp.payload" hex strings are
// joined in order; offsets then count bytes of the joined payloads.
#include <algorithm>
#include <cctype>
#include <cstdio>
#include <memory>
#include <numbers>
#include <optional>
#include <ostream>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "blockmap/core/angles.hpp"
#include "blockmap/hal/protocol/sick_cola.hpp"
#include "cli.hpp"
#include "commands/decoders.hpp"

namespace blockmap::cli {
namespace {

namespace cola = hal::protocol::sick_cola;

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

// "02:02:02:02:00:..." appended to `stream`; false when it is not colon-separated hex.
bool append_hex(std::string_view text, std::vector<std::uint8_t>& stream) {
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

// The joined "tcp.payload" strings of the list, in order, found piece by piece in the text
// itself, not through a JSON parser, so that a damaged byte costs only the segment it falls
// in: a payload that is not colon-separated hex is left out and counted.
class JsonPayloads {
 public:
  // The bytes of the payloads `text` completes (valid until the next call); at the end, a
  // payload still open is a damaged one.
  std::span<const std::uint8_t> feed(std::span<const std::uint8_t> text, bool at_end) {
    text_.append(reinterpret_cast<const char*>(text.data()), text.size());
    bytes_.clear();
    std::size_t decided = 0;  // the text before it needs no more looking at
    for (;;) {
      const std::size_t key_at = std::string_view(text_).find(kKey, decided);
      if (key_at == std::string_view::npos) {
        // Keep what could be the start of a key.
        const std::size_t keep = at_end ? 0 : std::min(text_.size(), kKey.size() - 1);
        decided = std::max(decided, text_.size() - keep);
        break;
      }
      std::size_t open = 0;
      std::size_t close = 0;
      const Found found = payload_at(key_at, at_end, open, close, decided);
      if (found == Found::kNeedMore) {
        decided = key_at;
        break;
      }
      ++segments_;
      piece_.clear();
      if (found == Found::kPayload &&
          append_hex(std::string_view(text_).substr(open + 1, close - open - 1), piece_)) {
        bytes_.insert(bytes_.end(), piece_.begin(), piece_.end());
        decided = close + 1;
        continue;
      }
      first_damaged_ = damaged_ == 0 ? segments_ : first_damaged_;
      ++damaged_;
    }
    text_.erase(0, decided);
    return bytes_;
  }
  [[nodiscard]] std::size_t segments() const noexcept { return segments_; }
  [[nodiscard]] std::size_t damaged() const noexcept { return damaged_; }
  [[nodiscard]] std::size_t first_damaged() const noexcept { return first_damaged_; }  // 1-based

 private:
  enum class Found { kPayload, kDamaged, kNeedMore };
  static constexpr std::string_view kKey = "\"tcp.payload\"";
  static constexpr std::string_view kSpace = " \t\r\n";
  // A segment's payload is far shorter: an unclosed string this long is a damaged one.
  static constexpr std::size_t kMaxPayloadTextBytes = std::size_t{1} << 22;

  // What follows the key at `key_at`: a payload between the quotes at `open` and `close`, a
  // damaged one (the next key is looked for from `resume`), or not yet known.
  Found payload_at(std::size_t key_at, bool at_end, std::size_t& open, std::size_t& close,
                   std::size_t& resume) const {
    const std::string_view text(text_);
    const std::size_t at = text.find_first_not_of(kSpace, key_at + kKey.size());
    if (at == std::string_view::npos) {
      resume = text.size();
      return at_end ? Found::kDamaged : Found::kNeedMore;
    }
    resume = at;
    if (text[at] != ':') {
      return Found::kDamaged;
    }
    open = text.find_first_not_of(kSpace, at + 1);
    if (open == std::string_view::npos) {
      return at_end ? Found::kDamaged : Found::kNeedMore;
    }
    if (text[open] != '"') {
      return Found::kDamaged;
    }
    close = text.find('"', open + 1);
    if (close == std::string_view::npos) {
      return at_end || text.size() - open > kMaxPayloadTextBytes ? Found::kDamaged
                                                                 : Found::kNeedMore;
    }
    return Found::kPayload;
  }

  std::string text_;  // from the first byte not yet decided
  std::vector<std::uint8_t> piece_;
  std::vector<std::uint8_t> bytes_;
  std::size_t segments_ = 0;
  std::size_t damaged_ = 0;
  std::size_t first_damaged_ = 0;
};

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

void print_step(const cola::Decoder::Step& step, const CaptureReader& capture, std::ostream& out) {
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

// Whether a capture whose first piece is `first` is SICK's JSON list: its first byte that is
// not a space is '[' (a first piece of spaces only is a raw stream).
bool looks_like_json(std::span<const std::uint8_t> first) {
  const auto byte =
      std::find_if(first.begin(), first.end(), [](std::uint8_t b) { return std::isspace(b) == 0; });
  return byte != first.end() && *byte == '[';
}

void decode_bytes(cola::Decoder& decoder, std::span<const std::uint8_t> rest, TimestampNs stamp_ns,
                  const CaptureReader& capture, std::ostream& out) {
  for (;;) {
    const cola::Decoder::Step step = decoder.push(rest, stamp_ns);
    rest = rest.subspan(step.consumed);
    print_step(step, capture, out);
    if (rest.empty() && !step.has_event()) {
      break;
    }
  }
}

}  // namespace

int decode_cola(CaptureReader& capture, std::ostream& out, std::ostream& err) {
  // Offline decoding may allocate: the decoder lives on the heap, not on a small stack.
  auto decoder = std::make_unique<cola::StaticDecoder<>>();
  std::optional<JsonPayloads> json;
  std::span<const std::uint8_t> piece;
  TimestampNs stamp_ns = 0;
  for (bool first = true; capture.next(piece, stamp_ns); first = false) {
    if (first && looks_like_json(piece)) {
      json.emplace();
    }
    if (json) {
      decode_bytes(*decoder, json->feed(piece, false), 0, capture, out);
    } else {
      decode_bytes(*decoder, piece, stamp_ns, capture, out);
    }
  }
  if (json) {
    decode_bytes(*decoder, json->feed({}, true), 0, capture, out);
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
    err << "; " << json->segments() << " TCP segments, " << json->damaged()
        << " damaged and left out";
    if (json->damaged() > 0) {
      err << " (the first: segment " << json->first_damaged() << ")";
    }
  }
  err << '\n';
  return kExitOk;
}

}  // namespace blockmap::cli
