#include "blockmap/hal/protocol/plane_stream.hpp"

#include <bit>
#include <cmath>
#include <limits>

#include "blockmap/hal/protocol/little_endian.hpp"

namespace blockmap::hal::protocol::plane_stream {
namespace {

// Appends to out at offset (the caller sized out by record_size).
class Writer {
 public:
  explicit Writer(std::span<std::uint8_t> out) noexcept : out_(out) {}
  void u8(std::uint8_t value) noexcept { out_[offset_++] = value; }
  void u16(std::uint16_t value) noexcept { put(value, 2); }
  void u32(std::uint32_t value) noexcept { put(value, 4); }
  void i64(std::int64_t value) noexcept { put(static_cast<std::uint64_t>(value), 8); }
  void f32(double value) noexcept { u32(std::bit_cast<std::uint32_t>(static_cast<float>(value))); }
  void vec3(const Eigen::Vector3d& v) noexcept {
    f32(v.x());
    f32(v.y());
    f32(v.z());
  }
  [[nodiscard]] std::size_t offset() const noexcept { return offset_; }

 private:
  void put(std::uint64_t value, std::size_t bytes) noexcept {
    write_le(value, out_.subspan(offset_, bytes));
    offset_ += bytes;
  }
  std::span<std::uint8_t> out_;
  std::size_t offset_ = 0;
};

std::size_t entry_size(const msg::PlanePatch& plane) noexcept {
  return kEntryFixedBytes + std::size_t{plane.polygon_size} * kVertexBytes;
}

// The float32 at offset, widened to double (the message's type).
double f32_at(std::span<const std::uint8_t> bytes, std::size_t offset) noexcept {
  return static_cast<double>(
      std::bit_cast<float>(static_cast<std::uint32_t>(read_le(bytes.subspan(offset, 4)))));
}

// Three floats at offset as a vector; false when one is not finite.
bool vec3_at(std::span<const std::uint8_t> bytes, std::size_t offset, Eigen::Vector3d& out) {
  out =
      Eigen::Vector3d(f32_at(bytes, offset), f32_at(bytes, offset + 4), f32_at(bytes, offset + 8));
  return out.allFinite();
}

}  // namespace

const char* to_string(ParseError error) noexcept {
  switch (error) {
    case ParseError::kNone:
      return "none";
    case ParseError::kTruncated:
      return "truncated record";
    case ParseError::kBadLength:
      return "record length disagrees with its entries";
    case ParseError::kBadChange:
      return "unknown change code";
    case ParseError::kBadKind:
      return "unknown plane kind";
    case ParseError::kBadPolygon:
      return "polygon of more than 32 vertices";
    case ParseError::kNotFinite:
      return "non-finite number";
  }
  return "unknown";
}

std::size_t record_size(std::span<const PlaneChange> changes) noexcept {
  std::size_t bytes = kRecordHeaderBytes;
  for (const PlaneChange& change : changes) {
    bytes += entry_size(change.plane);
  }
  return bytes;
}

std::size_t encode_update(TimestampNs stamp_ns, std::span<const PlaneChange> changes,
                          std::span<std::uint8_t> out) noexcept {
  const std::size_t length = record_size(changes);
  if (length > out.size() || changes.size() > std::numeric_limits<std::uint16_t>::max() ||
      length > std::numeric_limits<std::uint32_t>::max()) {
    return 0;
  }
  Writer writer(out);
  writer.u32(static_cast<std::uint32_t>(length));
  writer.i64(stamp_ns);
  writer.u16(static_cast<std::uint16_t>(changes.size()));
  for (const PlaneChange& change : changes) {
    const msg::PlanePatch& plane = change.plane;
    writer.u8(static_cast<std::uint8_t>(change.change));
    writer.u8(static_cast<std::uint8_t>(plane.kind));
    writer.u32(plane.id);
    writer.vec3(plane.normal);
    writer.f32(plane.d_m);
    writer.f32(plane.support);
    writer.f32(plane.rmse_m);
    writer.vec3(plane.centroid_m);
    writer.u8(plane.polygon_size);
    for (std::size_t i = 0; i < plane.polygon_size; ++i) {
      writer.vec3(plane.polygon_m[i]);
    }
  }
  return writer.offset();
}

ParseError read_update_header(std::span<const std::uint8_t> bytes, UpdateHeader& header) noexcept {
  if (bytes.size() < kRecordHeaderBytes) {
    return ParseError::kTruncated;
  }
  header.length = static_cast<std::uint32_t>(read_le(bytes.subspan(0, 4)));
  header.stamp_ns = static_cast<TimestampNs>(read_le(bytes.subspan(4, 8)));
  header.count = static_cast<std::uint16_t>(read_le(bytes.subspan(12, 2)));
  if (header.length < kRecordHeaderBytes) {
    return ParseError::kBadLength;
  }
  if (header.length > bytes.size()) {
    return ParseError::kTruncated;
  }
  return ParseError::kNone;
}

ParseError read_entry(std::span<const std::uint8_t> bytes, std::size_t& offset,
                      PlaneChange& out) noexcept {
  if (bytes.size() < offset + kEntryFixedBytes) {
    return ParseError::kBadLength;
  }
  const std::uint8_t change = bytes[offset];
  const std::uint8_t kind = bytes[offset + 1];
  if (change < 1 || change > 4) {
    return ParseError::kBadChange;
  }
  if (kind > 3) {
    return ParseError::kBadKind;
  }
  msg::PlanePatch& plane = out.plane;
  out.change = static_cast<Change>(change);
  plane.kind = static_cast<msg::PlaneKind>(kind);
  plane.id = static_cast<std::uint32_t>(read_le(bytes.subspan(offset + 2, 4)));
  const std::size_t numbers = offset + 6;
  plane.d_m = f32_at(bytes, numbers + 12);
  plane.support = f32_at(bytes, numbers + 16);
  plane.rmse_m = f32_at(bytes, numbers + 20);
  if (!vec3_at(bytes, numbers, plane.normal) || !vec3_at(bytes, numbers + 24, plane.centroid_m) ||
      !std::isfinite(plane.d_m) || !std::isfinite(plane.support) || !std::isfinite(plane.rmse_m)) {
    return ParseError::kNotFinite;
  }
  const std::uint8_t vertices = bytes[numbers + 36];
  if (vertices > msg::kMaxPolygonVertices) {
    return ParseError::kBadPolygon;
  }
  const std::size_t polygon = numbers + 37;
  if (bytes.size() < polygon + std::size_t{vertices} * kVertexBytes) {
    return ParseError::kBadLength;
  }
  plane.polygon_size = vertices;
  for (std::size_t i = 0; i < vertices; ++i) {
    if (!vec3_at(bytes, polygon + i * kVertexBytes, plane.polygon_m[i])) {
      return ParseError::kNotFinite;
    }
  }
  offset = polygon + std::size_t{vertices} * kVertexBytes;
  return ParseError::kNone;
}

}  // namespace blockmap::hal::protocol::plane_stream
