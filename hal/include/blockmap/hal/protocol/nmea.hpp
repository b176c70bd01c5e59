// NMEA 0183 codec: GNSS receiver bytes in, decoded sentences out (docs/protocols.md section 5).
//
// Pure: no file descriptors, no clock, no heap. Bytes may arrive in any chunking; the result
// is the same. A sentence is stamped with the receive time of the chunk that held its '$'.
// Accepted: GGA, RMC, GLL, GNS, GSA, GSV, VTG and ZDA from any talker (GP, GN, GL, GA, GB,
// BD, ...), with empty fields read as absent and extra trailing fields (NMEA 4.1) tolerated.
// Proprietary ($P...) and other valid sentences are skipped and counted, never parsed.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>

#include "blockmap/core/time.hpp"
#include "blockmap/hal/protocol/drop_counters.hpp"
#include "blockmap/msg/gps_fix.hpp"

namespace blockmap::hal::protocol::nmea {

enum class SentenceType : std::uint8_t { kGga, kRmc, kGll, kGns, kGsa, kGsv, kVtg, kZda };
[[nodiscard]] const char* to_string(SentenceType type) noexcept;  // "GGA", ...

// Why bytes or sentences were not turned into a Sentence. kProprietary and kUnsupported are
// well-formed sentences this codec does not interpret; the others are faults.
enum class DropReason : std::uint8_t {
  kGarbage,          // bytes outside any sentence (line noise, a partial sentence at start)
  kTooLong,          // no line end within Config::max_sentence_bytes
  kBadCharacter,     // a byte outside printable ASCII inside a sentence
  kTruncated,        // a new '$' arrived before the line end
  kMissingChecksum,  // no "*hh" (rejected unless Config::accept_missing_checksum)
  kBadChecksum,      // "*hh" present but wrong or malformed
  kMalformed,        // a field that cannot be what the sentence type says
  kUnsupported,      // a valid standard sentence of a type not decoded here (GST, TXT, ...)
  kProprietary,      // a valid $P... vendor sentence, ignored
  kCount
};
[[nodiscard]] const char* to_string(DropReason reason) noexcept;  // "bad_checksum", ...

struct Config {
  // Longest accepted sentence, '$' to line end inclusive. The standard says 82; real receivers
  // send up to 91 (a Furuno GSV in the test logs), so the default leaves room, as gpsd does.
  std::size_t max_sentence_bytes = 128;
  // Accept sentences without "*hh" (some old receivers); counted as kMissingChecksum when not.
  bool accept_missing_checksum = false;
  msg::SourceId source_id = 0;
};

inline constexpr std::size_t kMaxSentenceBytes = 256;  // capacity of the line buffer
inline constexpr std::size_t kMaxGsaSatellites = 24;   // one receiver sends 24

struct GsaData {
  bool automatic = false;     // A: automatic 2D/3D, M: manual
  std::uint8_t fix_type = 0;  // 1 none, 2 2D, 3 3D; 0 when absent
  std::uint8_t satellite_count = 0;
  std::array<std::uint16_t, kMaxGsaSatellites> satellite_ids{};
  bool has_pdop = false, has_hdop = false, has_vdop = false;
  double pdop = 0.0, hdop = 0.0, vdop = 0.0;
  bool has_system_id = false;  // NMEA 4.10: 1 GPS, 2 GLONASS, 3 Galileo, 4 BeiDou, ...
  std::uint8_t system_id = 0;
};

struct SatelliteInView {
  std::uint16_t id = 0;
  bool has_elevation = false, has_azimuth = false, has_snr = false;
  std::int16_t elevation_deg = 0;
  std::uint16_t azimuth_deg = 0;
  float snr_db = 0.0F;
};

struct GsvData {
  std::uint8_t sentence_count = 0;
  std::uint8_t sentence_number = 0;
  std::uint16_t satellites_in_view = 0;
  std::uint8_t block_count = 0;
  std::array<SatelliteInView, 4> satellites{};
  bool has_signal_id = false;  // NMEA 4.10
  std::uint8_t signal_id = 0;
};

struct VtgExtra {
  bool has_course_magnetic = false;
  double course_magnetic_deg = 0.0;
};

struct ZdaExtra {
  bool has_zone = false;
  std::int8_t zone_hours = 0;
  std::int8_t zone_minutes = 0;
};

struct Sentence {
  SentenceType type = SentenceType::kGga;
  std::array<char, 3> talker{};    // "GP", "GN", ... NUL-terminated
  std::uint64_t start_offset = 0;  // stream offset of its '$', counted from the first byte fed
  // GGA, RMC, GLL, GNS: position and time; RMC, ZDA: date; VTG, RMC: speed and course;
  // ZDA: time and date. header.stamp_ns is the receive time.
  msg::GpsFix fix;
  GsaData gsa;   // GSA only
  GsvData gsv;   // GSV only
  VtgExtra vtg;  // VTG only
  ZdaExtra zda;  // ZDA only
};

class Decoder {
 public:
  explicit Decoder(const Config& config = {});

  // What one push() did: `consumed` bytes were used (always > 0 for non-empty input); at most
  // one of `sentence` (valid until the next push) or `rejected` is set.
  struct Step {
    std::size_t consumed = 0;
    const Sentence* sentence = nullptr;
    bool rejected = false;
    DropReason reason = DropReason::kGarbage;  // when rejected
    std::uint64_t start_offset = 0;            // when rejected: where the sentence began
  };

  // Consumes bytes up to and including the end of the next sentence, or all of them. Call it
  // again with the rest until the input is used up. O(bytes). Never allocates.
  Step push(std::span<const std::uint8_t> bytes, TimestampNs rx_stamp_ns);

  [[nodiscard]] const DropCounters<DropReason>& drops() const noexcept { return drops_; }
  [[nodiscard]] std::uint64_t sentences_decoded() const noexcept { return decoded_.value(); }
  // Accepted sentences longer than the standard's 82 bytes (a sign of a chatty receiver).
  [[nodiscard]] std::uint64_t over_standard_length() const noexcept { return long_.value(); }

 private:
  enum class State : std::uint8_t { kHunting, kInSentence };

  Step finish_sentence(std::size_t consumed);
  Step reject(std::size_t consumed, DropReason reason);
  // Fills sentence_ from a checksummed body; the reason when it cannot.
  [[nodiscard]] std::optional<DropReason> parse(std::span<const char> body);

  Config config_;
  State state_ = State::kHunting;
  std::array<char, kMaxSentenceBytes> line_{};
  std::size_t line_length_ = 0;
  std::uint64_t stream_offset_ = 0;
  std::uint64_t sentence_offset_ = 0;
  TimestampNs sentence_stamp_ns_ = 0;
  std::uint8_t last_gsa_fix_type_ = 0;  // fills GpsFix::mode of later position sentences
  Sentence sentence_;
  DropCounters<DropReason> drops_;
  MonotonicCounter decoded_;
  MonotonicCounter long_;
};

// The "*hh" value of a sentence body (the characters between '$' and '*').
[[nodiscard]] std::uint8_t checksum(std::span<const char> body) noexcept;

// --- encoders, for a simulated receiver. Each writes one sentence "$<talker>XXX,...*hh\r\n"
// to the front of `out` and returns its length, or 0 when `out` is too small
// (kMaxSentenceBytes always suffices) or `talker` is not two characters. Fields the fix does
// not have are left empty, as receivers leave them. Latitude and longitude carry five decimals
// of minutes (1.9 cm) and the altitude one of a metre, time two decimals of seconds, as common
// receivers send them; a carrier-phase fix (RTK fixed or float) carries seven decimals of
// minutes (0.2 mm) and a millimetre of altitude, as RTK receivers send theirs.

// GGA: time, position, quality, satellites, HDOP, altitude and geoid separation.
[[nodiscard]] std::size_t encode_gga(const msg::GpsFix& fix, std::string_view talker,
                                     std::span<char> out) noexcept;
// RMC (NMEA 2.3, with the mode indicator): time, status, position, speed, course, date.
[[nodiscard]] std::size_t encode_rmc(const msg::GpsFix& fix, std::string_view talker,
                                     std::span<char> out) noexcept;
// GSA: mode, fix type, up to 12 satellite ids and the dilutions of precision.
[[nodiscard]] std::size_t encode_gsa(const GsaData& gsa, std::string_view talker,
                                     std::span<char> out) noexcept;

}  // namespace blockmap::hal::protocol::nmea
