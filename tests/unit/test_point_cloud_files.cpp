// The point cloud readers: every format and encoding, NaN and inf skipped and counted, and a
// corpus of broken files that each give one clear error, never a crash.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include <unistd.h>

#include "blockmap/hal/cloud/point_cloud_file.hpp"

namespace blockmap::hal::cloud {
namespace {

std::vector<std::uint8_t> bytes_of(const std::string& text) {
  return {text.begin(), text.end()};
}

template <typename T>
void put(std::vector<std::uint8_t>& out, T value, bool big_endian = false) {
  auto raw = std::bit_cast<std::array<std::uint8_t, sizeof(T)>>(value);
  if (big_endian == (std::endian::native == std::endian::little)) {
    std::reverse(raw.begin(), raw.end());
  }
  out.insert(out.end(), raw.begin(), raw.end());
}

void expect_points(const PointCloud& cloud, const std::vector<Eigen::Vector3f>& expected) {
  ASSERT_EQ(cloud.points_m.size(), expected.size()) << cloud.format;
  for (std::size_t i = 0; i < expected.size(); ++i) {
    EXPECT_TRUE(cloud.points_m[i].isApprox(expected[i], 1e-6f)) << cloud.format << " point " << i;
  }
}

const std::vector<Eigen::Vector3f> kThree = {{1, 2, 3}, {-4.5f, 0.25f, 6}, {7, 8, -9}};

TEST(PointCloudFiles, PlyAsciiWithFacesAndExtraProperties) {
  const std::string text =
      "ply\nformat ascii 1.0\ncomment made by hand\nelement vertex 3\nproperty float x\n"
      "property uchar red\nproperty float y\nproperty double z\nelement face 1\n"
      "property list uchar int vertex_indices\nend_header\n"
      "1 255 2 3\n-4.5 0 0.25 6\n7 1 8 -9\n3 0 1 2\n";
  expect_points(parse_point_cloud(bytes_of(text), CloudFormat::kPly), kThree);
}

std::vector<std::uint8_t> binary_ply(bool big_endian) {
  std::string header =
      std::string("ply\nformat ") + (big_endian ? "binary_big_endian" : "binary_little_endian") +
      " 1.0\nelement camera 1\nproperty float f\nelement vertex 3\nproperty double x\n"
      "property float y\nproperty list uchar int idx\nproperty float z\nend_header\n";
  std::vector<std::uint8_t> out = bytes_of(header);
  put(out, 1.0f, big_endian);  // the camera
  for (const Eigen::Vector3f& p : kThree) {
    put(out, static_cast<double>(p.x()), big_endian);
    put(out, p.y(), big_endian);
    out.push_back(2);  // a list of two ints in the middle of the vertex
    put(out, std::int32_t{5}, big_endian);
    put(out, std::int32_t{6}, big_endian);
    put(out, p.z(), big_endian);
  }
  return out;
}

TEST(PointCloudFiles, PlyBinaryBothEndians) {
  expect_points(parse_point_cloud(binary_ply(false), CloudFormat::kPly), kThree);
  expect_points(parse_point_cloud(binary_ply(true), CloudFormat::kPly), kThree);
}

TEST(PointCloudFiles, PcdAsciiAndBinary) {
  const std::string ascii =
      "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\n"
      "WIDTH 3\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA ascii\n"
      "1 2 3 0\n-4.5 0.25 6 0\n7 8 -9 0\n";
  expect_points(parse_point_cloud(bytes_of(ascii), CloudFormat::kPcd), kThree);
  std::vector<std::uint8_t> binary = bytes_of(
      "VERSION 0.7\nFIELDS intensity x y z\nSIZE 2 4 8 4\nTYPE U F F F\nCOUNT 1 1 1 1\nWIDTH 3\n"
      "HEIGHT 1\nPOINTS 3\nDATA binary\n");
  for (const Eigen::Vector3f& p : kThree) {
    put(binary, std::uint16_t{9});
    put(binary, p.x());
    put(binary, static_cast<double>(p.y()));
    put(binary, p.z());
  }
  expect_points(parse_point_cloud(binary, CloudFormat::kPcd), kThree);
}

TEST(PointCloudFiles, PcdBinaryCompressedIsColumnMajorLzf) {
  std::vector<std::uint8_t> raw;
  for (int axis = 0; axis < 3; ++axis) {
    for (const Eigen::Vector3f& p : kThree) {
      put(raw, p[axis]);
    }
  }
  // LZF: literal runs of at most 32 bytes (control byte = length - 1), and one back reference
  // that repeats the last four bytes.
  std::vector<std::uint8_t> lzf;
  for (std::size_t at = 0; at < raw.size(); at += 32) {
    const std::size_t length = std::min<std::size_t>(32, raw.size() - at);
    lzf.push_back(static_cast<std::uint8_t>(length - 1));
    lzf.insert(lzf.end(), raw.begin() + static_cast<std::ptrdiff_t>(at),
               raw.begin() + static_cast<std::ptrdiff_t>(at + length));
  }
  std::vector<std::uint8_t> file = bytes_of(
      "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 3\nHEIGHT 1\n"
      "POINTS 3\nDATA binary_compressed\n");
  put(file, static_cast<std::uint32_t>(lzf.size()));
  put(file, static_cast<std::uint32_t>(raw.size()));
  file.insert(file.end(), lzf.begin(), lzf.end());
  expect_points(parse_point_cloud(file, CloudFormat::kPcd), kThree);
}

TEST(PointCloudFiles, XyzTextKittiBinAnd3dtk) {
  expect_points(parse_point_cloud(bytes_of("# x y z\n1 2 3\n\n-4.5,0.25,6 extra\n7\t8\t-9\r\n"),
                                  CloudFormat::kXyz),
                kThree);
  std::vector<std::uint8_t> kitti;
  for (const Eigen::Vector3f& p : kThree) {
    put(kitti, p.x());
    put(kitti, p.y());
    put(kitti, p.z());
    put(kitti, 0.5f);
  }
  expect_points(parse_point_cloud(kitti, CloudFormat::kKittiBin), kThree);
  // 3DTK: centimetres, x right, y up, z forward; 3276 cm and beyond is no return.
  const PointCloud uos =
      parse_point_cloud(bytes_of("360 x 225\n-200 300 100\n0 0 3300\n"), CloudFormat::kUos3d);
  expect_points(uos, {{1, 2, 3}});
  EXPECT_EQ(uos.skipped_no_return, 1u);
}

TEST(PointCloudFiles, NanAndInfPointsAreSkippedAndCounted) {
  const PointCloud cloud = parse_point_cloud(
      bytes_of("1 2 3\nnan 0 0\n0 inf 0\n-4.5 0.25 6\n7 8 -9\n"), CloudFormat::kXyz);
  expect_points(cloud, kThree);
  EXPECT_EQ(cloud.skipped_nonfinite, 2u);
}

TEST(PointCloudFiles, LargeCoordinatesAreKeptRelativeToAnOrigin) {
  const PointCloud cloud = parse_point_cloud(
      bytes_of("500123.456 4100234.567 12.5\n500124.457 4100235.568 13.5\n"), CloudFormat::kXyz);
  EXPECT_EQ(cloud.origin_m, Eigen::Vector3d(500000, 4100000, 0));
  EXPECT_NEAR(static_cast<double>(cloud.points_m[1].x()) + cloud.origin_m.x(), 500124.457, 1e-3);
  EXPECT_NEAR(static_cast<double>(cloud.points_m[1].y()) + cloud.origin_m.y(), 4100235.568, 1e-3);
}

struct Broken {
  const char* name;
  CloudFormat format;
  std::vector<std::uint8_t> bytes;
};

std::vector<Broken> broken_corpus() {
  std::vector<Broken> corpus = {
      {"empty ply", CloudFormat::kPly, {}},
      {"not ply", CloudFormat::kPly, bytes_of("plyx\nformat ascii 1.0\nend_header\n")},
      {"ply no end_header", CloudFormat::kPly,
       bytes_of("ply\nformat ascii 1.0\nelement vertex 1\n")},
      {"ply no format", CloudFormat::kPly,
       bytes_of("ply\nelement vertex 1\nproperty float x\nend_header\n")},
      {"ply bad encoding", CloudFormat::kPly,
       bytes_of("ply\nformat binary_middle_endian 1.0\nend_header\n")},
      {"ply no vertex", CloudFormat::kPly,
       bytes_of("ply\nformat ascii 1.0\nelement face 0\nend_header\n")},
      {"ply no z", CloudFormat::kPly,
       bytes_of("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float "
                "y\nend_header\n1 2\n")},
      {"ply bad type", CloudFormat::kPly,
       bytes_of("ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n")},
      {"ply huge count", CloudFormat::kPly,
       bytes_of("ply\nformat ascii 1.0\nelement vertex 99999999999999999999999\nend_header\n")},
      {"ply ascii truncated", CloudFormat::kPly,
       bytes_of("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                "property float z\nend_header\n1 2 3\n")},
      {"ply ascii letters", CloudFormat::kPly,
       bytes_of("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                "property float z\nend_header\n1 two 3\n")},
      {"pcd no data", CloudFormat::kPcd, bytes_of("VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\n")},
      {"pcd no xyz", CloudFormat::kPcd,
       bytes_of(
           "FIELDS a b c\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nPOINTS 1\nDATA ascii\n1 2 3\n")},
      {"pcd size mismatch", CloudFormat::kPcd,
       bytes_of("FIELDS x y z\nSIZE 4 4\nTYPE F F F\nDATA ascii\n")},
      {"pcd bad type", CloudFormat::kPcd,
       bytes_of("FIELDS x y z\nSIZE 3 4 4\nTYPE F F F\nCOUNT 1 1 1\nPOINTS 1\nDATA "
                "binary\n123456789012")},
      {"pcd binary truncated", CloudFormat::kPcd,
       bytes_of("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nPOINTS 2\nDATA "
                "binary\n0123456789ab")},
      {"pcd compressed truncated", CloudFormat::kPcd,
       bytes_of("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nPOINTS 1\nDATA "
                "binary_compressed\n\x05")},
      {"pcd unknown data", CloudFormat::kPcd,
       bytes_of("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nPOINTS 1\nDATA zip\n")},
      {"pcd ascii short line", CloudFormat::kPcd,
       bytes_of("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nPOINTS 1\nDATA ascii\n1 2\n")},
      {"xyz two numbers", CloudFormat::kXyz, bytes_of("1 2 3\n4 5\n")},
      {"xyz words", CloudFormat::kXyz, bytes_of("x y z\n")},
      {"kitti truncated", CloudFormat::kKittiBin, std::vector<std::uint8_t>(17, 0)},
  };
  // A compressed PCD whose LZF back reference points before the start.
  std::vector<std::uint8_t> bad_lzf = bytes_of(
      "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nPOINTS 1\nDATA binary_compressed\n");
  put(bad_lzf, std::uint32_t{2});
  put(bad_lzf, std::uint32_t{12});
  bad_lzf.push_back(0x20);
  bad_lzf.push_back(0x10);
  corpus.push_back({"pcd lzf back reference", CloudFormat::kPcd, bad_lzf});
  return corpus;
}

TEST(PointCloudFiles, EveryBrokenFileGivesOneLineErrorNotACrash) {
  for (const Broken& broken : broken_corpus()) {
    try {
      const PointCloud cloud = parse_point_cloud(broken.bytes, broken.format);
      ADD_FAILURE() << broken.name << ": accepted with " << cloud.points_m.size() << " points";
    } catch (const CloudFileError& error) {
      const std::string message = error.what();
      EXPECT_FALSE(message.empty()) << broken.name;
      EXPECT_EQ(message.find('\n'), std::string::npos) << broken.name << ": " << message;
    }
  }
}

TEST(PointCloudFiles, FileNamesPickTheFormatAndUnknownOnesAreRefused) {
  EXPECT_EQ(format_from_path("a/b.PLY"), CloudFormat::kPly);
  EXPECT_EQ(format_from_path("scan.3d"), CloudFormat::kUos3d);
  EXPECT_EQ(format_from_path("x.bin"), CloudFormat::kKittiBin);
  EXPECT_THROW(static_cast<void>(format_from_path("cloud.las")), CloudFileError);
  EXPECT_THROW(static_cast<void>(read_point_cloud("/nonexistent/cloud.ply")), CloudFileError);
}

TEST(PointCloudFiles, WrittenPlyReadsBackTheSamePoints) {
  const std::filesystem::path folder =
      std::filesystem::temp_directory_path() / ("blockmap_ply_" + std::to_string(::getpid()));
  std::filesystem::create_directories(folder);
  const std::vector<Eigen::Vector3f> points = {{1.5f, -2.25f, 0.125f}, {-1e3f, 3e-3f, 42.0f}};
  write_ply(folder / "plain.ply", points);
  const PointCloud plain = read_point_cloud(folder / "plain.ply");
  EXPECT_EQ(plain.format, "ply binary_little_endian");
  EXPECT_EQ(plain.points_m, points);
  // Georeferenced: doubles keep the millimetres, and the reader takes the origin out again.
  const Eigen::Vector3d origin(500000.0, 4649776.0, 200.0);
  write_ply(folder / "utm.ply", points, origin);
  const PointCloud utm = read_point_cloud(folder / "utm.ply");
  ASSERT_EQ(utm.points_m.size(), points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    EXPECT_LT(
        ((utm.origin_m + utm.points_m[i].cast<double>()) - (origin + points[i].cast<double>()))
            .norm(),
        1e-3);
  }
  EXPECT_THROW(write_ply(folder / "missing" / "x.ply", points), CloudFileError);
  std::filesystem::remove_all(folder);
}

}  // namespace
}  // namespace blockmap::hal::cloud
