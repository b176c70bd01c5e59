// Snapshots of the map (no map is lost): every plane the registry holds, with the moments
// of its points, the next plane id, and the local frame's place on Earth, written so that a
// crash or a power cut at any instant leaves a whole snapshot on disk: into a temporary file,
// fsync'd, renamed over the last one (the one before kept as .prev until then), and the folder
// fsync'd. `blockmap run` resumes from it. The format (docs/log-formats.md, "Map snapshot") is
// little-endian binary ending in a CRC-32, so that a torn or damaged file is refused, never
// half-read. The buildings are not stored: they follow from the planes and are fitted again.
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "blockmap/core/time.hpp"
#include "blockmap/hal/geodesy.hpp"
#include "blockmap/map/plane_registry.hpp"

namespace blockmap::cli::daemon {

inline constexpr const char* kSnapshotFile = "snapshot.bin";

struct SnapshotHeader {
  TimestampNs stamp_ns = 0;                  // the data time it was taken at
  std::uint32_t next_id = 1;                 // the registry's next plane id
  std::optional<hal::GeodeticPoint> origin;  // the local frame's origin, once known
};

// Writes snapshots of up to `max_planes` planes without allocating after construction.
class SnapshotWriter {
 public:
  SnapshotWriter(std::filesystem::path dir, std::size_t max_planes);

  // Room for the planes to save (fill it, then write() the first `count`).
  [[nodiscard]] std::span<map::SavedPlane> planes() noexcept { return planes_; }
  // Empty when the snapshot is on disk, else one line why not (the last one stays).
  [[nodiscard]] std::string write(const SnapshotHeader& header, std::size_t count);
  // write() in two steps, for two threads: the planes encoded into the writer's bytes (quick,
  // the pipeline thread), then the bytes put on disk (write, fsync, rename: the output
  // thread). Returns the bytes encoded.
  [[nodiscard]] std::size_t encode(const SnapshotHeader& header, std::size_t count) noexcept;
  [[nodiscard]] std::string write_encoded(std::size_t bytes);
  [[nodiscard]] std::size_t buffer_bytes() const noexcept {
    return bytes_.capacity() + planes_.capacity() * sizeof(map::SavedPlane);
  }
  [[nodiscard]] std::uint64_t written() const noexcept {
    return written_.load(std::memory_order_relaxed);
  }

 private:
  std::filesystem::path dir_;
  std::string path_;       // dir/snapshot.bin
  std::string previous_;   // dir/snapshot.bin.prev
  std::string temporary_;  // dir/snapshot.bin.tmp
  std::vector<map::SavedPlane> planes_;
  std::vector<std::uint8_t> bytes_;
  std::atomic<std::uint64_t> written_{0};
};

struct Snapshot {
  SnapshotHeader header;
  std::vector<map::SavedPlane> planes;
};

// The snapshot in `dir` (or, when it is missing after a crash between the two renames, the one
// before it); none when there is neither. A damaged file is an error naming it and why.
[[nodiscard]] std::optional<Snapshot> read_snapshot(const std::filesystem::path& dir,
                                                    std::string& error);

// The bytes of a snapshot (for tests of damaged files): encoded into `out`, its size returned.
[[nodiscard]] std::size_t encode_snapshot(const SnapshotHeader& header,
                                          std::span<const map::SavedPlane> planes,
                                          std::span<std::uint8_t> out) noexcept;
[[nodiscard]] std::size_t snapshot_bytes(std::size_t planes) noexcept;
// Decodes `bytes`; empty when it worked, else what is wrong.
[[nodiscard]] std::string decode_snapshot(std::span<const std::uint8_t> bytes, Snapshot& out);

}  // namespace blockmap::cli::daemon
