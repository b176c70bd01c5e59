#include "daemon/snapshot.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <array>
#include <bit>
#include <cerrno>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <system_error>

#include "blockmap/hal/protocol/little_endian.hpp"

namespace blockmap::cli::daemon {
namespace {

namespace fs = std::filesystem;
using hal::protocol::read_le;
using hal::protocol::write_le;

constexpr std::array<std::uint8_t, 8> kMagic = {'B', 'M', 'S', 'N', 'A', 'P', '\r', '\n'};
constexpr std::uint32_t kVersion = 1;
constexpr std::size_t kHeaderBytes = 56;
// id, kind, polygon size, padding; 9 plane numbers; 10 moments (the second ones symmetric).
constexpr std::size_t kPlaneFixedBytes = 8 + (std::size_t{9} * 8) + (std::size_t{10} * 8);
constexpr std::size_t kVertexBytes = std::size_t{3} * 8;
constexpr std::size_t kCrcBytes = 4;

// CRC-32 (IEEE 802.3, reflected, as zlib and PNG compute it), bit by bit: a snapshot is a few
// hundred kB written every few seconds, so a table buys nothing worth a dependency.
std::uint32_t crc32(std::span<const std::uint8_t> bytes) noexcept {
  std::uint32_t crc = 0xFFFFFFFFU;
  for (const std::uint8_t byte : bytes) {
    crc ^= byte;
    for (int bit = 0; bit < 8; ++bit) {
      crc = (crc >> 1U) ^ (0xEDB88320U & (0U - (crc & 1U)));
    }
  }
  return ~crc;
}

class Writer {
 public:
  explicit Writer(std::span<std::uint8_t> out) : out_(out) {}
  void u(std::uint64_t value, std::size_t width) {
    write_le(value, out_.subspan(at_, width));
    at_ += width;
  }
  void f(double value) { u(std::bit_cast<std::uint64_t>(value), 8); }
  void v(const Eigen::Vector3d& value) {
    f(value.x());
    f(value.y());
    f(value.z());
  }
  void bytes(std::span<const std::uint8_t> data) {
    std::copy(data.begin(), data.end(), out_.begin() + static_cast<std::ptrdiff_t>(at_));
    at_ += data.size();
  }
  [[nodiscard]] std::size_t size() const noexcept { return at_; }

 private:
  std::span<std::uint8_t> out_;
  std::size_t at_ = 0;
};

class Reader {
 public:
  explicit Reader(std::span<const std::uint8_t> in) : in_(in) {}
  [[nodiscard]] bool has(std::size_t bytes) const noexcept { return in_.size() - at_ >= bytes; }
  std::uint64_t u(std::size_t width) {
    const std::uint64_t value = read_le(in_.subspan(at_, width));
    at_ += width;
    return value;
  }
  double f() { return std::bit_cast<double>(u(8)); }
  Eigen::Vector3d v() {
    const double x = f();
    const double y = f();
    return {x, y, f()};
  }
  [[nodiscard]] std::size_t at() const noexcept { return at_; }

 private:
  std::span<const std::uint8_t> in_;
  std::size_t at_ = 0;
};

void write_plane(Writer& w, const map::SavedPlane& saved) {
  const msg::PlanePatch& p = saved.plane;
  w.u(p.id, 4);
  w.u(static_cast<std::uint8_t>(p.kind), 1);
  w.u(p.polygon_size, 1);
  w.u(0, 2);
  w.v(p.normal);
  w.f(p.d_m);
  w.f(p.support);
  w.f(p.rmse_m);
  w.v(p.centroid_m);
  const planes::PointMoments& m = saved.moments;
  w.f(m.weight);
  w.v(m.sum);
  // The second moments are symmetric: the upper triangle.
  for (int row = 0; row < 3; ++row) {
    for (int col = row; col < 3; ++col) {
      w.f(m.sum_outer(row, col));
    }
  }
  for (std::size_t i = 0; i < p.polygon_size; ++i) {
    w.v(p.polygon_m[i]);
  }
}

std::string read_plane(Reader& r, map::SavedPlane& saved) {
  if (!r.has(kPlaneFixedBytes)) {
    return "ends inside a plane";
  }
  msg::PlanePatch& p = saved.plane;
  p.id = static_cast<std::uint32_t>(r.u(4));
  const auto kind = r.u(1);
  p.polygon_size = static_cast<std::uint8_t>(r.u(1));
  static_cast<void>(r.u(2));
  if (kind > static_cast<std::uint8_t>(msg::PlaneKind::kOther) ||
      p.polygon_size > msg::kMaxPolygonVertices || p.id == 0) {
    return "a plane with an impossible kind, polygon or id";
  }
  p.kind = static_cast<msg::PlaneKind>(kind);
  p.normal = r.v();
  p.d_m = r.f();
  p.support = r.f();
  p.rmse_m = r.f();
  p.centroid_m = r.v();
  planes::PointMoments& m = saved.moments;
  m.weight = r.f();
  m.sum = r.v();
  for (int row = 0; row < 3; ++row) {
    for (int col = row; col < 3; ++col) {
      m.sum_outer(row, col) = r.f();
      m.sum_outer(col, row) = m.sum_outer(row, col);
    }
  }
  if (!r.has(p.polygon_size * kVertexBytes)) {
    return "ends inside a plane's polygon";
  }
  for (std::size_t i = 0; i < p.polygon_size; ++i) {
    p.polygon_m[i] = r.v();
  }
  return {};
}

// Writes `bytes` to `path` and waits until they are on the disk.
std::string write_synced(const std::string& path, std::span<const std::uint8_t> bytes) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) {
    return path + ": " + std::generic_category().message(errno);
  }
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t written = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (written < 0 && errno == EINTR) {
      continue;
    }
    if (written <= 0) {
      const int error = errno;
      ::close(fd);
      return path + ": " + std::generic_category().message(error);
    }
    done += static_cast<std::size_t>(written);
  }
  const bool synced = ::fsync(fd) == 0;
  const int error = errno;
  ::close(fd);
  return synced ? std::string() : path + ": fsync: " + std::generic_category().message(error);
}

// The renames are durable only once the folder's entry is on the disk too.
void sync_folder(const fs::path& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
}

std::optional<Snapshot> read_file(const fs::path& path, std::string& error) {
  std::ifstream file(path, std::ios::binary);
  if (!file) {
    return std::nullopt;
  }
  const std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(file)),
                                        std::istreambuf_iterator<char>());
  Snapshot snapshot;
  if (std::string problem = decode_snapshot(bytes, snapshot); !problem.empty()) {
    error = path.string() + ": " + problem + " (move it away to start a new map)";
    return std::nullopt;
  }
  return snapshot;
}

}  // namespace

std::size_t snapshot_bytes(std::size_t planes) noexcept {
  return kHeaderBytes + planes * (kPlaneFixedBytes + msg::kMaxPolygonVertices * kVertexBytes) +
         kCrcBytes;
}

std::size_t encode_snapshot(const SnapshotHeader& header, std::span<const map::SavedPlane> planes,
                            std::span<std::uint8_t> out) noexcept {
  Writer w(out);
  w.bytes(kMagic);
  w.u(kVersion, 4);
  w.u(planes.size(), 4);
  w.u(header.next_id, 4);
  w.u(header.origin ? 1 : 0, 1);
  w.u(0, 3);
  const hal::GeodeticPoint origin = header.origin.value_or(hal::GeodeticPoint{});
  w.f(origin.latitude_deg);
  w.f(origin.longitude_deg);
  w.f(origin.height_m);
  w.u(static_cast<std::uint64_t>(header.stamp_ns), 8);
  for (const map::SavedPlane& plane : planes) {
    write_plane(w, plane);
  }
  const std::uint32_t crc = crc32(out.first(w.size()));
  w.u(crc, 4);
  return w.size();
}

std::string decode_snapshot(std::span<const std::uint8_t> bytes, Snapshot& out) {
  if (bytes.size() < kHeaderBytes + kCrcBytes ||
      !std::equal(kMagic.begin(), kMagic.end(), bytes.begin())) {
    return "not a blockmap map snapshot";
  }
  const std::span<const std::uint8_t> body = bytes.first(bytes.size() - kCrcBytes);
  if (crc32(body) != read_le(bytes.last(kCrcBytes))) {
    return "damaged (its CRC-32 does not match)";
  }
  Reader r(body);
  static_cast<void>(r.u(kMagic.size()));
  if (const auto version = r.u(4); version != kVersion) {
    return "format version " + std::to_string(version) + ", this build reads " +
           std::to_string(kVersion);
  }
  const auto count = static_cast<std::size_t>(r.u(4));
  out.header.next_id = static_cast<std::uint32_t>(r.u(4));
  const bool has_origin = r.u(1) != 0;
  static_cast<void>(r.u(3));
  hal::GeodeticPoint origin;
  origin.latitude_deg = r.f();
  origin.longitude_deg = r.f();
  origin.height_m = r.f();
  out.header.origin = has_origin ? std::optional(origin) : std::nullopt;
  out.header.stamp_ns = static_cast<TimestampNs>(r.u(8));
  if (count > (body.size() - kHeaderBytes) / kPlaneFixedBytes) {
    return "says " + std::to_string(count) + " planes, more than it holds";
  }
  out.planes.resize(count);
  for (map::SavedPlane& plane : out.planes) {
    if (std::string problem = read_plane(r, plane); !problem.empty()) {
      return problem;
    }
  }
  if (r.at() != body.size()) {
    return "has bytes after its last plane";
  }
  return {};
}

SnapshotWriter::SnapshotWriter(fs::path dir, std::size_t max_planes)
    : dir_(std::move(dir)),
      path_((dir_ / kSnapshotFile).string()),
      previous_(path_ + ".prev"),
      temporary_(path_ + ".tmp"),
      planes_(max_planes),
      bytes_(snapshot_bytes(max_planes)) {}

std::size_t SnapshotWriter::encode(const SnapshotHeader& header, std::size_t count) noexcept {
  return encode_snapshot(header, std::span<const map::SavedPlane>(planes_.data(), count), bytes_);
}

std::string SnapshotWriter::write_encoded(std::size_t bytes) {
  if (std::string problem = write_synced(temporary_, std::span(bytes_.data(), bytes));
      !problem.empty()) {
    return problem;
  }
  // The last snapshot becomes the one before; a crash between the renames leaves that one,
  // which read_snapshot() falls back to.
  static_cast<void>(std::rename(path_.c_str(), previous_.c_str()));
  if (std::rename(temporary_.c_str(), path_.c_str()) != 0) {
    return path_ + ": " + std::generic_category().message(errno);
  }
  sync_folder(dir_);
  written_.fetch_add(1, std::memory_order_relaxed);
  return {};
}

std::string SnapshotWriter::write(const SnapshotHeader& header, std::size_t count) {
  return write_encoded(encode(header, count));
}

std::optional<Snapshot> read_snapshot(const fs::path& dir, std::string& error) {
  error.clear();
  if (std::optional<Snapshot> snapshot = read_file(dir / kSnapshotFile, error); snapshot) {
    return snapshot;
  }
  if (!error.empty()) {
    return std::nullopt;
  }
  return read_file(dir / (std::string(kSnapshotFile) + ".prev"), error);
}

}  // namespace blockmap::cli::daemon
