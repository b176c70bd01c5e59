// The binary plane stream: round trip, the bytes pinned, and every damaged record refused
// whole (no change delivered from a record that fails a check).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "blockmap/hal/protocol/plane_stream.hpp"

namespace blockmap::hal::protocol::plane_stream {
namespace {

msg::PlanePatch wall(std::uint32_t id, std::uint8_t vertices) {
  msg::PlanePatch plane;
  plane.id = id;
  plane.kind = msg::PlaneKind::kWall;
  plane.normal = Eigen::Vector3d(0.0, 1.0, 0.0);
  plane.d_m = 12.5;
  plane.support = 5310.0;
  plane.rmse_m = 0.021;
  plane.centroid_m = Eigen::Vector3d(3.1, 12.5, 4.0);
  plane.polygon_size = vertices;
  for (std::uint8_t i = 0; i < vertices; ++i) {
    plane.polygon_m[i] = Eigen::Vector3d(0.5 * i, 12.5, 0.25 * i);
  }
  return plane;
}

std::vector<std::uint8_t> encode(TimestampNs stamp_ns, const std::vector<PlaneChange>& changes) {
  std::vector<std::uint8_t> bytes(record_size(changes));
  EXPECT_EQ(encode_update(stamp_ns, changes, bytes), bytes.size());
  return bytes;
}

std::vector<PlaneChange> decode(std::span<const std::uint8_t> bytes, ParseError& error,
                                UpdateHeader& header) {
  std::vector<PlaneChange> changes;
  error = decode_update(bytes, header, [&](const PlaneChange& c) { changes.push_back(c); });
  return changes;
}

TEST(PlaneStream, AnUpdateComesBackAsItWasWritten) {
  const std::vector<PlaneChange> changes = {{Change::kAdded, wall(7, 4)},
                                            {Change::kChanged, wall(3, 32)},
                                            {Change::kFinalized, wall(9, 0)}};
  const std::vector<std::uint8_t> bytes = encode(1'234'567'890'123, changes);
  EXPECT_EQ(bytes.size(), kRecordHeaderBytes + 3 * kEntryFixedBytes + 36 * kVertexBytes);
  ParseError error = ParseError::kNone;
  UpdateHeader header;
  const std::vector<PlaneChange> back = decode(bytes, error, header);
  ASSERT_EQ(error, ParseError::kNone) << to_string(error);
  EXPECT_EQ(header.stamp_ns, 1'234'567'890'123);
  EXPECT_EQ(header.length, bytes.size());
  ASSERT_EQ(back.size(), 3u);
  for (std::size_t i = 0; i < back.size(); ++i) {
    const msg::PlanePatch& a = changes[i].plane;
    const msg::PlanePatch& b = back[i].plane;
    EXPECT_EQ(back[i].change, changes[i].change);
    EXPECT_EQ(b.id, a.id);
    EXPECT_EQ(b.kind, a.kind);
    EXPECT_EQ(b.polygon_size, a.polygon_size);
    // float32 on the wire: a millimetre within 10 km.
    EXPECT_LT((b.normal - a.normal).norm(), 1e-7);
    EXPECT_NEAR(b.d_m, a.d_m, 1e-6);
    EXPECT_NEAR(b.support, a.support, 1e-3);
    EXPECT_NEAR(b.rmse_m, a.rmse_m, 1e-8);
    EXPECT_LT((b.centroid_m - a.centroid_m).norm(), 1e-6);
    for (std::size_t v = 0; v < a.polygon_size; ++v) {
      EXPECT_LT((b.polygon_m[v] - a.polygon_m[v]).norm(), 1e-6);
    }
  }
}

TEST(PlaneStream, TheBytesAreTheDocumentedLayout) {
  msg::PlanePatch plane = wall(0x01020304, 1);
  plane.kind = msg::PlaneKind::kGround;
  plane.normal = Eigen::Vector3d(0.0, 0.0, 1.0);
  plane.polygon_m[0] = Eigen::Vector3d(1.0, -2.0, 0.5);
  const std::vector<std::uint8_t> bytes = encode(0x0A0B0C0D0E0F1011, {{Change::kAdded, plane}});
  ASSERT_EQ(bytes.size(), 14u + 43u + 12u);
  const std::vector<std::uint8_t> head = {69,   0,    0,    0,                             // length
                                          0x11, 0x10, 0x0F, 0x0E, 0x0D, 0x0C, 0x0B, 0x0A,  // ns
                                          1,    0,                 // one entry
                                          1,    2,                 // added, ground
                                          0x04, 0x03, 0x02, 0x01,  // id
                                          0,    0,    0,    0,    0,    0,    0,    0,
                                          0,    0,    0x80, 0x3F};  // 0 0 1
  EXPECT_EQ(std::vector<std::uint8_t>(bytes.begin(), bytes.begin() + 32), head);
  EXPECT_EQ(bytes[14 + 42], 1);  // one vertex, then 1.0f = 00 00 80 3F
  EXPECT_EQ(std::vector<std::uint8_t>(bytes.begin() + 57, bytes.begin() + 61),
            (std::vector<std::uint8_t>{0, 0, 0x80, 0x3F}));
  EXPECT_EQ(std::string(kMagic.begin(), kMagic.end()), "BMPLANE1");
}

TEST(PlaneStream, ATooSmallBufferGetsNothingWritten) {
  const std::vector<PlaneChange> changes = {{Change::kAdded, wall(1, 8)}};
  std::vector<std::uint8_t> bytes(record_size(changes) - 1, 0xAA);
  EXPECT_EQ(encode_update(0, changes, bytes), 0u);
  for (const std::uint8_t b : bytes) {
    ASSERT_EQ(b, 0xAA);
  }
}

TEST(PlaneStream, EveryCutRecordIsRefusedAndDeliversNothing) {
  const std::vector<std::uint8_t> bytes =
      encode(5, {{Change::kAdded, wall(1, 8)}, {Change::kChanged, wall(2, 3)}});
  for (std::size_t cut = 0; cut < bytes.size(); ++cut) {
    ParseError error = ParseError::kNone;
    UpdateHeader header;
    const auto changes = decode(std::span(bytes).first(cut), error, header);
    EXPECT_NE(error, ParseError::kNone) << cut;
    EXPECT_TRUE(changes.empty()) << cut;
  }
}

TEST(PlaneStream, DamagedRecordsNameWhatIsWrongAndDeliverNothing) {
  const std::vector<std::uint8_t> good =
      encode(5, {{Change::kAdded, wall(1, 2)}, {Change::kChanged, wall(2, 2)}});
  const std::size_t second = kRecordHeaderBytes + kEntryFixedBytes + 2 * kVertexBytes;
  const auto expect_refused = [](std::vector<std::uint8_t> bytes, ParseError expected) {
    ParseError error = ParseError::kNone;
    UpdateHeader header;
    const auto changes = decode(bytes, error, header);
    EXPECT_EQ(error, expected) << to_string(error);
    EXPECT_TRUE(changes.empty());
  };
  std::vector<std::uint8_t> bytes = good;
  bytes[second] = 5;  // change code
  expect_refused(bytes, ParseError::kBadChange);
  bytes = good;
  bytes[second + 1] = 7;  // kind
  expect_refused(bytes, ParseError::kBadKind);
  bytes = good;
  bytes[second + 42] = 33;  // vertices
  expect_refused(bytes, ParseError::kBadPolygon);
  bytes = good;
  const auto nan = std::bit_cast<std::uint32_t>(std::numeric_limits<float>::quiet_NaN());
  for (std::size_t i = 0; i < 4; ++i) {
    bytes[second + 18 + i] = static_cast<std::uint8_t>(nan >> (8 * i));  // d
  }
  expect_refused(bytes, ParseError::kNotFinite);
  bytes = good;
  bytes[12] = 3;  // three entries promised, two present
  expect_refused(bytes, ParseError::kBadLength);
  bytes = good;
  bytes[12] = 1;  // one entry, but the length covers two
  expect_refused(bytes, ParseError::kBadLength);
  bytes = good;
  bytes[0] = 3;  // a length shorter than the header
  bytes[1] = 0;
  expect_refused(bytes, ParseError::kBadLength);
}

TEST(PlaneStream, RecordsFollowEachOtherInAStream) {
  std::vector<std::uint8_t> stream(kMagic.begin(), kMagic.end());
  for (TimestampNs t = 1; t <= 3; ++t) {
    const auto record = encode(t, {{Change::kAdded, wall(static_cast<std::uint32_t>(t), 4)}});
    stream.insert(stream.end(), record.begin(), record.end());
  }
  std::span<const std::uint8_t> rest = std::span(stream).subspan(kMagic.size());
  std::vector<std::uint32_t> ids;
  while (!rest.empty()) {
    UpdateHeader header;
    ASSERT_EQ(decode_update(rest, header, [&](const PlaneChange& c) { ids.push_back(c.plane.id); }),
              ParseError::kNone);
    rest = rest.subspan(header.length);
  }
  EXPECT_EQ(ids, (std::vector<std::uint32_t>{1, 2, 3}));
}

}  // namespace
}  // namespace blockmap::hal::protocol::plane_stream
