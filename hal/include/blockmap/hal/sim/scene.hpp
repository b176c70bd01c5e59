// What a laser beam can hit in a simulated world, and the ground truth of its planar faces.
//
// Built once from a World: every wall is a rectangle, every roof a horizontal polygon, the
// ground a Terrain; trunks and people are vertical cylinders, canopies and bushes porous
// ellipsoids, cars two boxes. A scan first selects the primitives its scan plane can reach
// (begin_scan), then casts each beam against that short list, so a beam costs a few dozen
// intersection tests whatever the size of the world. Nothing allocates after construction.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "blockmap/hal/sim/random.hpp"
#include "blockmap/hal/sim/terrain.hpp"
#include "blockmap/hal/sim/world.hpp"

namespace blockmap::hal::sim {

enum class SurfaceKind : std::uint8_t {
  kNone,
  kWall,
  kRoof,
  kGround,
  kTrunk,
  kFoliage,
  kCar,
  kPerson
};
[[nodiscard]] const char* to_string(SurfaceKind kind) noexcept;

// A planar face of the truth: normal . x = d, its corners, and the beams that returned from it.
struct TruthFace {
  int id = 0;
  SurfaceKind kind = SurfaceKind::kWall;  // kWall, kRoof or kGround
  int building_id = -1;                   // -1: none (the ground)
  Vec3 normal = Vec3::UnitZ();            // outward (walls), up (roofs, ground)
  double d_m = 0.0;
  std::vector<Vec3> corners_m;
  std::uint64_t returns = 0;
};

struct Hit {
  double range_m = 0.0;
  SurfaceKind kind = SurfaceKind::kNone;  // kNone: nothing within range
  int face = -1;                          // index into faces() for walls, roofs and the ground
};

class Scene {
 public:
  Scene(const World& world, std::uint64_t seed);

  // Selects what a scan from `origin` in the plane with normal `plane_normal` can reach within
  // `max_range_m`, with the people where they are at `time_s` into the run.
  void begin_scan(const Vec3& origin, const Vec3& plane_normal, double max_range_m,
                  double time_s) noexcept;
  // The first surface along origin + t * direction (unit), t in (0, max_range_m]. `random`
  // decides where a beam stops inside foliage.
  [[nodiscard]] Hit cast(const Vec3& origin, const Vec3& direction, double max_range_m,
                         SimRandom& random) const noexcept;

  [[nodiscard]] const std::vector<TruthFace>& faces() const noexcept { return faces_; }
  void count_return(int face) noexcept { ++faces_[static_cast<std::size_t>(face)].returns; }
  [[nodiscard]] const Terrain& terrain() const noexcept { return terrain_; }
  [[nodiscard]] const World& world() const noexcept { return world_; }
  // Where person `index` is at `time_s` (walking back and forth).
  [[nodiscard]] Vec2 person_position(std::size_t index, double time_s) const noexcept;
  [[nodiscard]] std::size_t memory_bytes() const noexcept;

 private:
  struct Aabb {
    Vec3 centre;
    Vec3 half;
  };
  struct Rect {  // p0 + a * u + b * v, a in [0, u_length], b in [0, v_length]
    Vec3 p0, u, v, normal;
    double u_length = 0.0, v_length = 0.0, d = 0.0;
    SurfaceKind kind = SurfaceKind::kWall;
    int face = -1;
  };
  struct Roof {
    std::size_t building = 0;  // index into world_.buildings (its footprint)
    double z_m = 0.0;
    Eigen::Vector2d low, high;
    int face = -1;
  };
  struct Cylinder {  // vertical
    Vec2 centre;
    double radius = 0.0, z0 = 0.0, z1 = 0.0;
    SurfaceKind kind = SurfaceKind::kTrunk;
    int person = -1;  // >= 0: moves with that person
  };
  struct Ellipsoid {  // porous, axis-aligned
    Vec3 centre, inverse_radii;
    double density_per_m = 0.0;
  };
  struct Box {  // oriented about z
    Vec2 centre;
    double cos_yaw = 1.0, sin_yaw = 0.0;
    Vec3 half;  // half extents; z from z0
    double z0 = 0.0;
  };
  enum class Type : std::uint8_t { kRect, kRoof, kCylinder, kEllipsoid, kBox };
  struct Ref {
    Type type;
    std::uint32_t index;
  };

  void add_building(std::size_t index);
  void add_ground_face();
  void add(Type type, std::size_t index, const Aabb& box);

  World world_;
  Terrain terrain_;
  std::vector<TruthFace> faces_;
  std::vector<Rect> rects_;
  std::vector<Roof> roofs_;
  std::vector<Cylinder> cylinders_;
  std::vector<Ellipsoid> ellipsoids_;
  std::vector<Box> boxes_;
  std::vector<Ref> refs_;
  std::vector<Aabb> bounds_;   // of refs_[i]
  std::vector<Ref> selected_;  // capacity refs_.size(): begin_scan never allocates
  std::size_t selected_count_ = 0;
};

// The axis-aligned bounds of a world (buildings, objects and the path) grown by `margin_m`.
void world_bounds(const World& world, double margin_m, Vec2& min_m, Vec2& max_m);

}  // namespace blockmap::hal::sim
