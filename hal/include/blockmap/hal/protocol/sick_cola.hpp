// SICK CoLa codec (TiM5xx/7xx, LMS1xx, LMS5xx over TCP or USB; docs/protocols.md section 3):
// telegrams in CoLa A (ASCII, `02 ... 03`) or CoLa B (binary, `02 02 02 02` + u32 BE length +
// body + XOR) framing in, generic telegrams and LMDscandata scans (msg::LaserScan) out; and the
// host's commands, plus whole scan telegrams for a simulated scanner, encoded into caller buffers.
//
// Pure: no file descriptors, no clock, no heap after construction, no exceptions. Bytes may arrive
// in any chunking; the result is the same. A telegram is stamped with the receive time of the
// chunk that held its first STX.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>

#include "blockmap/core/arena.hpp"
#include "blockmap/core/counter.hpp"
#include "blockmap/core/inline_storage.hpp"
#include "blockmap/core/time.hpp"
#include "blockmap/hal/protocol/drop_counters.hpp"
#include "blockmap/msg/laser_scan.hpp"

namespace blockmap::hal::protocol::sick_cola {

enum class Dialect : std::uint8_t { kColaA, kColaB };
[[nodiscard]] const char* to_string(Dialect dialect) noexcept;  // "cola_a", "cola_b"

// Which framing the decoder accepts. kDetect reads it from the first telegram (`02 02 02 02` is
// CoLa B, `02 's'` is CoLa A) and keeps it from then on.
enum class Framing : std::uint8_t { kDetect, kColaA, kColaB };

// Why bytes or telegrams were not delivered. kGarbage counts bytes; every other reason counts
// telegrams (or what looked like the start of one).
enum class DropReason : std::uint8_t {
  kGarbage,       // bytes outside any telegram (line noise, a partial telegram at start)
  kBadLength,     // CoLa B: length field 0, or more than the telegram buffer holds
  kBadChecksum,   // CoLa B: XOR of the body differs (also how a cut-off telegram shows)
  kTruncated,     // CoLa A: a new STX before the ETX; either: input ended inside one (flush)
  kBadCharacter,  // CoLa A: a byte outside printable ASCII inside a telegram
  kTooLong,       // CoLa A: no ETX within the telegram buffer
  kMalformed,     // framed and checksummed, but not a CoLa telegram or not a valid scan
  kTooManyBeams,  // a scan with more than msg::kMaxLaserBeams beams
  kCount
};
[[nodiscard]] const char* to_string(DropReason reason) noexcept;  // "bad_checksum", ...

// An LMS511 scan at 1/6 degree with 16-bit RSSI is about 4.7 KB in CoLa B and 12 KB in CoLa A
// (5 characters a value); 16 KiB holds either. Multi-echo LMS5xx output (DIST1..5, RSSI1..5)
// needs a larger buffer.
inline constexpr std::size_t kDefaultTelegramCapacityBytes = std::size_t{16} * 1024;
inline constexpr std::size_t kMinTelegramCapacityBytes = 64;

struct Config {
  Framing framing = Framing::kDetect;
  // Size of the telegram buffer the Arena constructor takes; the span constructor uses the span.
  std::size_t telegram_capacity_bytes = kDefaultTelegramCapacityBytes;
  msg::SourceId source_id = 0;
  // A beam whose RSSI is 0 is "no echo" even when its distance is not 0 (TiM7xx sends 2 mm with
  // RSSI 0). docs/protocols.md 3.5 marks this [UNVERIFIED]; in all five real captures every beam
  // with RSSI 0 has distance 0 or 2.
  bool rssi_zero_is_no_return = true;
  // The model's range limits, copied into each LaserScan (the telegram does not carry them).
  // When range_min_m > 0, shorter returns are BeamStatus::kTooClose. 0 means unknown.
  double range_min_m = 0.0;
  double range_max_m = 0.0;
};

// The generic view of any telegram: "sRA LMDscandata <payload>", "sAN Run <payload>", ...
// Views point into the decoder's buffer and stay valid until the next push().
struct Telegram {
  Dialect dialect = Dialect::kColaB;
  std::string_view type;     // "sRA", "sSN", "sAN", "sEA", "sWA", "sFA" (error), ...
  std::string_view command;  // "LMDscandata", "SetAccessMode"; empty when none follows a space
  // What follows "type command ": binary fields (CoLa B) or space-separated tokens (CoLa A).
  std::span<const std::uint8_t> payload;
  std::uint64_t start_offset = 0;  // stream offset of its first STX, counted from the first byte
  TimestampNs stamp_ns = 0;        // receive time of the chunk that held its first STX
};

// One channel block of an LMDscandata telegram, as sent (docs/protocols.md 3.4).
struct ScanChannel {
  std::array<char, 6> name{};  // "DIST1", "RSSI1", NUL-terminated
  std::uint8_t bits = 0;       // 16 or 8
  float scale_factor = 0.0F;
  float scale_offset = 0.0F;
  std::int32_t start_angle_1e4deg = 0;  // SICK's angle, 1/10000 degree
  std::uint16_t step_1e4deg = 0;        // 1/10000 degree
  std::uint16_t count = 0;
};

// The optional time block (the device's clock, not synchronised to ours).
struct DeviceTime {
  std::uint16_t year = 0;
  std::uint8_t month = 0, day = 0, hour = 0, minute = 0, second = 0;
  std::uint32_t microsecond = 0;
};

// The LMDscandata fields a LaserScan does not carry (docs/protocols.md 3.4, in telegram order).
struct ScanInfo {
  std::uint16_t version = 0;
  std::uint16_t device_number = 0;
  std::uint32_t serial_number = 0;
  std::array<std::uint8_t, 2> device_status{};  // 0 0 = ok
  std::uint16_t telegram_counter = 0;
  std::uint16_t scan_counter = 0;
  std::uint32_t time_since_startup_us = 0;
  std::uint32_t time_of_transmission_us = 0;
  std::array<std::uint8_t, 2> digital_inputs{};
  std::array<std::uint8_t, 2> digital_outputs{};
  std::uint16_t reserved = 0;                       // layer angle on multi-layer devices
  std::uint32_t scan_frequency_centihz = 0;         // 1/100 Hz: 1500 = 15 Hz
  std::uint32_t measurement_frequency_hectohz = 0;  // x100 Hz: 162 = 16.2 kHz
  std::uint16_t encoder_count = 0;
  std::uint32_t encoder_position = 0;  // the first encoder's, when encoder_count > 0
  std::uint16_t encoder_speed = 0;
  std::uint16_t channel16_count = 0;
  std::uint16_t channel8_count = 0;
  ScanChannel distance;  // DIST1
  bool has_rssi = false;
  ScanChannel rssi;  // RSSI1
  bool has_device_time = false;
  DeviceTime device_time;
};

// The size-erased decoder: its telegram buffer is a span handed over at init (from the Arena, or
// the storage of StaticDecoder below).
class Decoder {
 public:
  // Views `telegram_storage` (its size is the longest telegram accepted); it must outlive this.
  explicit Decoder(std::span<std::uint8_t> telegram_storage, const Config& config = {});
  // Takes Config::telegram_capacity_bytes from the arena at init.
  Decoder(Arena& arena, const Config& config);

  Decoder(const Decoder&) = delete;
  Decoder& operator=(const Decoder&) = delete;
  ~Decoder() = default;

  // What one push() did. `consumed` bytes of the input were used. At most one event is set: a
  // `telegram` (with `scan` and `scan_info` when it is an LMDscandata scan), or `rejected`.
  // Pointers stay valid until the next push().
  struct Step {
    std::size_t consumed = 0;
    const Telegram* telegram = nullptr;
    const msg::LaserScan* scan = nullptr;
    const ScanInfo* scan_info = nullptr;
    bool rejected = false;
    DropReason reason = DropReason::kGarbage;  // when rejected
    std::uint64_t start_offset = 0;            // when rejected: where the telegram began
    [[nodiscard]] bool has_event() const noexcept { return telegram != nullptr || rejected; }
  };

  // Consumes bytes up to the end of the next telegram, or all of them. O(bytes); never allocates.
  // Call it again while input remains or the last step had an event: a telegram that began
  // inside rejected bytes (a false start pattern, a cut-off telegram) is held and delivered from
  // the buffer, possibly with `consumed` == 0. push({}, t) delivers what the buffer still holds.
  Step push(std::span<const std::uint8_t> bytes, TimestampNs rx_stamp_ns);

  // The input has ended or broken off (end of a capture, a reconnect): an unfinished telegram
  // is rejected as kTruncated and the bytes after its start are searched again. Call it until
  // it returns no event; buffered_bytes() is then 0.
  Step flush();

  [[nodiscard]] const DropCounters<DropReason>& drops() const noexcept { return drops_; }
  [[nodiscard]] std::uint64_t dropped_bytes() const noexcept { return dropped_bytes_.value(); }
  [[nodiscard]] std::uint64_t telegrams_decoded() const noexcept { return telegrams_.value(); }
  [[nodiscard]] std::uint64_t scans_decoded() const noexcept { return scans_.value(); }
  // Bytes of an unfinished telegram held for the next push.
  [[nodiscard]] std::size_t buffered_bytes() const noexcept { return length_ - delivered_; }
  [[nodiscard]] std::size_t capacity_bytes() const noexcept { return capacity_; }
  // The framing in use: the configured one, or the detected one (kDetect until the first).
  [[nodiscard]] Framing framing() const noexcept { return framing_; }
  [[nodiscard]] std::size_t memory_bytes() const noexcept { return capacity_ + sizeof(*this); }

 private:
  enum class Outcome : std::uint8_t { kNeedMore, kGarbage, kReject, kComplete };
  // kNeedMore: `bytes` = buffer length wanted (0: up to the next CoLa A stop byte);
  // kGarbage, kReject: `bytes` to drop from the front; kComplete: the frame length.
  struct Examination {
    Outcome outcome = Outcome::kNeedMore;
    std::size_t bytes = 0;
    DropReason reason = DropReason::kGarbage;
  };
  struct StampMark {
    std::uint64_t offset = 0;  // stream offset of the first byte received at `stamp_ns`
    TimestampNs stamp_ns = 0;
  };
  static constexpr std::size_t kStampMarks = 16;

  Step run(std::span<const std::uint8_t> bytes, TimestampNs rx_stamp_ns, bool end_of_input);
  [[nodiscard]] Examination examine() noexcept;
  [[nodiscard]] Examination examine_cola_b() noexcept;
  [[nodiscard]] Examination examine_cola_a() noexcept;
  [[nodiscard]] Dialect candidate_dialect() const noexcept;
  [[nodiscard]] bool possible_start(std::size_t index) const noexcept;
  [[nodiscard]] std::size_t next_start(std::size_t from) const noexcept;
  std::size_t skip_garbage(std::span<const std::uint8_t> bytes) noexcept;
  std::size_t append(std::span<const std::uint8_t> bytes, std::size_t wanted,
                     TimestampNs rx_stamp_ns) noexcept;
  void drop_front(std::size_t bytes) noexcept;
  [[nodiscard]] TimestampNs candidate_stamp() const noexcept;
  [[nodiscard]] std::uint64_t candidate_offset() const noexcept { return stream_offset_ - length_; }
  Step reject(std::size_t consumed, DropReason reason, std::size_t drop) noexcept;
  Step deliver(std::size_t consumed, std::size_t frame_bytes) noexcept;

  Config config_;
  Framing framing_;
  std::uint8_t* buffer_ = nullptr;
  std::size_t capacity_ = 0;
  std::size_t length_ = 0;     // bytes held; buffer_[0] is an STX whenever length_ > 0
  std::size_t scanned_ = 1;    // CoLa A: bytes already searched for a stop byte
  std::size_t delivered_ = 0;  // a delivered frame still viewed by the caller, dropped next push
  std::uint64_t stream_offset_ = 0;  // bytes taken from the input so far
  std::array<StampMark, kStampMarks> marks_{};
  std::size_t mark_count_ = 0;
  Telegram telegram_;
  ScanInfo scan_info_;
  msg::LaserScan scan_;
  DropCounters<DropReason> drops_;
  MonotonicCounter dropped_bytes_;
  MonotonicCounter telegrams_;
  MonotonicCounter scans_;
};

// A decoder with its telegram buffer inside (N bytes), for tests, tools and static objects.
template <std::size_t N = kDefaultTelegramCapacityBytes>
class StaticDecoder : private blockmap::detail::InlineStorage<std::uint8_t, N>, public Decoder {
  static_assert(N >= kMinTelegramCapacityBytes, "a CoLa telegram buffer needs at least 64 bytes");

 public:
  explicit StaticDecoder(const Config& config = {})
      : blockmap::detail::InlineStorage<std::uint8_t, N>(),
        Decoder(std::span<std::uint8_t>(this->slots), config) {}
};

// --- encoding (every function writes one whole frame into `out` and returns its length, or 0
// when `out` is too small or the input cannot be encoded; nothing allocates)

// CoLa B checksum: XOR of the body (docs/protocols.md 3.2 [solid]).
[[nodiscard]] std::uint8_t checksum(std::span<const std::uint8_t> body) noexcept;

// Frames a body ("sMN Run", or "sEN LMDscandata " + binary 01) as it goes on the wire.
[[nodiscard]] std::size_t frame_cola_b(std::span<const std::uint8_t> body,
                                       std::span<std::uint8_t> out) noexcept;
[[nodiscard]] std::size_t frame_cola_a(std::string_view body, std::span<std::uint8_t> out) noexcept;

// Builds one telegram field by field in either dialect: CoLa B writes "type command", one space
// before the first argument, then big-endian binary; CoLa A writes a space and upper-case hex
// (no leading zeros; floats as their 8 IEEE-754 hex digits; negative s32 as two's complement).
class TelegramWriter {
 public:
  TelegramWriter(Dialect dialect, std::span<std::uint8_t> out, std::string_view type,
                 std::string_view command) noexcept;

  TelegramWriter& u8(std::uint8_t value) noexcept;
  TelegramWriter& u16(std::uint16_t value) noexcept;
  TelegramWriter& u32(std::uint32_t value) noexcept;
  TelegramWriter& i32(std::int32_t value) noexcept;
  TelegramWriter& f32(float value) noexcept;
  // A u16 that CoLa A writes as signed decimal ("+1"), as some configuration fields are.
  TelegramWriter& u16_decimal(std::uint16_t value) noexcept;
  // Fixed-width text without a length (channel names such as "DIST1").
  TelegramWriter& name(std::string_view text) noexcept;
  // A string: u16 length then the characters (CoLa A: hex length, a space, the characters).
  TelegramWriter& string(std::string_view text) noexcept;

  // Closes the frame (CoLa B: length and checksum; CoLa A: ETX); its length, or 0 on overflow.
  [[nodiscard]] std::size_t finish() noexcept;

 private:
  void separator() noexcept;
  void put(std::uint8_t byte) noexcept;
  void put_text(std::string_view text) noexcept;
  void put_hex(std::uint32_t value, int min_digits) noexcept;
  void put_be(std::uint32_t value, int bytes) noexcept;

  Dialect dialect_;
  std::span<std::uint8_t> out_;
  std::size_t length_ = 0;
  bool has_argument_ = false;
  bool overflow_ = false;
};

// SetAccessMode levels and password hashes used by the public drivers (docs/protocols.md 3.3:
// `sMN SetAccessMode 03 F4724744` [S11][S14][S15]).
inline constexpr std::uint8_t kAccessLevelAuthorizedClient = 3;
inline constexpr std::uint32_t kAuthorizedClientPasswordHash = 0xF4724744;

// sWN LMDscandatacfg: what each scan telegram carries. The field layout is read from one real
// CoLa B frame (S14 TiM5xx start-up log) and one CoLa A driver (S15 LMS1xx.cpp);
// docs/protocols.md 3.3 lists the fields without widths, so treat the layout as [single].
struct ScanDataConfig {
  std::uint8_t output_channel = 1;  // bit mask of echoes: 1 = first echo only
  bool rssi = true;                 // "remission"
  bool rssi_16bit = false;          // "resolution": RSSI as a 16-bit channel, else 8-bit
  std::uint8_t unit = 0;            // 0 = mm
  std::uint8_t encoder = 0;         // encoder setting (0 = none)
  bool position = false;
  bool device_name = false;
  bool comment = false;
  bool time = true;
  std::uint16_t output_interval = 1;  // every n-th scan
};

// A command without arguments: "sRN FirmwareVersion", "sRN SCdevicestate", ...
[[nodiscard]] std::size_t encode_command(Dialect dialect, std::string_view type,
                                         std::string_view command,
                                         std::span<std::uint8_t> out) noexcept;
// sMN SetAccessMode <level u8> <password hash u32>.
[[nodiscard]] std::size_t encode_set_access_mode(Dialect dialect, std::uint8_t level,
                                                 std::uint32_t password_hash,
                                                 std::span<std::uint8_t> out) noexcept;
// sWN LMDscandatacfg ... (optional: the device keeps its stored configuration otherwise).
[[nodiscard]] std::size_t encode_scan_data_config(Dialect dialect, const ScanDataConfig& config,
                                                  std::span<std::uint8_t> out) noexcept;
// sMN LMCstartmeas: laser and motor on (LMS1xx/5xx; harmless on a TiM).
[[nodiscard]] std::size_t encode_start_measurement(Dialect dialect,
                                                   std::span<std::uint8_t> out) noexcept;
// sMN Run: leave configuration mode and apply the settings.
[[nodiscard]] std::size_t encode_run(Dialect dialect, std::span<std::uint8_t> out) noexcept;
// sEN LMDscandata 1 / 0: start / stop streaming scans.
[[nodiscard]] std::size_t encode_scan_events(Dialect dialect, bool enable,
                                             std::span<std::uint8_t> out) noexcept;
// sRN LMDscandata: poll one scan.
[[nodiscard]] std::size_t encode_scan_poll(Dialect dialect, std::span<std::uint8_t> out) noexcept;

// What a simulated scanner puts in a scan telegram besides the LaserScan.
struct ScanTelegramFields {
  std::string_view type = "sSN";  // "sSN" when streaming, "sRA" when polled
  std::uint16_t version = 1;
  std::uint16_t device_number = 1;
  std::uint32_t serial_number = 0;
  std::uint16_t telegram_counter = 0;
  std::uint32_t time_since_startup_us = 0;
  std::uint32_t time_of_transmission_us = 0;
  bool rssi_16bit = true;  // when the scan has intensities: RSSI1 16-bit (TiM) or 8-bit (LMS5xx)
  bool has_device_time = false;
  DeviceTime device_time;
};

// An LMDscandata telegram of `scan`: ranges in mm (scale 1, offset 0; non-valid beams as 0),
// angles back in SICK's convention, frequencies from scan_period_s and time_increment_s, the
// scan counter from scan.scan_counter (low 16 bits). Decoder reads it back.
[[nodiscard]] std::size_t encode_scan(Dialect dialect, const msg::LaserScan& scan,
                                      const ScanTelegramFields& fields,
                                      std::span<std::uint8_t> out) noexcept;

}  // namespace blockmap::hal::protocol::sick_cola
