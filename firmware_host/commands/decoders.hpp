// The protocol decoders behind `blockmap decode`: each turns a whole capture into JSON Lines on
// `out` (one message a line, decoding errors as {"error": ..., "line"/"offset": ...} lines) and
// prints a one-line summary of what it dropped, and why, on `err`. Adding a protocol is a file
// decode_<name>.cpp and one entry in kDecoders (decode.cpp).
#pragma once

#include <cstdint>
#include <iosfwd>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <ostream>

#include "blockmap/core/time.hpp"
#include "blockmap/hal/protocol/drop_counters.hpp"
#include "blockmap/msg/laser_scan.hpp"

namespace blockmap::cli {

using Json = nlohmann::ordered_json;

// Bytes as one read returned them, and when (a timestamped byte log, docs/log-formats.md).
struct Chunk {
  std::size_t offset = 0;  // into Capture::bytes
  std::size_t length = 0;
  TimestampNs stamp_ns = 0;
};

// A whole capture: a raw byte stream (one chunk, no time), or the device-to-host bytes of a
// timestamped byte log, chunk by chunk (`timed`).
struct Capture {
  std::string path;
  std::vector<std::uint8_t> bytes;
  std::vector<Chunk> chunks;
  bool timed = false;
  std::size_t host_records = 0;  // host-to-device records of a byte log (not decoded)
};

// A decoded message's time in a timed capture: Unix seconds with microseconds.
void add_time(Json& line, const Capture& capture, TimestampNs stamp_ns);

using DecoderFunction = int (*)(const Capture& capture, std::ostream& out, std::ostream& err);

int decode_nmea(const Capture& capture, std::ostream& out, std::ostream& err);
int decode_rmp(const Capture& capture, std::ostream& out, std::ostream& err);
int decode_scip2(const Capture& capture, std::ostream& out, std::ostream& err);
int decode_lms2xx(const Capture& capture, std::ostream& out, std::ostream& err);
int decode_cola(const Capture& capture, std::ostream& out, std::ostream& err);

// 1-based line of a byte offset, for error reports that point into a text capture.
class LineIndex {
 public:
  explicit LineIndex(const std::vector<std::uint8_t>& bytes);
  [[nodiscard]] std::size_t line_of(std::uint64_t offset) const;

 private:
  std::vector<std::size_t> newlines_;
};

// Appends ", reason count" for every drop reason with a non-zero count: the tail of each
// decoder's one-line summary.
template <typename Reason>
void print_drops(std::ostream& err, const hal::protocol::DropCounters<Reason>& drops) {
  for (std::size_t r = 0; r < hal::protocol::DropCounters<Reason>::kReasons; ++r) {
    const auto reason = static_cast<Reason>(r);
    if (drops.value(reason) != 0) {
      err << ", " << to_string(reason) << " " << drops.value(reason);
    }
  }
}

// A scan's ranges as a JSON array in metres with `decimals` decimals; null where the beam has
// no valid range.
Json ranges_json(const msg::LaserScan& scan, int decimals);

// `value` with `decimals` decimals: the nearest double to that decimal, which JSON then prints
// in its shortest form (41.574970205, not 41.574970204999998).
Json rounded(double value, int decimals);

}  // namespace blockmap::cli
