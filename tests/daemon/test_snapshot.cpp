// Map snapshots (firmware_host/daemon/snapshot.hpp): what is written is read back the same;
// a damaged or torn file is refused with one line naming it, never half-read; a crash between
// the two renames leaves the snapshot before, which is read instead.
#include "daemon/snapshot.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "scratch.hpp"

namespace blockmap::cli::daemon {
namespace {

namespace fs = std::filesystem;

map::SavedPlane plane(std::uint32_t id, double d_m, std::uint8_t vertices) {
  map::SavedPlane saved;
  saved.plane.id = id;
  saved.plane.kind = msg::PlaneKind::kWall;
  saved.plane.normal = Eigen::Vector3d(0.6, 0.8, 0.0);
  saved.plane.d_m = d_m;
  saved.plane.support = 1234.5;
  saved.plane.rmse_m = 0.021;
  saved.plane.centroid_m = Eigen::Vector3d(3.0, 4.0 + d_m, 2.5);
  saved.plane.polygon_size = vertices;
  for (std::uint8_t i = 0; i < vertices; ++i) {
    saved.plane.polygon_m[i] = Eigen::Vector3d(i, -i, 0.5 * i);
  }
  saved.moments.add(Eigen::Vector3d(1.0, 2.0, 3.0), 2.0);
  saved.moments.add(Eigen::Vector3d(-1.0, 0.5, 7.0));
  return saved;
}

// An empty folder of the test's own.
fs::path empty_folder(const std::string& name) {
  fs::path dir = blockmap::testing::scratch("snapshot_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

TEST(Snapshot, WhatIsWrittenIsReadBackTheSame) {
  const fs::path dir = empty_folder("same");
  SnapshotWriter writer(dir, 8);
  writer.planes()[0] = plane(7, 12.5, 4);
  writer.planes()[1] = plane(9, -3.25, 32);
  writer.planes()[2] = plane(11, 0.0, 0);
  SnapshotHeader header;
  header.stamp_ns = 1'147'280'400'250'000'000;
  header.next_id = 12;
  header.origin = hal::GeodeticPoint{34.0205, -118.2856, 61.5};
  ASSERT_EQ(writer.write(header, 3), "");
  EXPECT_FALSE(fs::exists(dir / "snapshot.bin.tmp"));

  std::string error;
  const std::optional<Snapshot> read = read_snapshot(dir, error);
  ASSERT_TRUE(read) << error;
  EXPECT_EQ(read->header.stamp_ns, header.stamp_ns);
  EXPECT_EQ(read->header.next_id, 12u);
  ASSERT_TRUE(read->header.origin);
  EXPECT_EQ(read->header.origin->latitude_deg, 34.0205);
  EXPECT_EQ(read->header.origin->height_m, 61.5);
  ASSERT_EQ(read->planes.size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) {
    const map::SavedPlane& a = writer.planes()[i];
    const map::SavedPlane& b = read->planes[i];
    EXPECT_EQ(b.plane.id, a.plane.id);
    EXPECT_EQ(b.plane.kind, a.plane.kind);
    EXPECT_EQ(b.plane.normal, a.plane.normal);
    EXPECT_EQ(b.plane.d_m, a.plane.d_m);
    EXPECT_EQ(b.plane.support, a.plane.support);
    EXPECT_EQ(b.plane.rmse_m, a.plane.rmse_m);
    EXPECT_EQ(b.plane.centroid_m, a.plane.centroid_m);
    ASSERT_EQ(b.plane.polygon_size, a.plane.polygon_size);
    for (std::size_t v = 0; v < a.plane.polygon_size; ++v) {
      EXPECT_EQ(b.plane.polygon_m[v], a.plane.polygon_m[v]);
    }
    EXPECT_EQ(b.moments.weight, a.moments.weight);
    EXPECT_EQ(b.moments.sum, a.moments.sum);
    EXPECT_EQ(b.moments.sum_outer, a.moments.sum_outer);
  }
  fs::remove_all(dir);
}

TEST(Snapshot, ADamagedOrTornFileIsRefusedNamingIt) {
  const std::vector<map::SavedPlane> planes = {plane(1, 2.0, 5), plane(2, 4.0, 6)};
  std::vector<std::uint8_t> bytes(snapshot_bytes(planes.size()));
  bytes.resize(encode_snapshot(SnapshotHeader{}, planes, bytes));
  Snapshot out;
  ASSERT_EQ(decode_snapshot(bytes, out), "");
  // Every single flipped bit, and every cut, is caught.
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    std::vector<std::uint8_t> flipped = bytes;
    flipped[i] ^= 0x10U;
    EXPECT_NE(decode_snapshot(flipped, out), "") << "byte " << i;
    EXPECT_NE(decode_snapshot(std::span(bytes).first(i), out), "") << "cut at " << i;
  }
  const fs::path dir = empty_folder("damaged");
  bytes[100] ^= 0xFFU;
  std::ofstream(dir / "snapshot.bin", std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()),
             static_cast<std::streamsize>(bytes.size()));
  std::string error;
  EXPECT_FALSE(read_snapshot(dir, error));
  EXPECT_NE(error.find((dir / "snapshot.bin").string() + ": damaged"), std::string::npos) << error;
  EXPECT_EQ(error.find('\n'), std::string::npos);
  fs::remove_all(dir);
}

TEST(Snapshot, ACrashBetweenTheRenamesLeavesTheOneBefore) {
  const fs::path dir = empty_folder("renames");
  SnapshotWriter writer(dir, 2);
  writer.planes()[0] = plane(3, 1.0, 3);
  SnapshotHeader header;
  header.next_id = 4;
  ASSERT_EQ(writer.write(header, 1), "");
  header.next_id = 5;
  ASSERT_EQ(writer.write(header, 1), "");
  EXPECT_EQ(writer.written(), 2u);
  // The newest is missing (the power went after it became .prev, before the new one landed).
  fs::remove(dir / "snapshot.bin");
  std::string error;
  const std::optional<Snapshot> read = read_snapshot(dir, error);
  ASSERT_TRUE(read) << error;
  EXPECT_EQ(read->header.next_id, 4u);
  fs::remove(dir / "snapshot.bin.prev");
  EXPECT_FALSE(read_snapshot(dir, error));
  EXPECT_EQ(error, "") << "no snapshot is not an error: a new map";
  fs::remove_all(dir);
}

}  // namespace
}  // namespace blockmap::cli::daemon
