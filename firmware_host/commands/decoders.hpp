// The protocol decoders behind `blockmap decode`: each turns a capture, read piece by piece,
// into JSON Lines on `out` (one message a line, decoding errors as {"error": ...,
// "line"/"offset": ...} lines) and prints a one-line summary of what it dropped, and why, on
// `err`, in memory that does not grow with the capture. Adding a protocol is a file
// decode_<name>.cpp and one entry in kDecoders (decode.cpp).
#pragma once

#include <cstdint>
#include <deque>
#include <iosfwd>
#include <span>
#include <string>

#include <nlohmann/json.hpp>
#include <ostream>

#include "blockmap/core/time.hpp"
#include "blockmap/hal/protocol/drop_counters.hpp"
#include "blockmap/msg/laser_scan.hpp"
#include "commands/capture_reader.hpp"

namespace blockmap::cli {

using Json = nlohmann::ordered_json;

// A decoded message's time in a timed capture: Unix seconds with microseconds.
void add_time(Json& line, const CaptureReader& capture, TimestampNs stamp_ns);

using DecoderFunction = int (*)(CaptureReader& capture, std::ostream& out, std::ostream& err);

int decode_nmea(CaptureReader& capture, std::ostream& out, std::ostream& err);
int decode_rmp(CaptureReader& capture, std::ostream& out, std::ostream& err);
int decode_scip2(CaptureReader& capture, std::ostream& out, std::ostream& err);
int decode_lms2xx(CaptureReader& capture, std::ostream& out, std::ostream& err);
int decode_cola(CaptureReader& capture, std::ostream& out, std::ostream& err);

// The 1-based line of a byte offset of a text capture fed piece by piece, for error reports;
// exact for offsets in the last kLookBackBytes fed (a decoder reports where a sentence it
// rejects began, never further back).
class LineCounter {
 public:
  // The next piece of the stream, before it is decoded.
  void feed(std::span<const std::uint8_t> bytes);
  [[nodiscard]] std::size_t line_of(std::uint64_t offset) const;

 private:
  static constexpr std::uint64_t kLookBackBytes = std::uint64_t{1} << 16;
  std::deque<std::uint64_t> newlines_;  // the offsets of those in the last kLookBackBytes
  std::size_t older_ = 0;               // newlines before them
  std::uint64_t fed_ = 0;
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
