// What the building fitter's stages share: the footprint's frame (u along the group's
// dominant axis, v across it) and the edges of a rectilinear model in it. Private to
// src/buildings.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>

#include <Eigen/Core>

#include "blockmap/buildings/building_fitter.hpp"

namespace blockmap::buildings::footprint {

// Observed walls and model edges are compared at points this far apart.
inline constexpr double kSampleStepM = 0.25;

// A point of the map in the frame turned by axis_rad, and back.
inline Eigen::Vector2d to_frame(const Eigen::Vector2d& p, double axis_rad) {
  const double c = std::cos(axis_rad);
  const double s = std::sin(axis_rad);
  return {c * p.x() + s * p.y(), -s * p.x() + c * p.y()};
}

inline Eigen::Vector2d from_frame(const Eigen::Vector2d& q, double axis_rad) {
  const double c = std::cos(axis_rad);
  const double s = std::sin(axis_rad);
  return {c * q.x() - s * q.y(), s * q.x() + c * q.y()};
}

// One edge of a rectilinear model: it runs along `axis` at `level`, from `from` to `to` along
// that axis (in the footprint's counter-clockwise order).
struct Edge {
  int axis = 0;
  double level = 0.0;
  double from = 0.0;
  double to = 0.0;
  [[nodiscard]] double lo() const { return std::min(from, to); }
  [[nodiscard]] double hi() const { return std::max(from, to); }
  [[nodiscard]] Eigen::Vector2d point(double along) const {
    return axis == 0 ? Eigen::Vector2d(along, level) : Eigen::Vector2d(level, along);
  }
};

inline Edge edge_of(const BuildingFitter::Model& model, std::size_t k) {
  const Eigen::Vector2d& a = model.corners[k];
  const Eigen::Vector2d& b = model.corners[(k + 1) % model.size];
  const int axis = std::abs(b.x() - a.x()) >= std::abs(b.y() - a.y()) ? 0 : 1;
  return {axis, a[1 - axis], a[axis], b[axis]};
}

using Piece = BuildingFitter::Piece;
using Box = BuildingFitter::Box;

// Whether a piece lies on the line of an edge (same direction, level within tolerance).
inline bool on_line(const Piece& piece, int axis, double level, double tolerance_m) {
  return piece.axis == axis && std::abs(piece.level - level) <= tolerance_m;
}

}  // namespace blockmap::buildings::footprint
