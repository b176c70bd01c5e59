#include "blockmap/planes/point_moments.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>

namespace blockmap::planes {

PlaneFit fit_plane(const PointMoments& moments) noexcept {
  PlaneFit fit;
  if (moments.weight < 3.0) {
    return fit;
  }
  fit.centroid_m = moments.mean();
  // The closed form for 3 x 3 (Eigen's computeDirect): a plane's smallest eigenvalue is well
  // apart from the others, where it is as exact as the iterative solver and several times
  // faster (the merger fits every candidate at every extraction).
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver;
  solver.computeDirect(moments.covariance());
  fit.eigenvalues_m2 = solver.eigenvalues().cwiseMax(0.0);
  fit.normal_unit = solver.eigenvectors().col(0).normalized();
  fit.d_m = fit.normal_unit.dot(fit.centroid_m);
  fit.rmse_m = std::sqrt(fit.eigenvalues_m2(0));
  fit.valid = fit.normal_unit.allFinite();
  return fit;
}

PlaneFit fit_plane_along_axis(const PointMoments& moments,
                              const Eigen::Vector3d& axis_unit) noexcept {
  PlaneFit fit;
  if (moments.weight < 3.0) {
    return fit;
  }
  fit.centroid_m = moments.mean();
  const Eigen::Matrix3d covariance = moments.covariance();
  // The normal is the direction of least spread among those square to the axis.
  const Eigen::Vector3d e1 = axis_unit.unitOrthogonal();
  const Eigen::Vector3d e2 = axis_unit.cross(e1);
  Eigen::Matrix<double, 3, 2> basis;
  basis << e1, e2;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> solver(basis.transpose() * covariance *
                                                              basis);
  const Eigen::Vector2d smallest = solver.eigenvectors().col(0);
  fit.normal_unit = (smallest.x() * e1 + smallest.y() * e2).normalized();
  fit.eigenvalues_m2 = Eigen::Vector3d(std::max(solver.eigenvalues()(0), 0.0),
                                       std::max(solver.eigenvalues()(1), 0.0),
                                       std::max(axis_unit.dot(covariance * axis_unit), 0.0));
  fit.d_m = fit.normal_unit.dot(fit.centroid_m);
  fit.rmse_m = std::sqrt(fit.eigenvalues_m2(0));
  fit.valid = fit.normal_unit.allFinite();
  return fit;
}

PlaneFit fit_vertical_plane(const PointMoments& moments) noexcept {
  PlaneFit fit;
  if (moments.weight < 3.0) {
    return fit;
  }
  fit.centroid_m = moments.mean();
  const Eigen::Matrix3d covariance = moments.covariance();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> solver(covariance.topLeftCorner<2, 2>());
  const Eigen::Vector2d across = solver.eigenvectors().col(0).normalized();
  fit.normal_unit = Eigen::Vector3d(across.x(), across.y(), 0.0);
  fit.eigenvalues_m2 =
      Eigen::Vector3d(std::max(solver.eigenvalues()(0), 0.0),
                      std::max(solver.eigenvalues()(1), 0.0), std::max(covariance(2, 2), 0.0));
  fit.d_m = fit.normal_unit.dot(fit.centroid_m);
  fit.rmse_m = std::sqrt(fit.eigenvalues_m2(0));
  fit.valid = fit.normal_unit.allFinite();
  return fit;
}

PlaneFit fit_plane_or_wall(const PointMoments& moments, double line_width_m) noexcept {
  PlaneFit wall = fit_vertical_plane(moments);
  const bool in_a_slice = wall.valid && std::sqrt(wall.eigenvalues_m2(2)) < line_width_m;
  if (!in_a_slice) {
    return fit_plane(moments);
  }
  wall.from_line = true;
  return wall;
}

}  // namespace blockmap::planes
