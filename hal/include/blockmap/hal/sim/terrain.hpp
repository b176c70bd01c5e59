// The ground of a simulated world as a height grid: smooth random unevenness, bumps and kerbs,
// built once, then read by bilinear interpolation (the robot's wheels and the lasers' rays see
// the same surface). Outside the grid the ground is flat at height 0.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "blockmap/hal/sim/world.hpp"

namespace blockmap::hal::sim {

class Terrain {
 public:
  // Covers [min_m, max_m]; `seed` draws the unevenness.
  Terrain(const Ground& ground, const Vec2& min_m, const Vec2& max_m, std::uint64_t seed);

  [[nodiscard]] double height_m(double x_m, double y_m) const noexcept;
  // Lowest and highest height anywhere (rays outside this band cannot hit the ground).
  [[nodiscard]] double min_height_m() const noexcept { return min_height_m_; }
  [[nodiscard]] double max_height_m() const noexcept { return max_height_m_; }
  [[nodiscard]] const Vec2& min_m() const noexcept { return min_m_; }
  [[nodiscard]] const Vec2& max_m() const noexcept { return max_m_; }
  [[nodiscard]] double cell_m() const noexcept { return cell_m_; }

  // The first crossing of the ray origin + t * direction (unit) with the ground for t in
  // (0, max_t]; max_t + 1 when there is none. Walks the grid's tiles, skips those whose highest
  // point the ray passes above, marches the others at half a cell, then bisects.
  [[nodiscard]] double intersect(const Vec3& origin, const Vec3& direction, double max_t) const;

  [[nodiscard]] std::size_t memory_bytes() const noexcept {
    return heights_.capacity() * sizeof(float) + tile_max_.capacity() * sizeof(float);
  }

 private:
  static constexpr std::size_t kTileCells = 16;

  [[nodiscard]] float& at(std::size_t ix, std::size_t iy) { return heights_[iy * nx_ + ix]; }
  void build_tiles();
  // The first ground crossing within [t0, t1] of the ray, marching; max_t + 1 when none.
  [[nodiscard]] double march(const Vec3& origin, const Vec3& direction, double t0, double t1,
                             double miss) const;

  Vec2 min_m_;
  Vec2 max_m_;
  double cell_m_;
  std::size_t nx_ = 0;
  std::size_t ny_ = 0;
  std::vector<float> heights_;
  std::size_t tiles_x_ = 0;
  std::size_t tiles_y_ = 0;
  std::vector<float> tile_max_;  // the highest grid height of each tile (and its far edges)
  double min_height_m_ = 0.0;
  double max_height_m_ = 0.0;
};

}  // namespace blockmap::hal::sim
