// First and second moments of a set of points. They are all a least-squares plane fit needs,
// they merge exactly (the moments of a union are the sum of the moments), and points can be
// taken out again, which the streaming map needs when points leave its window.
#pragma once

#include <Eigen/Core>

namespace blockmap::planes {

// In double: sums over a whole wall reach 1e7 m^2 and must keep centimetres.
struct PointMoments {
  double weight = 0.0;                                  // number of points (or their total weight)
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();        // sum of p, relative to the owner's origin
  Eigen::Matrix3d sum_outer = Eigen::Matrix3d::Zero();  // sum of p p^T

  void add(const Eigen::Vector3d& point, double point_weight = 1.0) noexcept {
    weight += point_weight;
    sum += point_weight * point;
    sum_outer += point_weight * point * point.transpose();
  }
  void merge(const PointMoments& other) noexcept {
    weight += other.weight;
    sum += other.sum;
    sum_outer += other.sum_outer;
  }
  // The same points seen from an origin `shift_m` away: p' = p + shift_m.
  [[nodiscard]] PointMoments shifted(const Eigen::Vector3d& shift_m) const noexcept {
    PointMoments out;
    out.weight = weight;
    out.sum = sum + weight * shift_m;
    out.sum_outer = sum_outer + sum * shift_m.transpose() + shift_m * sum.transpose() +
                    weight * shift_m * shift_m.transpose();
    return out;
  }
  // The same points moved rigidly: p' = rotation p + shift_m.
  [[nodiscard]] PointMoments moved(const Eigen::Matrix3d& rotation,
                                   const Eigen::Vector3d& shift_m) const noexcept {
    PointMoments out;
    out.weight = weight;
    const Eigen::Vector3d turned = rotation * sum;
    out.sum = turned + weight * shift_m;
    out.sum_outer = rotation * sum_outer * rotation.transpose() + turned * shift_m.transpose() +
                    shift_m * turned.transpose() + weight * shift_m * shift_m.transpose();
    return out;
  }
  [[nodiscard]] Eigen::Vector3d mean() const noexcept { return sum / weight; }
  [[nodiscard]] Eigen::Matrix3d covariance() const noexcept {
    const Eigen::Vector3d m = mean();
    return sum_outer / weight - m * m.transpose();
  }
};

// The least-squares plane n . p = d of a set of points: the normal is the covariance's
// eigenvector of the smallest eigenvalue, the plane passes through the centroid.
struct PlaneFit {
  bool valid = false;  // false for fewer than three points
  Eigen::Vector3d normal_unit = Eigen::Vector3d::UnitZ();
  double d_m = 0.0;  // relative to the moments' origin
  Eigen::Vector3d centroid_m = Eigen::Vector3d::Zero();
  double rmse_m = 0.0;                                       // RMS point distance to the plane
  Eigen::Vector3d eigenvalues_m2 = Eigen::Vector3d::Zero();  // ascending
  bool from_line = false;  // fit_plane_or_wall: the vertical plane through a horizontal line
};

[[nodiscard]] PlaneFit fit_plane(const PointMoments& moments) noexcept;

// The least-squares plane that contains the direction `axis_unit` (its normal square to it).
// eigenvalues_m2 holds the points' spread across the plane, in it square to the axis, and
// along the axis.
[[nodiscard]] PlaneFit fit_plane_along_axis(const PointMoments& moments,
                                            const Eigen::Vector3d& axis_unit) noexcept;

// The least-squares vertical plane: the line that best fits the points seen from above.
// eigenvalues_m2 holds the points' horizontal spread across and along the plane, then their
// vertical spread.
[[nodiscard]] PlaneFit fit_vertical_plane(const PointMoments& moments) noexcept;

// fit_plane(), unless the points lie in one horizontal slice (spread less than line_width_m
// vertically): a wall as a level 2D laser sees it, a line, which fits every plane through it
// and the slice itself. Then the vertical plane that fits the points seen from above, the
// paper's assumption for walls, with from_line set; eigenvalues_m2(1) then says whether they
// are a line (spread along it) or a blob.
[[nodiscard]] PlaneFit fit_plane_or_wall(const PointMoments& moments, double line_width_m) noexcept;

}  // namespace blockmap::planes
