// What PathSmoother's files share: a keyframe's state (x, y, yaw and the receiver's slow
// error) and the blocks of the normal equations over it. Private to src/localize.
#pragma once

#include <Eigen/Core>

namespace blockmap::localize::path_state {

using Matrix5 = Eigen::Matrix<double, 5, 5, Eigen::RowMajor>;
using Vector5 = Eigen::Matrix<double, 5, 1>;
using Jacobian3 = Eigen::Matrix<double, 3, 5, Eigen::RowMajor>;
using Jacobian2 = Eigen::Matrix<double, 2, 5, Eigen::RowMajor>;

// The state's layout in a keyframe.
inline constexpr int kX = 0;
inline constexpr int kY = 1;
inline constexpr int kYaw = 2;
inline constexpr int kBiasX = 3;
inline constexpr int kBiasY = 4;

}  // namespace blockmap::localize::path_state
