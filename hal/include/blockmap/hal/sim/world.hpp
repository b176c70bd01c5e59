// The simulated city block: what is there (ground, buildings, trees, bushes, cars, people), where
// the robot drives, and where on Earth it lies. Read from a world file (config/worlds/*.toml,
// config/README.md) by load_world(); the built-in worlds are compiled into the program.
//
// Frame: the local East-North-Up frame of the run, metres, origin at `site.origin`. Building
// footprints are counter-clockwise seen from above.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "blockmap/core/time.hpp"
#include "blockmap/hal/geodesy.hpp"

namespace blockmap::hal::sim {

using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;

enum class BuildingShape : std::uint8_t { kRect, kL, kT };
[[nodiscard]] const char* to_string(BuildingShape shape) noexcept;  // "rect", "L", "T"

// A building is a prism: its footprint extruded from the ground to a flat roof.
struct Building {
  int id = 0;
  BuildingShape shape = BuildingShape::kRect;
  std::vector<Vec2> footprint_m;  // counter-clockwise, no repeated first vertex
  double height_m = 0.0;
};

// Shape parameters of a footprint (in the building's own frame: centre at the origin, the
// length along x). Rect: length x width. L: a length x width rectangle whose +x/+y corner lacks
// a notch_length x notch_width rectangle. T: a bar of the whole length and bar_width along +y,
// and a stem of stem_width, centred on x, down to -width/2.
struct FootprintParameters {
  BuildingShape shape = BuildingShape::kRect;
  double length_m = 0.0;
  double width_m = 0.0;
  double notch_length_m = 0.0;  // L
  double notch_width_m = 0.0;   // L
  double bar_width_m = 0.0;     // T
  double stem_width_m = 0.0;    // T
};
// The footprint polygon in the world: the shape's vertices turned by `yaw_rad` and moved to
// `centre_m`. Throws std::invalid_argument for impossible dimensions.
[[nodiscard]] std::vector<Vec2> make_footprint(const FootprintParameters& parameters,
                                               const Vec2& centre_m, double yaw_rad);

struct Tree {
  Vec2 position_m = Vec2::Zero();
  double trunk_radius_m = 0.15;
  double trunk_height_m = 2.5;   // the trunk is solid up to here
  double canopy_radius_m = 2.0;  // a sphere of foliage centred above the trunk
  double canopy_centre_height_m = 4.0;
  // Foliage is porous: a beam crossing the canopy stops within a path of length s with
  // probability 1 - exp(-density * s).
  double canopy_density_per_m = 0.8;
};

struct Bush {  // an ellipsoid of foliage on the ground
  Vec2 position_m = Vec2::Zero();
  double radius_m = 0.8;
  double height_m = 1.2;
  double density_per_m = 2.0;
};

struct Car {  // a body box and a narrower cabin box on top
  Vec2 position_m = Vec2::Zero();
  double yaw_rad = 0.0;
  double length_m = 4.5;
  double width_m = 1.8;
  double height_m = 1.5;
};

struct Person {  // a cylinder walking back and forth between two points
  Vec2 from_m = Vec2::Zero();
  Vec2 to_m = Vec2::Zero();
  double speed_mps = 1.2;
  double radius_m = 0.25;
  double height_m = 1.75;
};

struct Bump {  // a smooth (cosine) bump or dip of the ground
  Vec2 position_m = Vec2::Zero();
  double radius_m = 0.3;
  double height_m = 0.05;  // negative: a dip
};

struct Kerb {  // ground raised by height_m on the left of from -> to, over width_m
  Vec2 from_m = Vec2::Zero();
  Vec2 to_m = Vec2::Zero();
  double height_m = 0.12;
  double width_m = 3.0;
};

struct Ground {
  // Random smooth unevenness: standard deviation and the length over which it changes.
  double roughness_m = 0.0;
  double roughness_wavelength_m = 1.5;
  double cell_m = 0.1;  // resolution of the height grid the simulator builds
  std::vector<Bump> bumps;
  std::vector<Kerb> kerbs;
};

struct Path {
  std::vector<Vec2> waypoints_m;  // driven in order; a loop ends where it started
  double cruise_speed_mps = 1.2;
};

struct Site {
  GeodeticPoint origin;             // the local frame's origin
  double start_unix_s = 0.0;        // UTC of the run's first instant
  double geoid_separation_m = 0.0;  // geoid above the ellipsoid here (NMEA GGA)
};

struct World {
  std::string name;
  std::string description;
  Site site;
  Ground ground;
  std::vector<Building> buildings;
  std::vector<Tree> trees;
  std::vector<Bush> bushes;
  std::vector<Car> cars;
  std::vector<Person> people;
  Path path;
};

// A world file's text -> World. Every mistake (TOML syntax, an unknown key, a missing or
// ill-typed value, an impossible dimension) throws ConfigError (hal/config/toml_reader.hpp)
// whose message names the file and the key.
[[nodiscard]] World parse_world(std::string_view toml_text, std::string_view source_name);

// The names of the worlds compiled into the program (config/worlds/*.toml).
[[nodiscard]] std::span<const std::string_view> builtin_world_names() noexcept;

// The text of a built-in world by name, or of a world file by path (anything with a '/' or
// ending in .toml); `source` is set to the name errors carry. Throws ConfigError.
[[nodiscard]] std::string world_text(std::string_view name_or_path, std::string& source);
// world_text() parsed. Throws ConfigError.
[[nodiscard]] World load_world(std::string_view name_or_path);

// Makes `world`'s path `laps` laps of its loop (a long run, for tests of bounded memory): the
// path again from its first waypoint. Empty when done, else why not (the path is no loop).
[[nodiscard]] std::string repeat_laps(World& world, int laps);

}  // namespace blockmap::hal::sim
