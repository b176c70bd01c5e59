// Point cloud files: PLY (ascii, binary little and big endian), PCD (ascii, binary,
// binary_compressed), XYZ text, KITTI Velodyne .bin and 3DTK .3d scans.
//
// Debian has no small library for these (PCL's io pulls in VTK and Boost), so they are read
// here: each reader checks its header, reads the vertices' x, y and z in whatever numeric type
// the file declares, and refuses a malformed file with one line that says where and why.
// Points with a NaN or infinite coordinate are skipped and counted, never passed on.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

namespace blockmap::hal::cloud {

enum class CloudFormat : std::uint8_t { kPly, kPcd, kXyz, kKittiBin, kUos3d };

class CloudFileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct PointCloud {
  // Points are stored relative to origin_m in float; origin_m is 0 unless the coordinates are
  // large (georeferenced), where float would lose millimetres.
  Eigen::Vector3d origin_m = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3f> points_m;
  std::uint64_t skipped_nonfinite = 0;
  std::uint64_t skipped_no_return = 0;  // 3DTK max-range readings
  std::string format;                   // "ply binary_little_endian", "pcd ascii", ...
};

// The format a file name implies: .ply, .pcd, .xyz/.txt/.asc, .bin, .3d. Throws
// CloudFileError for any other extension.
[[nodiscard]] CloudFormat format_from_path(const std::filesystem::path& path);

// Parses a whole file's bytes. Throws CloudFileError.
[[nodiscard]] PointCloud parse_point_cloud(std::span<const std::uint8_t> bytes, CloudFormat format);

// Reads and parses a file. Throws CloudFileError (including for I/O errors), whose message
// starts with the file name.
// Files bigger than `max_bytes` are refused, before their bytes are parsed.
inline constexpr std::size_t kMaxCloudFileBytes = std::size_t{1} << 30;
[[nodiscard]] PointCloud read_point_cloud(const std::filesystem::path& path,
                                          std::size_t max_bytes = kMaxCloudFileBytes);

// Writes points (relative to origin_m) as a binary little-endian PLY of x, y, z: floats, or
// doubles with the origin added back when it is not zero. Throws CloudFileError.
void write_ply(const std::filesystem::path& path, std::span<const Eigen::Vector3f> points_m,
               const Eigen::Vector3d& origin_m = Eigen::Vector3d::Zero());

// 3DTK .3d ("uos") scans give centimetres in a left-handed frame with y up; a range of this
// much or more is the scanner's no-return reading.
inline constexpr double kUosNoReturnRangeM = 32.76;

}  // namespace blockmap::hal::cloud
