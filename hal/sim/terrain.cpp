#include "blockmap/hal/sim/terrain.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "blockmap/hal/sim/random.hpp"

namespace blockmap::hal::sim {
namespace {

// Value noise: random heights on a lattice of spacing `wavelength / 2`, blended with a
// smoothstep, scaled so that its standard deviation is about `sigma`.
class ValueNoise {
 public:
  ValueNoise(const Vec2& min_m, const Vec2& max_m, double wavelength_m, double sigma_m,
             SimRandom& random)
      : origin_(min_m), spacing_(wavelength_m / 2.0) {
    nx_ = static_cast<std::size_t>(std::ceil((max_m.x() - min_m.x()) / spacing_)) + 2;
    ny_ = static_cast<std::size_t>(std::ceil((max_m.y() - min_m.y()) / spacing_)) + 2;
    values_.resize(nx_ * ny_);
    // Blending four lattice values lowers the spread; 1.5 brings it back to about sigma.
    for (double& value : values_) {
      value = random.gaussian(sigma_m * 1.5);
    }
  }

  [[nodiscard]] double at(double x_m, double y_m) const {
    const double gx = std::clamp((x_m - origin_.x()) / spacing_, 0.0, static_cast<double>(nx_ - 2));
    const double gy = std::clamp((y_m - origin_.y()) / spacing_, 0.0, static_cast<double>(ny_ - 2));
    const auto ix = static_cast<std::size_t>(gx);
    const auto iy = static_cast<std::size_t>(gy);
    const double fx = smooth(gx - static_cast<double>(ix));
    const double fy = smooth(gy - static_cast<double>(iy));
    const double v00 = values_[iy * nx_ + ix];
    const double v10 = values_[iy * nx_ + ix + 1];
    const double v01 = values_[(iy + 1) * nx_ + ix];
    const double v11 = values_[(iy + 1) * nx_ + ix + 1];
    return (v00 * (1 - fx) + v10 * fx) * (1 - fy) + (v01 * (1 - fx) + v11 * fx) * fy;
  }

 private:
  static double smooth(double f) { return f * f * (3.0 - 2.0 * f); }

  Vec2 origin_;
  double spacing_;
  std::size_t nx_ = 0;
  std::size_t ny_ = 0;
  std::vector<double> values_;
};

// Height added by a kerb at `p`: full height on its left within width_m, a 2 cm chamfer at the
// edge so that the step is steep but not a discontinuity for the interpolation.
double kerb_height_m(const Kerb& kerb, const Vec2& p) {
  const Vec2 along = (kerb.to_m - kerb.from_m).normalized();
  const Vec2 left(-along.y(), along.x());
  const double s = (p - kerb.from_m).dot(along);
  const double lateral = (p - kerb.from_m).dot(left);
  const double length = (kerb.to_m - kerb.from_m).norm();
  if (s < 0.0 || s > length || lateral < 0.0 || lateral > kerb.width_m) {
    return 0.0;
  }
  return kerb.height_m * std::min(1.0, lateral / 0.02);
}

}  // namespace

Terrain::Terrain(const Ground& ground, const Vec2& min_m, const Vec2& max_m, std::uint64_t seed)
    : min_m_(min_m), max_m_(max_m), cell_m_(ground.cell_m) {
  nx_ = static_cast<std::size_t>(std::ceil((max_m.x() - min_m.x()) / cell_m_)) + 1;
  ny_ = static_cast<std::size_t>(std::ceil((max_m.y() - min_m.y()) / cell_m_)) + 1;
  heights_.assign(nx_ * ny_, 0.0F);
  SimRandom random(seed, "terrain");
  if (ground.roughness_m > 0.0) {
    const ValueNoise noise(min_m, max_m, ground.roughness_wavelength_m, ground.roughness_m, random);
    for (std::size_t iy = 0; iy < ny_; ++iy) {
      for (std::size_t ix = 0; ix < nx_; ++ix) {
        at(ix, iy) = static_cast<float>(noise.at(min_m.x() + static_cast<double>(ix) * cell_m_,
                                                 min_m.y() + static_cast<double>(iy) * cell_m_));
      }
    }
  }
  // Bumps and kerbs touch only the cells under them.
  const auto cells_of = [&](double low, double high, double origin, std::size_t count) {
    const auto first = static_cast<std::ptrdiff_t>(std::floor((low - origin) / cell_m_));
    const auto last = static_cast<std::ptrdiff_t>(std::ceil((high - origin) / cell_m_));
    return std::pair<std::size_t, std::size_t>(
        static_cast<std::size_t>(
            std::clamp<std::ptrdiff_t>(first, 0, static_cast<std::ptrdiff_t>(count) - 1)),
        static_cast<std::size_t>(
            std::clamp<std::ptrdiff_t>(last, 0, static_cast<std::ptrdiff_t>(count) - 1)));
  };
  for (const Bump& bump : ground.bumps) {
    const auto [x0, x1] = cells_of(bump.position_m.x() - bump.radius_m,
                                   bump.position_m.x() + bump.radius_m, min_m.x(), nx_);
    const auto [y0, y1] = cells_of(bump.position_m.y() - bump.radius_m,
                                   bump.position_m.y() + bump.radius_m, min_m.y(), ny_);
    for (std::size_t iy = y0; iy <= y1; ++iy) {
      for (std::size_t ix = x0; ix <= x1; ++ix) {
        const Vec2 p(min_m.x() + static_cast<double>(ix) * cell_m_,
                     min_m.y() + static_cast<double>(iy) * cell_m_);
        const double r = (p - bump.position_m).norm() / bump.radius_m;
        if (r < 1.0) {
          at(ix, iy) +=
              static_cast<float>(bump.height_m * 0.5 * (1.0 + std::cos(std::numbers::pi * r)));
        }
      }
    }
  }
  for (const Kerb& kerb : ground.kerbs) {
    const Vec2 along = (kerb.to_m - kerb.from_m).normalized();
    const Vec2 left(-along.y(), along.x());
    const Vec2 corners[] = {kerb.from_m, kerb.to_m, kerb.from_m + left * kerb.width_m,
                            kerb.to_m + left * kerb.width_m};
    Vec2 low = corners[0];
    Vec2 high = corners[0];
    for (const Vec2& c : corners) {
      low = low.cwiseMin(c);
      high = high.cwiseMax(c);
    }
    const auto [x0, x1] = cells_of(low.x(), high.x(), min_m.x(), nx_);
    const auto [y0, y1] = cells_of(low.y(), high.y(), min_m.y(), ny_);
    for (std::size_t iy = y0; iy <= y1; ++iy) {
      for (std::size_t ix = x0; ix <= x1; ++ix) {
        const Vec2 p(min_m.x() + static_cast<double>(ix) * cell_m_,
                     min_m.y() + static_cast<double>(iy) * cell_m_);
        at(ix, iy) += static_cast<float>(kerb_height_m(kerb, p));
      }
    }
  }
  const auto [low, high] = std::minmax_element(heights_.begin(), heights_.end());
  min_height_m_ = std::min(0.0, static_cast<double>(*low));
  max_height_m_ = std::max(0.0, static_cast<double>(*high));
  build_tiles();
}

void Terrain::build_tiles() {
  tiles_x_ = (nx_ - 1 + kTileCells - 1) / kTileCells;
  tiles_y_ = (ny_ - 1 + kTileCells - 1) / kTileCells;
  tile_max_.assign(tiles_x_ * tiles_y_, std::numeric_limits<float>::lowest());
  for (std::size_t ty = 0; ty < tiles_y_; ++ty) {
    for (std::size_t tx = 0; tx < tiles_x_; ++tx) {
      float highest = std::numeric_limits<float>::lowest();
      // A tile's surface interpolates its own samples and those on its far edges.
      for (std::size_t iy = ty * kTileCells; iy <= std::min((ty + 1) * kTileCells, ny_ - 1); ++iy) {
        for (std::size_t ix = tx * kTileCells; ix <= std::min((tx + 1) * kTileCells, nx_ - 1);
             ++ix) {
          highest = std::max(highest, heights_[iy * nx_ + ix]);
        }
      }
      tile_max_[ty * tiles_x_ + tx] = highest;
    }
  }
}

double Terrain::height_m(double x_m, double y_m) const noexcept {
  const double gx = (x_m - min_m_.x()) / cell_m_;
  const double gy = (y_m - min_m_.y()) / cell_m_;
  if (!(gx >= 0.0 && gy >= 0.0 && gx < static_cast<double>(nx_ - 1) &&
        gy < static_cast<double>(ny_ - 1))) {
    return 0.0;
  }
  const auto ix = static_cast<std::size_t>(gx);
  const auto iy = static_cast<std::size_t>(gy);
  const double fx = gx - static_cast<double>(ix);
  const double fy = gy - static_cast<double>(iy);
  const float* row = heights_.data() + iy * nx_ + ix;
  const auto h00 = static_cast<double>(row[0]);
  const auto h10 = static_cast<double>(row[1]);
  const auto h01 = static_cast<double>(row[nx_]);
  const auto h11 = static_cast<double>(row[nx_ + 1]);
  const double h0 = h00 + (h10 - h00) * fx;
  const double h1 = h01 + (h11 - h01) * fx;
  return h0 + (h1 - h0) * fy;
}

double Terrain::march(const Vec3& origin, const Vec3& direction, double t0, double t1,
                      double miss) const {
  const double horizontal = std::hypot(direction.x(), direction.y());
  const double step = horizontal > 1e-9 ? std::min(0.5 * cell_m_ / horizontal, 1.0) : 1.0;
  const auto above = [&](double t) {
    const Vec3 p = origin + t * direction;
    return p.z() - height_m(p.x(), p.y());
  };
  double t_prev = t0;
  if (above(t_prev) <= 0.0) {
    return t_prev > 0.0 ? t_prev : miss;  // starts below ground: only a wheel-level origin
  }
  for (double t = t0 + step;; t += step) {
    const double t_now = std::min(t, t1);
    if (above(t_now) <= 0.0) {
      double low = t_prev;
      double high = t_now;
      for (int i = 0; i < 12; ++i) {
        const double mid = 0.5 * (low + high);
        (above(mid) > 0.0 ? low : high) = mid;
      }
      return high;
    }
    if (t_now >= t1) {
      return miss;
    }
    t_prev = t_now;
  }
}

double Terrain::intersect(const Vec3& origin, const Vec3& direction, double max_t) const {
  const double miss = max_t + 1.0;
  // Only the stretch of the ray inside the band [min height, max height] can touch the ground.
  double t = 0.0;
  double t_end = max_t;
  if (direction.z() < -1e-12) {
    t = std::max(0.0, (origin.z() - max_height_m_) / -direction.z());
    t_end = std::min(max_t, (origin.z() - min_height_m_) / -direction.z());
  } else if (origin.z() > max_height_m_) {
    return miss;
  }
  // Walk the tiles the ray crosses (a 2D DDA); march only where it dips below a tile's top.
  const double tile_m = cell_m_ * static_cast<double>(kTileCells);
  if (t > t_end) {
    return miss;
  }
  for (;;) {
    const Vec3 p = origin + t * direction;
    const double gx = (p.x() - min_m_.x()) / tile_m;
    const double gy = (p.y() - min_m_.y()) / tile_m;
    const double fx = std::floor(gx);
    const double fy = std::floor(gy);
    double t_exit = t_end;
    if (std::abs(direction.x()) > 1e-12) {
      const double edge = min_m_.x() + (direction.x() > 0 ? fx + 1 : fx) * tile_m;
      t_exit = std::min(t_exit, (edge - origin.x()) / direction.x());
    }
    if (std::abs(direction.y()) > 1e-12) {
      const double edge = min_m_.y() + (direction.y() > 0 ? fy + 1 : fy) * tile_m;
      t_exit = std::min(t_exit, (edge - origin.y()) / direction.y());
    }
    t_exit = std::max(t_exit, t + 1e-9);  // on an edge: step past it
    const double lowest_z = std::min(p.z(), origin.z() + t_exit * direction.z());
    const bool inside = fx >= 0 && fy >= 0 && fx < static_cast<double>(tiles_x_) &&
                        fy < static_cast<double>(tiles_y_);
    if (!inside) {
      // Flat at 0 outside the grid: a plane.
      if (direction.z() < -1e-12) {
        const double t_zero = origin.z() / -direction.z();
        if (t_zero >= t && t_zero <= std::min(t_exit, t_end)) {
          return t_zero;
        }
      }
    } else {
      const auto top = static_cast<double>(
          tile_max_[static_cast<std::size_t>(fy) * tiles_x_ + static_cast<std::size_t>(fx)]);
      if (lowest_z <= top) {
        const double hit = march(origin, direction, t, std::min(t_exit, t_end), miss);
        if (hit <= max_t) {
          return hit;
        }
      }
    }
    if (t_exit >= t_end) {
      return miss;
    }
    t = t_exit;
  }
}

}  // namespace blockmap::hal::sim
