#include <cstdio>
#include <fstream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>

#include "blockmap/hal/cloud/point_cloud_file.hpp"
#include "peers.hpp"

namespace blockmap::bench {

PeerRun run_open3d_segment_plane(std::span<const Eigen::Vector3f> points,
                                 const PeerParameters& parameters,
                                 const std::filesystem::path& scratch,
                                 const std::filesystem::path& script) {
  PeerRun run{"Open3D segment_plane, iterative", 0.0, {}, ""};
  std::filesystem::create_directories(scratch);
  const std::filesystem::path cloud = scratch / "cloud.ply";
  const std::filesystem::path labels_path = scratch / "labels.i32";
  hal::cloud::write_ply(cloud, points);
  std::ostringstream command;
  command << "OMP_NUM_THREADS=1 /usr/bin/python3 '" << script.string() << "' '" << cloud.string()
          << "' '" << labels_path.string() << "' " << parameters.distance_m << ' '
          << parameters.min_plane_points << ' ' << parameters.max_planes << ' '
          << parameters.time_limit_s;
  const std::unique_ptr<FILE, int (*)(FILE*)> pipe(popen(command.str().c_str(), "r"), pclose);
  if (!pipe) {
    throw std::runtime_error("cannot run " + script.string());
  }
  std::string output;
  char buffer[256];
  while (std::fgets(buffer, sizeof(buffer), pipe.get()) != nullptr) {
    output += buffer;
  }
  std::istringstream words(output);
  if (!(words >> run.seconds)) {
    throw std::runtime_error("open3d_planes.py printed no time: " + output);
  }
  std::getline(words >> std::ws, run.note);
  std::vector<std::int32_t> labels(points.size());
  std::ifstream file(labels_path, std::ios::binary);
  file.read(reinterpret_cast<char*>(labels.data()),
            static_cast<std::streamsize>(labels.size() * sizeof(std::int32_t)));
  if (!file) {
    throw std::runtime_error("open3d_planes.py wrote no labels");
  }
  run.planes = planes_from_labels(points, labels, parameters);
  run.note += "; 1000 iterations, distance 0.10 m";
  return run;
}

}  // namespace blockmap::bench
