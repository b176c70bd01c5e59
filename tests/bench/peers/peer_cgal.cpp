// CGAL 5.5 (Debian's libcgal-dev): Efficient RANSAC (Schnabel et al.) for planes, on points
// with normals from PCA over 12 neighbours, one thread, with the user manual's parameters
// except epsilon (the inlier distance) and min_points, which are the benchmark's.
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Shape_detection/Efficient_RANSAC.h>
#include <CGAL/pca_estimate_normals.h>
#include <CGAL/property_map.h>

#include <utility>

#include "peers.hpp"

namespace blockmap::bench {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using PointWithNormal = std::pair<Kernel::Point_3, Kernel::Vector_3>;
using Points = std::vector<PointWithNormal>;
using PointMap = CGAL::First_of_pair_property_map<PointWithNormal>;
using NormalMap = CGAL::Second_of_pair_property_map<PointWithNormal>;
using Traits = CGAL::Shape_detection::Efficient_RANSAC_traits<Kernel, Points, PointMap, NormalMap>;
using EfficientRansac = CGAL::Shape_detection::Efficient_RANSAC<Traits>;
using Plane = CGAL::Shape_detection::Plane<Traits>;

}  // namespace

PeerRun run_cgal_efficient_ransac(std::span<const Eigen::Vector3f> points,
                                  const PeerParameters& parameters) {
  PeerRun run{"CGAL Efficient RANSAC (+ normals)",
              0.0,
              {},
              "PCA normals k = 12; probability 0.05, cluster epsilon 0.5 m, normal 0.9"};
  const Stopwatch watch;
  Points cloud;
  cloud.reserve(points.size());
  for (const Eigen::Vector3f& p : points) {
    cloud.emplace_back(Kernel::Point_3(p.x(), p.y(), p.z()), Kernel::Vector_3(0, 0, 0));
  }
  CGAL::pca_estimate_normals<CGAL::Sequential_tag>(
      cloud, 12, CGAL::parameters::point_map(PointMap()).normal_map(NormalMap()));
  EfficientRansac ransac;
  ransac.set_input(cloud);
  ransac.add_shape_factory<Plane>();
  EfficientRansac::Parameters settings;
  settings.probability = 0.05;
  settings.min_points = parameters.min_plane_points;
  settings.epsilon = parameters.distance_m;
  settings.cluster_epsilon = 0.5;
  settings.normal_threshold = 0.9;
  ransac.detect(settings);
  std::vector<std::int32_t> labels(points.size(), -1);
  std::int32_t label = 0;
  for (const auto& shape : ransac.shapes()) {
    for (const std::size_t i : shape->indices_of_assigned_points()) {
      labels[i] = label;
    }
    ++label;
  }
  run.seconds = watch.seconds();
  // The indices are into the detector's input range, which it sorts into its octree: the
  // points are read back from there, not from the caller's order.
  std::vector<Eigen::Vector3f> detected_order;
  detected_order.reserve(cloud.size());
  for (const PointWithNormal& p : cloud) {
    detected_order.emplace_back(static_cast<float>(p.first.x()), static_cast<float>(p.first.y()),
                                static_cast<float>(p.first.z()));
  }
  run.planes = planes_from_labels(detected_order, labels, parameters);
  return run;
}

}  // namespace blockmap::bench
