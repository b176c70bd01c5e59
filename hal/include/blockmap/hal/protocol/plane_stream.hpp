// The binary plane stream: the mapper's plane-list updates as compact records, for a file or
// a UDP datagram each (docs/log-formats.md, "Plane stream"). The JSON Lines stream carries the
// same updates as text. A stream starts with the 8-byte magic "BMPLANE1"; then records, one
// per update, all little-endian:
//
//   offset 0   uint32   record length in bytes, this field included
//   offset 4   int64    the update's time, ns (the run's time base)
//   offset 12  uint16   number of entries
//   offset 14  entries, each:
//     uint8   change: 1 added, 2 changed, 3 finalized (its region left the window; again
//             when the robot comes back or the rigid path's solve moves it)
//     uint8   kind: 0 wall, 1 roof, 2 ground, 3 other
//     uint32  plane id (a consumer applies changes by id)
//     float32 x 4   normal (unit), d (m): normal . x = d
//     float32 x 2   support (points), rmse (m)
//     float32 x 3   centroid (m)
//     uint8   polygon vertex count n (at most 32), then float32 x 3n vertices (m)
//
// Floats keep a millimetre within 10 km of the local frame's origin. A reader that meets a
// change or kind it does not know rejects the record (a newer format would change the magic).
// Pure functions, no I/O, no heap.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include "blockmap/core/time.hpp"
#include "blockmap/msg/plane_patch.hpp"

namespace blockmap::hal::protocol::plane_stream {

inline constexpr std::array<std::uint8_t, 8> kMagic = {'B', 'M', 'P', 'L', 'A', 'N', 'E', '1'};
inline constexpr std::size_t kRecordHeaderBytes = 14;
// One entry without its polygon, and each polygon vertex.
inline constexpr std::size_t kEntryFixedBytes = 1 + 1 + 4 + 9 * 4 + 1;
inline constexpr std::size_t kVertexBytes = 12;
inline constexpr std::size_t kMaxEntryBytes =
    kEntryFixedBytes + msg::kMaxPolygonVertices * kVertexBytes;

// The mapper's plane changes (msg/plane_patch.hpp); the byte values are the format's.
using Change = msg::PlaneChangeKind;
using PlaneChange = msg::PlaneChange;

// The bytes one update takes.
[[nodiscard]] std::size_t record_size(std::span<const PlaneChange> changes) noexcept;

// Writes one update; returns the bytes written, or 0 when `out` is too small or there are
// more than 65,535 changes (nothing is written then).
[[nodiscard]] std::size_t encode_update(TimestampNs stamp_ns, std::span<const PlaneChange> changes,
                                        std::span<std::uint8_t> out) noexcept;

enum class ParseError : std::uint8_t {
  kNone = 0,
  kTruncated,   // fewer bytes than the record's header or length says
  kBadLength,   // the length disagrees with the entries it holds
  kBadChange,   // a change code other than 1, 2 or 3
  kBadKind,     // a kind code other than 0 to 3
  kBadPolygon,  // more than 32 vertices
  kNotFinite,   // a NaN or infinite number
};
[[nodiscard]] const char* to_string(ParseError error) noexcept;

struct UpdateHeader {
  TimestampNs stamp_ns = 0;
  std::uint32_t length = 0;  // the whole record
  std::uint16_t count = 0;
};

// Reads the record at the front of `bytes`: its header, and each change through
// `on_change(const PlaneChange&)` once the whole record has been checked (a bad record
// delivers nothing). Returns kNone and the header, or what is wrong.
template <typename OnChange>
ParseError decode_update(std::span<const std::uint8_t> bytes, UpdateHeader& header,
                         OnChange&& on_change) noexcept;

// The checks and the reading, entry by entry (decode_update's parts).
[[nodiscard]] ParseError read_update_header(std::span<const std::uint8_t> bytes,
                                            UpdateHeader& header) noexcept;
[[nodiscard]] ParseError read_entry(std::span<const std::uint8_t> bytes, std::size_t& offset,
                                    PlaneChange& out) noexcept;

template <typename OnChange>
ParseError decode_update(std::span<const std::uint8_t> bytes, UpdateHeader& header,
                         OnChange&& on_change) noexcept {
  if (const ParseError error = read_update_header(bytes, header); error != ParseError::kNone) {
    return error;
  }
  const std::span<const std::uint8_t> record = bytes.first(header.length);
  // First pass checks every entry, the second delivers them: all or nothing.
  for (int pass = 0; pass < 2; ++pass) {
    std::size_t offset = kRecordHeaderBytes;
    PlaneChange change;
    for (std::uint16_t i = 0; i < header.count; ++i) {
      if (const ParseError error = read_entry(record, offset, change); error != ParseError::kNone) {
        return error;
      }
      if (pass == 1) {
        on_change(change);
      }
    }
    if (offset != record.size()) {
      return ParseError::kBadLength;
    }
  }
  return ParseError::kNone;
}

}  // namespace blockmap::hal::protocol::plane_stream
