// The peers the benchmark runs, each from points to planes on one core.
#pragma once

#include <filesystem>
#include <span>

#include <Eigen/Core>

#include "peer_planes.hpp"

namespace blockmap::bench {

PeerRun run_pcl_ransac(std::span<const Eigen::Vector3f> points, const PeerParameters& parameters);
PeerRun run_pcl_region_growing(std::span<const Eigen::Vector3f> points,
                               const PeerParameters& parameters);
PeerRun run_cgal_efficient_ransac(std::span<const Eigen::Vector3f> points,
                                  const PeerParameters& parameters);
// Open3D runs in Debian's python3-open3d: the cloud goes through a PLY file in `scratch`
// (loading is not timed), the script times its own segment_plane loop.
PeerRun run_open3d_segment_plane(std::span<const Eigen::Vector3f> points,
                                 const PeerParameters& parameters,
                                 const std::filesystem::path& scratch,
                                 const std::filesystem::path& script);

}  // namespace blockmap::bench
