#include <chrono>
#include <cstdio>

#include "blockmap/hal/sim/robot.hpp"
#include "blockmap/hal/sim/truth_cloud.hpp"
#include "blockmap/hal/sim/world.hpp"
#include "blockmap/planes/plane_detector.hpp"
#include "plane_truth.hpp"

using namespace blockmap;

int main(int argc, char** argv) {
  const char* world_name = argc > 1 ? argv[1] : "usc_block";
  hal::sim::SimOptions options;
  options.seed = 3;
  options.max_duration_s = argc > 2 ? std::atof(argv[2]) : 0.0;
  auto t0 = std::chrono::steady_clock::now();
  const auto cloud = hal::sim::simulate_truth_cloud(hal::sim::load_world(world_name),
                                                    hal::sim::load_robot("paper_rmp"), options);
  auto t1 = std::chrono::steady_clock::now();
  std::printf("points %zu sim %.2f s\n", cloud.points_m.size(), std::chrono::duration<double>(t1 - t0).count());
  Arena arena(std::size_t{600} << 20);
  planes::PlanesConfig config;
  planes::PlaneDetector detector;
  detector.init(arena, config);
  std::printf("memory %zu MB\n", detector.memory_bytes() >> 20);
  arena.seal();
  for (int rep = 0; rep < 2; ++rep) {
    auto a = std::chrono::steady_clock::now();
    detector.clear();
    detector.add_points(cloud.points_m);
    auto b = std::chrono::steady_clock::now();
    const auto planes = detector.detect();
    auto c = std::chrono::steady_clock::now();
    const auto& s = detector.stats();
    std::printf("add %.1f ms detect %.1f ms; samples %llu planar %llu linear %llu scattered %llu sections %llu votes %llu peaks %llu section_planes %llu planes %zu\n",
                std::chrono::duration<double, std::milli>(b - a).count(),
                std::chrono::duration<double, std::milli>(c - b).count(),
                (unsigned long long)s.samples, (unsigned long long)s.planar_samples, (unsigned long long)s.linear_samples,
                (unsigned long long)s.scattered_samples, (unsigned long long)s.sections, (unsigned long long)s.votes,
                (unsigned long long)s.peaks, (unsigned long long)s.section_planes, planes.size());
    if (rep == 1) {
      const auto score = testing::score_planes(cloud.faces, planes);
      std::printf("faces %zu found %zu recall %.3f; structural %zu real %zu precision %.3f; twice %zu; median angle %.3f deg offset %.3f m\n",
                  score.faces_considered, score.faces_found, score.recall(), score.structural_planes,
                  score.structural_real, score.precision(), score.faces_reported_twice, score.median_angle_deg,
                  score.median_offset_m);
      for (int id : score.missed_faces) {
        const auto& f = cloud.faces[static_cast<std::size_t>(id)];
        std::printf("  missed face %d kind %d returns %llu n %.2f %.2f %.2f d %.2f\n", id, (int)f.kind,
                    (unsigned long long)f.returns, f.normal.x(), f.normal.y(), f.normal.z(), f.d_m);
      }
      for (const auto& p : planes) {
        if (p.id > 40 && !testing::structural(p.kind)) continue;
        bool is_false = std::find(score.false_planes.begin(), score.false_planes.end(), p.id) != score.false_planes.end();
        std::printf("  plane %u %s%s n %.3f %.3f %.3f d %.2f support %.0f rmse %.3f c %.1f %.1f %.1f poly %d\n", p.id,
                    std::string(msg::to_string(p.kind)).c_str(), is_false ? " FALSE" : "", p.normal.x(), p.normal.y(),
                    p.normal.z(), p.d_m, p.support, p.rmse_m, p.centroid_m.x(), p.centroid_m.y(), p.centroid_m.z(),
                    p.polygon_size);
      }
    }
  }
}
