// Hokuyo SCIP 2.0 codec (URG/UTM laser scanners over USB CDC-ACM or serial; docs/protocols.md
// section 4). Pure: no file descriptors, no clock, no heap after construction.
//
// The sensor answers every command with a block of lines ended by an empty line: the echo of
// the command, a status line, then data. The decoder frames these blocks from any chunking,
// checks every line's checksum, and hands out either a scan (GD/GS/MD/MS replies) as a
// msg::LaserScan, or the reply itself (status, parameter lines). A PP reply updates the sensor
// geometry used for later scans. The 24-bit millisecond timestamps are unwrapped.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>

#include "blockmap/core/counter.hpp"
#include "blockmap/core/time.hpp"
#include "blockmap/hal/protocol/drop_counters.hpp"
#include "blockmap/msg/laser_scan.hpp"

namespace blockmap::hal::protocol::hokuyo_scip2 {

// The geometry a PP reply reports (docs/protocols.md 4.6). Defaults: the URG-04LX of the real
// session.
struct SensorParameters {
  std::uint32_t min_range_mm = 20;      // DMIN
  std::uint32_t max_range_mm = 5600;    // DMAX
  std::uint32_t steps_per_turn = 1024;  // ARES
  std::uint32_t first_step = 44;        // AMIN
  std::uint32_t last_step = 725;        // AMAX
  std::uint32_t front_step = 384;       // AFRT
  std::uint32_t scan_rpm = 600;         // SCAN
};

enum class DropReason : std::uint8_t {
  kBadChecksum,   // a status, timestamp, data or parameter line whose checksum is wrong
  kTooLong,       // a reply larger than the buffer, or a line longer than a SCIP line can be
  kMalformed,     // an echo, status or data line that cannot be what the command says
  kBadCharacter,  // a byte outside printable ASCII
  kCount
};
[[nodiscard]] const char* to_string(DropReason reason) noexcept;

struct Config {
  msg::SourceId source_id = 0;
  SensorParameters sensor;  // until a PP reply says otherwise
};

inline constexpr std::size_t kMaxReplyBytes = 16384;  // a UTM-30LX intensity scan fits

// A reply that is not a scan, or the frame of one that is.
struct Reply {
  std::string_view echo;     // the command as echoed (without the line end)
  std::string_view status;   // two characters ("00", "99", "0C"...); one for SCIP 1.1 replies
  std::string_view body;     // the lines after the status line, each ending in '\n'
  TimestampNs stamp_ns = 0;  // arrival of the echo's first byte
};

class Decoder {
 public:
  explicit Decoder(const Config& config = {});

  struct Step {
    std::size_t consumed = 0;
    const Reply* reply = nullptr;  // any complete, checked reply (views valid until next push)
    const msg::LaserScan* scan = nullptr;  // also set for a scan reply with data
    bool rejected = false;
    DropReason reason = DropReason::kMalformed;
  };

  // Consumes bytes up to the end of the next reply, or all of them. O(bytes).
  Step push(std::span<const std::uint8_t> bytes, TimestampNs rx_stamp_ns);

  [[nodiscard]] const SensorParameters& sensor() const noexcept { return sensor_; }
  [[nodiscard]] const DropCounters<DropReason>& drops() const noexcept { return drops_; }
  [[nodiscard]] std::uint64_t replies_decoded() const noexcept { return replies_.value(); }
  [[nodiscard]] std::uint64_t scans_decoded() const noexcept { return scans_.value(); }
  // Sensor time of the last scan, unwrapped past the 24-bit counter (ms since the sensor's reset).
  [[nodiscard]] std::uint64_t sensor_time_ms() const noexcept { return sensor_time_ms_; }

 private:
  Step finish_reply(std::size_t consumed);
  Step reject(std::size_t consumed, DropReason reason);
  [[nodiscard]] bool read_parameters(std::string_view body);
  [[nodiscard]] bool read_scan(std::string_view echo, std::string_view body, bool& has_scan);

  Config config_;
  SensorParameters sensor_;
  std::array<char, kMaxReplyBytes> buffer_{};
  std::size_t length_ = 0;
  std::size_t line_start_ = 0;
  bool skipping_ = false;  // after an error: drop bytes until the blank line ending the reply
  TimestampNs reply_stamp_ns_ = 0;
  Reply reply_;
  msg::LaserScan scan_;
  std::uint32_t last_raw_time_ms_ = 0;
  std::uint64_t sensor_time_ms_ = 0;
  bool has_time_ = false;
  DropReason drops_reason_ = DropReason::kMalformed;  // why read_scan() failed
  DropCounters<DropReason> drops_;
  MonotonicCounter replies_;
  MonotonicCounter scans_;
};

// --- the character code and checksums (docs/protocols.md 4.2, 4.3)

// (sum of the bytes) & 0x3F, + 0x30.
[[nodiscard]] char checksum(std::string_view payload) noexcept;
// A value of `chars.size()` (2, 3 or 4) characters, 6 bits each, most significant first.
[[nodiscard]] std::uint32_t decode_value(std::string_view chars) noexcept;

// --- encoders (host commands, and a simulated sensor's replies), into `out`; return the length
// written, or 0 when `out` is too small or an argument is out of range.

// "GD0046072201\n": one scan of steps first..last, `cluster` steps per value; three-character
// values (`three_char` false: GS, two characters, up to 4095 mm).
[[nodiscard]] std::size_t encode_single_scan_request(std::span<char> out, std::uint32_t first_step,
                                                     std::uint32_t last_step, std::uint32_t cluster,
                                                     bool three_char = true) noexcept;
// "MD0044072501000\n": continuous scans (scan_count 0 = unlimited; skip = scans left out between
// two sent).
[[nodiscard]] std::size_t encode_continuous_request(std::span<char> out, std::uint32_t first_step,
                                                    std::uint32_t last_step, std::uint32_t cluster,
                                                    std::uint32_t skip, std::uint32_t scan_count,
                                                    bool three_char = true) noexcept;
// A scan reply as the sensor sends it: echo, status ("00" for G*, "99" for M*), the 24-bit
// timestamp and the values (mm) in 64-character lines with checksums, then a blank line.
[[nodiscard]] std::size_t encode_scan_reply(std::span<char> out, std::string_view echo,
                                            std::string_view status, std::uint32_t time_ms,
                                            std::span<const std::uint32_t> values_mm,
                                            bool three_char = true) noexcept;

}  // namespace blockmap::hal::protocol::hokuyo_scip2
