#include "blockmap/hal/sim/scene.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace blockmap::hal::sim {
namespace {

constexpr double kMinRangeM = 1e-3;     // hits closer than this are the sensor's own housing
constexpr double kMarginM = 30.0;       // ground beyond the outermost object
constexpr double kGroundReachM = 80.0;  // the LMS2xx's longest range

// Ray-crossing test of a point against a polygon (even-odd).
bool inside_polygon(const std::vector<Vec2>& polygon, double x, double y) noexcept {
  bool inside = false;
  for (std::size_t i = 0, j = polygon.size() - 1; i < polygon.size(); j = i++) {
    const Vec2& a = polygon[i];
    const Vec2& b = polygon[j];
    if ((a.y() > y) != (b.y() > y) && x < (b.x() - a.x()) * (y - a.y()) / (b.y() - a.y()) + a.x()) {
      inside = !inside;
    }
  }
  return inside;
}

}  // namespace

const char* to_string(SurfaceKind kind) noexcept {
  switch (kind) {
    case SurfaceKind::kNone:
      return "none";
    case SurfaceKind::kWall:
      return "wall";
    case SurfaceKind::kRoof:
      return "roof";
    case SurfaceKind::kGround:
      return "ground";
    case SurfaceKind::kTrunk:
      return "trunk";
    case SurfaceKind::kFoliage:
      return "foliage";
    case SurfaceKind::kCar:
      return "car";
    case SurfaceKind::kPerson:
      return "person";
  }
  return "unknown";
}

void world_bounds(const World& world, double margin_m, Vec2& min_m, Vec2& max_m) {
  min_m = Vec2::Constant(std::numeric_limits<double>::max());
  max_m = Vec2::Constant(std::numeric_limits<double>::lowest());
  const auto grow = [&](const Vec2& p, double radius) {
    min_m = min_m.cwiseMin(p - Vec2::Constant(radius));
    max_m = max_m.cwiseMax(p + Vec2::Constant(radius));
  };
  for (const Building& building : world.buildings) {
    for (const Vec2& p : building.footprint_m) {
      grow(p, 0.0);
    }
  }
  for (const Tree& tree : world.trees) {
    grow(tree.position_m, tree.canopy_radius_m);
  }
  for (const Bush& bush : world.bushes) {
    grow(bush.position_m, bush.radius_m);
  }
  for (const Car& car : world.cars) {
    grow(car.position_m, car.length_m);
  }
  for (const Person& person : world.people) {
    grow(person.from_m, person.radius_m);
    grow(person.to_m, person.radius_m);
  }
  for (const Vec2& p : world.path.waypoints_m) {
    grow(p, 0.0);
  }
  min_m -= Vec2::Constant(margin_m);
  max_m += Vec2::Constant(margin_m);
}

namespace {

// The ground under everything in the world, and a margin around it.
Terrain terrain_for(const World& world, std::uint64_t seed) {
  Vec2 low;
  Vec2 high;
  world_bounds(world, kMarginM, low, high);
  return {world.ground, low, high, seed};
}

}  // namespace

Scene::Scene(const World& world, std::uint64_t seed)
    : world_(world), terrain_(terrain_for(world, seed)) {
  add_ground_face();
  for (std::size_t b = 0; b < world_.buildings.size(); ++b) {
    add_building(b);
  }
  for (const Tree& tree : world_.trees) {
    const double base = terrain_.height_m(tree.position_m.x(), tree.position_m.y());
    Cylinder trunk{tree.position_m,     tree.trunk_radius_m,
                   base - 0.5,          base + tree.trunk_height_m,
                   SurfaceKind::kTrunk, -1};
    cylinders_.push_back(trunk);
    add(Type::kCylinder, cylinders_.size() - 1,
        {Vec3(tree.position_m.x(), tree.position_m.y(), (trunk.z0 + trunk.z1) / 2),
         Vec3(tree.trunk_radius_m, tree.trunk_radius_m, (trunk.z1 - trunk.z0) / 2)});
    if (tree.canopy_radius_m > 0.0 && tree.canopy_density_per_m > 0.0) {
      const Vec3 centre(tree.position_m.x(), tree.position_m.y(),
                        base + tree.canopy_centre_height_m);
      ellipsoids_.push_back(
          {centre, Vec3::Constant(1.0 / tree.canopy_radius_m), tree.canopy_density_per_m});
      add(Type::kEllipsoid, ellipsoids_.size() - 1, {centre, Vec3::Constant(tree.canopy_radius_m)});
    }
  }
  for (const Bush& bush : world_.bushes) {
    const double base = terrain_.height_m(bush.position_m.x(), bush.position_m.y());
    const Vec3 radii(bush.radius_m, bush.radius_m, bush.height_m / 2.0);
    const Vec3 centre(bush.position_m.x(), bush.position_m.y(), base + bush.height_m / 2.0);
    ellipsoids_.push_back({centre, radii.cwiseInverse(), bush.density_per_m});
    add(Type::kEllipsoid, ellipsoids_.size() - 1, {centre, radii});
  }
  for (const Car& car : world_.cars) {
    const double base = terrain_.height_m(car.position_m.x(), car.position_m.y());
    const double c = std::cos(car.yaw_rad);
    const double s = std::sin(car.yaw_rad);
    // Body up to 55 % of the height (from 0.15 m: the gap under the car), cabin above it.
    const Box body{car.position_m, c, s,
                   Vec3(car.length_m / 2, car.width_m / 2, 0.55 * car.height_m / 2 - 0.075),
                   base + 0.15};
    const Box cabin{car.position_m - 0.1 * car.length_m * Vec2(c, s), c, s,
                    Vec3(0.28 * car.length_m, 0.45 * car.width_m, 0.45 * car.height_m / 2),
                    base + 0.55 * car.height_m};
    for (const Box& box : {body, cabin}) {
      boxes_.push_back(box);
      const double extent = std::hypot(box.half.x(), box.half.y());
      add(Type::kBox, boxes_.size() - 1,
          {Vec3(box.centre.x(), box.centre.y(), box.z0 + box.half.z()),
           Vec3(extent, extent, box.half.z())});
    }
  }
  for (std::size_t p = 0; p < world_.people.size(); ++p) {
    const Person& person = world_.people[p];
    cylinders_.push_back({person.from_m, person.radius_m, -1.0, person.height_m,
                          SurfaceKind::kPerson, static_cast<int>(p)});
    const Vec2 low = person.from_m.cwiseMin(person.to_m) - Vec2::Constant(person.radius_m);
    const Vec2 high = person.from_m.cwiseMax(person.to_m) + Vec2::Constant(person.radius_m);
    add(Type::kCylinder, cylinders_.size() - 1,
        {Vec3((low.x() + high.x()) / 2, (low.y() + high.y()) / 2, person.height_m / 2),
         Vec3((high.x() - low.x()) / 2, (high.y() - low.y()) / 2, person.height_m / 2 + 1.0)});
  }
  selected_.resize(refs_.size());
}

void Scene::add(Type type, std::size_t index, const Aabb& box) {
  refs_.push_back({type, static_cast<std::uint32_t>(index)});
  bounds_.push_back(box);
}

void Scene::add_ground_face() {
  TruthFace ground;
  ground.id = 0;
  ground.kind = SurfaceKind::kGround;
  ground.normal = Vec3::UnitZ();
  ground.d_m = 0.0;
  // Beyond its height grid the ground goes on flat: the face reaches as far as a laser does.
  const Vec2 low = terrain_.min_m() - Vec2::Constant(kGroundReachM);
  const Vec2 high = terrain_.max_m() + Vec2::Constant(kGroundReachM);
  ground.corners_m = {Vec3(low.x(), low.y(), 0), Vec3(high.x(), low.y(), 0),
                      Vec3(high.x(), high.y(), 0), Vec3(low.x(), high.y(), 0)};
  faces_.push_back(ground);
}

void Scene::add_building(std::size_t index) {
  const Building& building = world_.buildings[index];
  const std::vector<Vec2>& footprint = building.footprint_m;
  // Walls stand on the lowest ground under the building so that no gap shows under them.
  double base = std::numeric_limits<double>::max();
  for (const Vec2& p : footprint) {
    base = std::min(base, terrain_.height_m(p.x(), p.y()));
  }
  base = std::min(base, 0.0);
  for (std::size_t i = 0; i < footprint.size(); ++i) {
    const Vec2& a = footprint[i];
    const Vec2& b = footprint[(i + 1) % footprint.size()];
    const Vec2 edge = b - a;
    const Vec2 outward = Vec2(edge.y(), -edge.x()).normalized();  // counter-clockwise footprint
    Rect wall;
    wall.p0 = Vec3(a.x(), a.y(), base);
    wall.u = Vec3(edge.x(), edge.y(), 0.0).normalized();
    wall.u_length = edge.norm();
    wall.v = Vec3::UnitZ();
    wall.v_length = building.height_m - base;
    wall.normal = Vec3(outward.x(), outward.y(), 0.0);
    wall.d = wall.normal.dot(wall.p0);
    wall.kind = SurfaceKind::kWall;
    wall.face = static_cast<int>(faces_.size());
    TruthFace face;
    face.id = wall.face;
    face.kind = SurfaceKind::kWall;
    face.building_id = building.id;
    face.normal = wall.normal;
    face.d_m = wall.d;
    face.corners_m = {Vec3(a.x(), a.y(), 0.0), Vec3(b.x(), b.y(), 0.0),
                      Vec3(b.x(), b.y(), building.height_m), Vec3(a.x(), a.y(), building.height_m)};
    faces_.push_back(face);
    rects_.push_back(wall);
    const Vec3 mid = wall.p0 + 0.5 * wall.u_length * wall.u + 0.5 * wall.v_length * wall.v;
    add(Type::kRect, rects_.size() - 1,
        {mid, Vec3(std::abs(edge.x()) / 2, std::abs(edge.y()) / 2, wall.v_length / 2)});
  }
  Roof roof;
  roof.building = index;
  roof.z_m = building.height_m;
  roof.low = footprint.front();
  roof.high = footprint.front();
  for (const Vec2& p : footprint) {
    roof.low = roof.low.cwiseMin(p);
    roof.high = roof.high.cwiseMax(p);
  }
  roof.face = static_cast<int>(faces_.size());
  TruthFace face;
  face.id = roof.face;
  face.kind = SurfaceKind::kRoof;
  face.building_id = building.id;
  face.normal = Vec3::UnitZ();
  face.d_m = building.height_m;
  for (const Vec2& p : footprint) {
    face.corners_m.emplace_back(p.x(), p.y(), building.height_m);
  }
  faces_.push_back(face);
  roofs_.push_back(roof);
  const Vec2 centre = (roof.low + roof.high) / 2;
  const Vec2 half = (roof.high - roof.low) / 2;
  add(Type::kRoof, roofs_.size() - 1,
      {Vec3(centre.x(), centre.y(), roof.z_m), Vec3(half.x(), half.y(), 0.0)});
}

Vec2 Scene::person_position(std::size_t index, double time_s) const noexcept {
  const Person& person = world_.people[index];
  const double length = (person.to_m - person.from_m).norm();
  if (length < 1e-9 || person.speed_mps <= 0.0) {
    return person.from_m;
  }
  // Back and forth: a triangle wave of period 2 * length / speed.
  const double travelled = std::fmod(time_s * person.speed_mps, 2.0 * length);
  const double s = travelled <= length ? travelled : 2.0 * length - travelled;
  return person.from_m + (person.to_m - person.from_m) * (s / length);
}

void Scene::begin_scan(const Vec3& origin, const Vec3& plane_normal, double max_range_m,
                       double time_s) noexcept {
  for (Cylinder& cylinder : cylinders_) {
    if (cylinder.person >= 0) {
      cylinder.centre = person_position(static_cast<std::size_t>(cylinder.person), time_s);
    }
  }
  selected_count_ = 0;
  const Vec3 abs_normal = plane_normal.cwiseAbs();
  for (std::size_t i = 0; i < refs_.size(); ++i) {
    const Aabb& box = bounds_[i];
    const Vec3 offset = box.centre - origin;
    // The box lies wholly on one side of the scan plane: no beam can reach it.
    if (std::abs(plane_normal.dot(offset)) > abs_normal.dot(box.half) + 1e-6) {
      continue;
    }
    // Or wholly beyond the maximum range.
    if ((offset.cwiseAbs() - box.half).cwiseMax(0.0).norm() > max_range_m) {
      continue;
    }
    selected_[selected_count_++] = refs_[i];
  }
}

Hit Scene::cast(const Vec3& origin, const Vec3& direction, double max_range_m,
                SimRandom& random) const noexcept {
  Hit hit;
  double best = max_range_m;
  const auto take = [&](double t, SurfaceKind kind, int face) {
    if (t > kMinRangeM && t < best) {
      best = t;
      hit.kind = kind;
      hit.face = face;
    }
  };
  for (std::size_t k = 0; k < selected_count_; ++k) {
    const Ref ref = selected_[k];
    switch (ref.type) {
      case Type::kRect: {
        const Rect& r = rects_[ref.index];
        const double facing = r.normal.dot(direction);
        if (std::abs(facing) < 1e-12) {
          break;
        }
        const double t = (r.d - r.normal.dot(origin)) / facing;
        if (t <= kMinRangeM || t >= best) {
          break;
        }
        const Vec3 q = origin + t * direction - r.p0;
        const double a = q.dot(r.u);
        const double b = q.dot(r.v);
        if (a >= 0.0 && a <= r.u_length && b >= 0.0 && b <= r.v_length) {
          take(t, r.kind, r.face);
        }
        break;
      }
      case Type::kRoof: {
        const Roof& roof = roofs_[ref.index];
        if (std::abs(direction.z()) < 1e-12) {
          break;
        }
        const double t = (roof.z_m - origin.z()) / direction.z();
        if (t <= kMinRangeM || t >= best) {
          break;
        }
        const double x = origin.x() + t * direction.x();
        const double y = origin.y() + t * direction.y();
        if (x >= roof.low.x() && x <= roof.high.x() && y >= roof.low.y() && y <= roof.high.y() &&
            inside_polygon(world_.buildings[roof.building].footprint_m, x, y)) {
          take(t, SurfaceKind::kRoof, roof.face);
        }
        break;
      }
      case Type::kCylinder: {
        const Cylinder& c = cylinders_[ref.index];
        const double dx = origin.x() - c.centre.x();
        const double dy = origin.y() - c.centre.y();
        const double a = direction.x() * direction.x() + direction.y() * direction.y();
        if (a < 1e-12) {
          break;
        }
        const double b = dx * direction.x() + dy * direction.y();
        const double cc = dx * dx + dy * dy - c.radius * c.radius;
        const double disc = b * b - a * cc;
        if (disc < 0.0) {
          break;
        }
        const double root = std::sqrt(disc);
        const double t_in = (-b - root) / a;
        const double t_out = (-b + root) / a;
        const double z_in = origin.z() + t_in * direction.z();
        if (z_in >= c.z0 && z_in <= c.z1) {
          take(t_in, c.kind, -1);
        } else if (direction.z() < 0.0 && z_in > c.z1) {  // through the top
          const double t_top = (c.z1 - origin.z()) / direction.z();
          if (t_top <= t_out) {
            take(t_top, c.kind, -1);
          }
        }
        break;
      }
      case Type::kEllipsoid: {
        const Ellipsoid& e = ellipsoids_[ref.index];
        const Vec3 o = (origin - e.centre).cwiseProduct(e.inverse_radii);
        const Vec3 d = direction.cwiseProduct(e.inverse_radii);
        const double a = d.squaredNorm();
        const double b = o.dot(d);
        const double c = o.squaredNorm() - 1.0;
        const double disc = b * b - a * c;
        if (disc < 0.0) {
          break;
        }
        const double root = std::sqrt(disc);
        const double t_in = std::max((-b - root) / a, kMinRangeM);
        const double t_out = (-b + root) / a;
        if (t_out <= t_in || t_in >= best) {
          break;
        }
        // Porous foliage: the free path is exponential with the density as its rate.
        const double free_path = -std::log(1.0 - random.uniform()) / e.density_per_m;
        if (t_in + free_path < t_out) {
          take(t_in + free_path, SurfaceKind::kFoliage, -1);
        }
        break;
      }
      case Type::kBox: {
        const Box& box = boxes_[ref.index];
        const double ox = origin.x() - box.centre.x();
        const double oy = origin.y() - box.centre.y();
        const Vec3 o(box.cos_yaw * ox + box.sin_yaw * oy, -box.sin_yaw * ox + box.cos_yaw * oy,
                     origin.z() - box.z0 - box.half.z());
        const Vec3 d(box.cos_yaw * direction.x() + box.sin_yaw * direction.y(),
                     -box.sin_yaw * direction.x() + box.cos_yaw * direction.y(), direction.z());
        double t_near = 0.0;
        double t_far = best;
        bool missed = false;
        for (int axis = 0; axis < 3 && !missed; ++axis) {
          if (std::abs(d[axis]) < 1e-12) {
            missed = std::abs(o[axis]) > box.half[axis];
            continue;
          }
          double t0 = (-box.half[axis] - o[axis]) / d[axis];
          double t1 = (box.half[axis] - o[axis]) / d[axis];
          if (t0 > t1) {
            std::swap(t0, t1);
          }
          t_near = std::max(t_near, t0);
          t_far = std::min(t_far, t1);
          missed = t_near > t_far;
        }
        if (!missed) {
          take(t_near, SurfaceKind::kCar, -1);
        }
        break;
      }
    }
  }
  const double t_ground = terrain_.intersect(origin, direction, best);
  if (t_ground <= best) {
    take(t_ground, SurfaceKind::kGround, 0);
  }
  if (hit.kind != SurfaceKind::kNone) {
    hit.range_m = best;
  }
  return hit;
}

std::size_t Scene::memory_bytes() const noexcept {
  std::size_t bytes = terrain_.memory_bytes() + rects_.capacity() * sizeof(Rect) +
                      roofs_.capacity() * sizeof(Roof) + cylinders_.capacity() * sizeof(Cylinder) +
                      ellipsoids_.capacity() * sizeof(Ellipsoid) + boxes_.capacity() * sizeof(Box) +
                      refs_.capacity() * sizeof(Ref) * 2 + bounds_.capacity() * sizeof(Aabb);
  for (const TruthFace& face : faces_) {
    bytes += sizeof(TruthFace) + face.corners_m.capacity() * sizeof(Vec3);
  }
  return bytes;
}

}  // namespace blockmap::hal::sim
