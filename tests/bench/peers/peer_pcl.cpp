// PCL 1.13 (Debian's libpcl-dev), the two ways its users find planes:
// - iterative RANSAC: SACSegmentation finds the largest plane, its inliers are removed, and
//   again, until no plane of min_plane_points is left (the tutorial's loop);
// - region growing: normals from the 30 nearest neighbours (kd-tree), regions grown while
//   normals agree within 3 deg (the tutorial's settings), a plane fitted to each region.
#include "peers.hpp"

#include <algorithm>
#include <numbers>

#include <pcl/features/normal_3d.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/sample_consensus/method_types.h>
#include <pcl/sample_consensus/model_types.h>
#include <pcl/search/kdtree.h>
#include <pcl/segmentation/region_growing.h>
#include <pcl/segmentation/sac_segmentation.h>

namespace blockmap::bench {
namespace {

pcl::PointCloud<pcl::PointXYZ>::Ptr to_pcl(std::span<const Eigen::Vector3f> points) {
  auto cloud = std::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  cloud->reserve(points.size());
  for (const Eigen::Vector3f& p : points) {
    cloud->push_back(pcl::PointXYZ(p.x(), p.y(), p.z()));
  }
  return cloud;
}

}  // namespace

PeerRun run_pcl_ransac(std::span<const Eigen::Vector3f> points, const PeerParameters& parameters) {
  PeerRun run{"PCL SACSegmentation, iterative", 0.0, {}, ""};
  const Stopwatch watch;
  const auto cloud = to_pcl(points);
  pcl::SACSegmentation<pcl::PointXYZ> segmentation;
  segmentation.setOptimizeCoefficients(true);
  segmentation.setModelType(pcl::SACMODEL_PLANE);
  segmentation.setMethodType(pcl::SAC_RANSAC);
  segmentation.setMaxIterations(1000);
  segmentation.setDistanceThreshold(parameters.distance_m);
  segmentation.setInputCloud(cloud);
  auto remaining = std::make_shared<pcl::Indices>(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    (*remaining)[i] = static_cast<pcl::index_t>(i);
  }
  std::vector<std::int32_t> labels(points.size(), -1);
  std::int32_t planes = 0;
  while (remaining->size() >= parameters.min_plane_points &&
         static_cast<std::size_t>(planes) < parameters.max_planes) {
    if (watch.seconds() > parameters.time_limit_s) {
      run.note = "stopped at the time limit";
      break;
    }
    segmentation.setIndices(remaining);
    pcl::PointIndices inliers;
    pcl::ModelCoefficients coefficients;
    segmentation.segment(inliers, coefficients);
    if (inliers.indices.size() < parameters.min_plane_points) {
      break;
    }
    for (const pcl::index_t i : inliers.indices) {
      labels[static_cast<std::size_t>(i)] = planes;
    }
    ++planes;
    std::erase_if(*remaining,
                  [&](pcl::index_t i) { return labels[static_cast<std::size_t>(i)] >= 0; });
  }
  run.seconds = watch.seconds();
  run.planes = planes_from_labels(points, labels, parameters);
  run.note += (run.note.empty() ? "" : "; ") + std::string("1000 iterations, distance 0.10 m");
  return run;
}

PeerRun run_pcl_region_growing(std::span<const Eigen::Vector3f> points,
                               const PeerParameters& parameters) {
  PeerRun run{"PCL RegionGrowing (+ normals)", 0.0, {}, "k = 30, smoothness 3 deg, curvature 1"};
  const Stopwatch watch;
  const auto cloud = to_pcl(points);
  auto tree = std::make_shared<pcl::search::KdTree<pcl::PointXYZ>>();
  auto normals = std::make_shared<pcl::PointCloud<pcl::Normal>>();
  pcl::NormalEstimation<pcl::PointXYZ, pcl::Normal> estimation;
  estimation.setSearchMethod(tree);
  estimation.setInputCloud(cloud);
  estimation.setKSearch(30);
  estimation.compute(*normals);
  pcl::RegionGrowing<pcl::PointXYZ, pcl::Normal> growing;
  growing.setMinClusterSize(static_cast<pcl::uindex_t>(parameters.min_plane_points));
  growing.setMaxClusterSize(static_cast<pcl::uindex_t>(points.size()));
  growing.setSearchMethod(tree);
  growing.setNumberOfNeighbours(30);
  growing.setInputCloud(cloud);
  growing.setInputNormals(normals);
  growing.setSmoothnessThreshold(static_cast<float>(3.0 * std::numbers::pi / 180.0));
  growing.setCurvatureThreshold(1.0f);
  std::vector<pcl::PointIndices> clusters;
  growing.extract(clusters);
  std::vector<std::int32_t> labels(points.size(), -1);
  for (std::size_t c = 0; c < clusters.size(); ++c) {
    for (const pcl::index_t i : clusters[c].indices) {
      labels[static_cast<std::size_t>(i)] = static_cast<std::int32_t>(c);
    }
  }
  run.seconds = watch.seconds();
  run.planes = planes_from_labels(points, labels, parameters);
  return run;
}

}  // namespace blockmap::bench
