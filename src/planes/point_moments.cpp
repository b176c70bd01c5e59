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
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(moments.covariance());
  fit.eigenvalues_m2 = solver.eigenvalues().cwiseMax(0.0);
  fit.normal_unit = solver.eigenvectors().col(0).normalized();
  fit.d_m = fit.normal_unit.dot(fit.centroid_m);
  fit.rmse_m = std::sqrt(fit.eigenvalues_m2(0));
  fit.valid = fit.normal_unit.allFinite();
  return fit;
}

}  // namespace blockmap::planes
