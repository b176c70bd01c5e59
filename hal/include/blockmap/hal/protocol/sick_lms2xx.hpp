// SICK LMS 200 / 291 serial telegram codec (docs/protocols.md section 2): scanner bytes in,
// ACK/NAK events, reply telegrams and LaserScans out; request telegrams (and, for a simulated
// scanner, reply and measured-values telegrams) encoded into caller-provided buffers.
//
// Pure: no file descriptors, no clock, no heap, no exceptions. Bytes may arrive in any chunking;
// the result is the same. A telegram is stamped with the receive time of the chunk that held its
// STX. Framing (2.2): STX(02) ADDR LEN_lo LEN_hi CMD data... [STATUS] CRC_lo CRC_hi, LEN <= 806
// (812 bytes in all), CRC as in 2.3. A candidate that fails the address, length or CRC check is
// dropped and the search restarts at the byte after its STX, so a real telegram that began
// inside the rejected bytes is still found.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>

#include "blockmap/core/counter.hpp"
#include "blockmap/core/time.hpp"
#include "blockmap/hal/protocol/drop_counters.hpp"
#include "blockmap/msg/device_status.hpp"
#include "blockmap/msg/header.hpp"
#include "blockmap/msg/laser_scan.hpp"

namespace blockmap::hal::protocol::sick_lms2xx {

// --- framing constants (docs/protocols.md 2.2, 2.4)

inline constexpr std::uint8_t kStx = 0x02;
inline constexpr std::uint8_t kAckByte = 0x06;
inline constexpr std::uint8_t kNakByte = 0x15;
inline constexpr std::uint8_t kHostAddress = 0x00;   // requests: broadcast / first device
inline constexpr std::uint8_t kReplyAddress = 0x80;  // replies: 0x80 | device address
inline constexpr std::size_t kMaxTelegramBytes = 812;
inline constexpr std::size_t kFrameOverheadBytes = 6;  // STX, ADDR, LEN (2), CRC (2)
inline constexpr std::size_t kMaxBodyBytes = kMaxTelegramBytes - kFrameOverheadBytes;
// Enough for every named request encoder below (the longest, installation mode, is 16 bytes).
inline constexpr std::size_t kRequestBufferBytes = 16;

// Command bytes (docs/protocols.md 2.5); a reply's command is the request's + 0x80 (2.2).
namespace command {
inline constexpr std::uint8_t kReset = 0x10;
inline constexpr std::uint8_t kSwitchMode = 0x20;
inline constexpr std::uint8_t kRequestValues = 0x30;
inline constexpr std::uint8_t kStatus = 0x31;
inline constexpr std::uint8_t kDeviceType = 0x3A;
inline constexpr std::uint8_t kVariant = 0x3B;
inline constexpr std::uint8_t kReadConfiguration = 0x74;
inline constexpr std::uint8_t kWriteConfiguration = 0x77;
inline constexpr std::uint8_t kReplyOffset = 0x80;
inline constexpr std::uint8_t kPowerOn = 0x90;
inline constexpr std::uint8_t kResetAck = 0x91;
inline constexpr std::uint8_t kNotAcknowledged = 0x92;  // "incorrect command"
inline constexpr std::uint8_t kSwitchModeReply = 0xA0;
inline constexpr std::uint8_t kMeasuredValues = 0xB0;
inline constexpr std::uint8_t kStatusReply = 0xB1;
inline constexpr std::uint8_t kSubRangeValues = 0xB7;
inline constexpr std::uint8_t kDeviceTypeReply = 0xBA;
inline constexpr std::uint8_t kVariantReply = 0xBB;
inline constexpr std::uint8_t kConfigurationReply = 0xF4;
inline constexpr std::uint8_t kWriteConfigurationReply = 0xF7;
}  // namespace command

// Mode bytes after 20 (docs/protocols.md 2.5).
namespace mode {
inline constexpr std::uint8_t kInstallation = 0x00;
inline constexpr std::uint8_t kContinuousAllValues = 0x24;
inline constexpr std::uint8_t kValuesOnRequest = 0x25;
inline constexpr std::uint8_t kBaud38400 = 0x40;
inline constexpr std::uint8_t kBaud19200 = 0x41;
inline constexpr std::uint8_t kBaud9600 = 0x42;
inline constexpr std::uint8_t kBaud500000 = 0x48;
}  // namespace mode

inline constexpr std::string_view kDefaultPassword = "SICK_LMS";

// --- the measured values (docs/protocols.md 2.6, 2.8)

// Count word bits 14-15.
enum class Units : std::uint8_t { kCm = 0, kMm = 1 };
[[nodiscard]] const char* to_string(Units units) noexcept;  // "cm", "mm"
[[nodiscard]] double metres_per_unit(Units units) noexcept;

// Scan field and angular resolution, as set with 3B.
enum class AngularVariant : std::uint8_t {
  k180Deg1Deg,       // 181 values
  k180DegHalfDeg,    // 361
  k100Deg1Deg,       // 101
  k100DegHalfDeg,    // 201
  k100DegQuarterDeg  // 401 (0.25 deg exists only with the 100 deg field)
};
[[nodiscard]] const char* to_string(AngularVariant variant) noexcept;  // "180/1", "100/0.25", ...
struct VariantGeometry {
  std::uint16_t field_deg = 0;            // 180 or 100
  std::uint16_t resolution_centideg = 0;  // 100, 50 or 25, as the 3B telegram carries it
  std::uint16_t value_count = 0;          // field / resolution + 1
};
[[nodiscard]] VariantGeometry geometry(AngularVariant variant) noexcept;
// The variant whose value count is `count`; none for other counts.
[[nodiscard]] std::optional<AngularVariant> variant_from_count(std::size_t count) noexcept;

// Range bits of a measuring mode (configuration byte 5, docs/protocols.md 2.5/2.6): modes 00-02 ->
// 13, 03-05 -> 14, 06 -> 15; none for the other modes (0F, 3F reflectivity, unknown).
[[nodiscard]] std::optional<std::uint8_t> range_bits_of_measuring_mode(std::uint8_t mode) noexcept;

// The nominal measuring range: 8 / 16 / 32 m for 13 / 14 / 15 range bits with mm units, ten
// times that with cm units (docs/protocols.md 2.5 "8 m vs 80 m follows the unit"). `range_bits`
// must be 13, 14 or 15 (CHECK).
[[nodiscard]] double range_max_m(Units units, std::uint8_t range_bits);

// The status byte's health (docs/protocols.md 2.7): bits 0-2 give the severity; pollution (0x80)
// and implausible values (0x40) raise it to at least a warning, a restart (0x20) to at least info.
// Bit 4 (0x10), set in every real reply, is not an error.
[[nodiscard]] msg::DeviceSeverity severity_of_status(std::uint8_t status) noexcept;

// --- CRC (docs/protocols.md 2.3)

// Over STX up to the last byte before the CRC; appended low byte first.
[[nodiscard]] std::uint16_t crc16(std::span<const std::uint8_t> bytes) noexcept;

// --- encoders. Each writes one whole telegram to the front of `out` and returns its length, or
// returns 0 and leaves `out` unspecified when it cannot: `out` too small, the telegram longer
// than 812 bytes, or an argument the protocol cannot carry.

// Frames `body` (command byte, data and, for a reply, the status byte) for `address`.
[[nodiscard]] std::size_t encode_telegram(std::span<std::uint8_t> out, std::uint8_t address,
                                          std::span<const std::uint8_t> body) noexcept;
// A host request (address 00): `command_and_data` is the command byte and its data.
[[nodiscard]] std::size_t encode_request(std::span<std::uint8_t> out,
                                         std::span<const std::uint8_t> command_and_data) noexcept;

[[nodiscard]] std::size_t encode_status_request(std::span<std::uint8_t> out) noexcept;       // 31
[[nodiscard]] std::size_t encode_device_type_request(std::span<std::uint8_t> out) noexcept;  // 3A
[[nodiscard]] std::size_t encode_read_configuration(std::span<std::uint8_t> out) noexcept;   // 74
[[nodiscard]] std::size_t encode_request_scan(std::span<std::uint8_t> out) noexcept;  // 30 01
// 20 00 + the 8-character password; 0 for a password of another length.
[[nodiscard]] std::size_t encode_installation_mode(
    std::span<std::uint8_t> out, std::string_view password = kDefaultPassword) noexcept;
[[nodiscard]] std::size_t encode_continuous_output(std::span<std::uint8_t> out) noexcept;  // 20 24
[[nodiscard]] std::size_t encode_stop_continuous_output(
    std::span<std::uint8_t> out) noexcept;  // 20 25
// The mode byte of a baud rate: 9600, 19200, 38400, 500000 (RS-422 only); none for others.
[[nodiscard]] std::optional<std::uint8_t> baud_mode(std::uint32_t baud_bps) noexcept;
// 20 40/41/42/48; 0 for an unsupported rate. Send at the old rate (docs/protocols.md 2.4).
[[nodiscard]] std::size_t encode_set_baud(std::span<std::uint8_t> out,
                                          std::uint32_t baud_bps) noexcept;
// 3B angle_lo angle_hi res_lo res_hi.
[[nodiscard]] std::size_t encode_variant(std::span<std::uint8_t> out,
                                         AngularVariant variant) noexcept;

// A reply as a scanner sends it: command, data, status (for a simulated scanner and tests).
[[nodiscard]] std::size_t encode_reply(std::span<std::uint8_t> out, std::uint8_t reply_command,
                                       std::span<const std::uint8_t> data, std::uint8_t status,
                                       std::uint8_t address = kReplyAddress) noexcept;
// A B0 measured-values telegram: the count word (value count | units << 14), the value words as
// given (range codes and flag bits, see encode_beam), then the status byte. 0 for more than 401
// values (the telegram would exceed 812 bytes).
[[nodiscard]] std::size_t encode_measured_values(std::span<std::uint8_t> out,
                                                 std::span<const std::uint16_t> values, Units units,
                                                 std::uint8_t status,
                                                 std::uint8_t address = kReplyAddress) noexcept;
// The value word of one beam: the range in `units` when `status` is kValid, else a reserved
// code: kNoReturn -> "value > max", kDazzled -> "dazzle", kDeviceError and kTooClose ->
// "not valid" (the device has no "too close" code). A range that does not fit below the
// reserved codes, or is negative or not a number, becomes "value > max" / "not valid".
// `range_bits` must be 13, 14 or 15 (CHECK).
[[nodiscard]] std::uint16_t encode_beam(double range_m, msg::BeamStatus status, Units units,
                                        std::uint8_t range_bits);

// --- decoder

// Why bytes or telegrams were not turned into events. kGarbage counts bytes; the other reasons
// count telegrams (candidates). kUnsupported is a valid telegram this codec does not interpret.
enum class DropReason : std::uint8_t {
  kGarbage,      // bytes outside any telegram: noise, a partial telegram at the start, an STX
                 // not followed by the reply address, bytes of a rejected candidate
  kBadLength,    // LEN below the minimum or the telegram above 812 bytes
  kBadCrc,       // the CRC does not match (a damaged telegram, or a false STX in noise)
  kTruncated,    // the input ended inside a telegram (flush())
  kMalformed,    // a valid CRC over impossible contents (B0 count vs LEN, units, variant)
  kUnsupported,  // a valid telegram of a command not decoded here, or an interlaced partial scan
  kCount
};
[[nodiscard]] const char* to_string(DropReason reason) noexcept;  // "bad_crc", ...

struct Config {
  msg::SourceId source_id = 0;
  // Range bits of the measured values: 13 (measuring modes 00-02, the power-on default), 14
  // (03-05) or 15 (06). See range_bits_of_measuring_mode.
  std::uint8_t range_bits = 13;
  // The angular variant of B0 telegrams; when not set, inferred from the value count (181, 361,
  // 101, 201, 401). When set, a B0 with another count is rejected as malformed.
  std::optional<AngularVariant> variant;
  // Only telegrams addressed 0x80 (a single scanner's replies). When false, any address: replies
  // of a scanner at another RS-485 address, and the host's requests (which have no status).
  bool require_reply_address = true;
};

// A decoded telegram. `data` and everything else are valid until the next push() or flush().
struct Telegram {
  std::uint64_t start_offset = 0;  // stream offset of its STX, counted from the first byte fed
  TimestampNs stamp_ns = 0;        // receive time of the chunk that held its STX
  std::uint8_t address = 0;
  std::uint8_t command = 0;  // the command or reply byte (B0, A0, ...)
  bool has_status = false;   // replies (address bit 7 set) carry a status byte, requests do not
  std::uint8_t status = 0;
  std::span<const std::uint8_t> data;  // after the command byte, before the status byte
  msg::DeviceStatus device_status;     // replies: the status byte's severity (2.7)

  // B0 only (has_scan): the measured values as a scan in the scanner frame (x forward, y left,
  // counter-clockwise positive): value i at i * resolution - 90 deg (180 deg field) or
  // - 50 deg (100 deg field). Ranges in metres; non-valid beams have range 0 and a status.
  bool has_scan = false;
  std::uint16_t count_word = 0;
  Units units = Units::kCm;
  AngularVariant variant = AngularVariant::k180Deg1Deg;
  std::size_t trailing_bytes = 0;  // bytes between the last value and the status (indices)
  msg::LaserScan scan;
};

class Decoder {
 public:
  explicit Decoder(const Config& config = {});

  enum class Event : std::uint8_t { kNone, kAck, kNak, kTelegram, kRejected };

  // What one push() did: `consumed` bytes of its input were used; at most one event happened.
  struct Step {
    std::size_t consumed = 0;
    Event event = Event::kNone;
    const Telegram* telegram = nullptr;        // kTelegram
    DropReason reason = DropReason::kGarbage;  // kRejected
    std::uint64_t offset = 0;  // stream offset of the ACK/NAK byte or of the rejected STX
  };

  // Consumes bytes up to and including the one that completes the next event, or all of them.
  // A rejected candidate's bytes after its STX are examined again before new input, so an
  // event may come from bytes consumed by an earlier call (then `consumed` may be 0). Call
  // push() again with the rest of the input (possibly empty) until it returns Event::kNone:
  // that step has consumed everything. Never allocates. O(bytes) on a clean stream; each
  // rejected candidate costs re-examining its bytes (at most 811), and a telegram hidden behind
  // a false STX is found only once that candidate's LEN has elapsed.
  Step push(std::span<const std::uint8_t> bytes, TimestampNs rx_stamp_ns);

  // End of input: a telegram still incomplete is rejected as kTruncated and the bytes after its
  // STX are examined again. Call it until it returns Event::kNone.
  Step flush();

  [[nodiscard]] const DropCounters<DropReason>& drops() const noexcept { return drops_; }
  [[nodiscard]] std::uint64_t telegrams_decoded() const noexcept { return telegrams_.value(); }
  [[nodiscard]] std::uint64_t scans_decoded() const noexcept { return scans_.value(); }
  [[nodiscard]] std::uint64_t acks() const noexcept { return acks_.value(); }
  // NAK bytes (15): the scanner refused a request (bad CRC or format, docs/protocols.md 2.4).
  [[nodiscard]] std::uint64_t naks() const noexcept { return naks_.value(); }

 private:
  Step run(std::span<const std::uint8_t> bytes, TimestampNs rx_stamp_ns, bool end_of_input);
  Step on_byte(std::uint8_t byte, TimestampNs stamp_ns, std::uint64_t offset, bool replayed);
  Step hunt(std::uint8_t byte, TimestampNs stamp_ns, std::uint64_t offset, bool replayed);
  Step reject(DropReason reason);
  void replay_after_stx();
  Step finish_telegram();
  [[nodiscard]] std::optional<DropReason> read_measured_values();
  [[nodiscard]] bool address_accepted(std::uint8_t address) const noexcept;
  [[nodiscard]] std::size_t declared_telegram_bytes() const noexcept;

  Config config_;
  std::uint16_t range_mask_ = 0;
  // The current candidate, STX at index 0, and each byte's receive stamp. After a rejection the
  // bytes to examine again ([replay_next_, replay_end_)) are kept here too: a new candidate is
  // written at or before the byte being read, so one buffer serves both.
  std::array<std::uint8_t, kMaxTelegramBytes> frame_{};
  std::array<TimestampNs, kMaxTelegramBytes> stamps_{};
  std::size_t frame_length_ = 0;
  std::size_t replay_next_ = 0;
  std::size_t replay_end_ = 0;
  std::uint64_t frame_offset_ = 0;   // stream offset of frame_[0]
  std::uint64_t replay_offset_ = 0;  // stream offset of frame_[replay_next_]
  std::uint64_t stream_offset_ = 0;  // stream offset of the next new byte
  Telegram telegram_;
  DropCounters<DropReason> drops_;
  MonotonicCounter telegrams_;
  MonotonicCounter scans_;
  MonotonicCounter acks_;
  MonotonicCounter naks_;
};

}  // namespace blockmap::hal::protocol::sick_lms2xx
