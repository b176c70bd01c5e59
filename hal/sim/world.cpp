// World files (config/worlds/*.toml) -> World. The keys are listed in config/README.md.
#include "blockmap/hal/sim/world.hpp"
#include "blockmap/core/angles.hpp"

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include "../config/toml_reader.hpp"
#include "builtin_worlds.hpp"

namespace blockmap::hal::sim {
namespace {

using config::TableReader;

std::vector<Vec2> shape_vertices(const FootprintParameters& p) {
  const double hl = p.length_m / 2.0;
  const double hw = p.width_m / 2.0;
  switch (p.shape) {
    case BuildingShape::kRect:
      return {{-hl, -hw}, {hl, -hw}, {hl, hw}, {-hl, hw}};
    case BuildingShape::kL:
      return {{-hl, -hw},
              {hl, -hw},
              {hl, hw - p.notch_width_m},
              {hl - p.notch_length_m, hw - p.notch_width_m},
              {hl - p.notch_length_m, hw},
              {-hl, hw}};
    case BuildingShape::kT: {
      const double hs = p.stem_width_m / 2.0;
      const double bar_y = hw - p.bar_width_m;
      return {{-hs, -hw}, {hs, -hw}, {hs, bar_y},  {hl, bar_y},
              {hl, hw},   {-hl, hw}, {-hl, bar_y}, {-hs, bar_y}};
    }
  }
  return {};
}

void check_footprint_parameters(const FootprintParameters& p) {
  if (!(p.length_m > 0.0 && p.width_m > 0.0)) {
    throw std::invalid_argument("length_m and width_m must be > 0");
  }
  if (p.shape == BuildingShape::kL && !(p.notch_length_m > 0.0 && p.notch_length_m < p.length_m &&
                                        p.notch_width_m > 0.0 && p.notch_width_m < p.width_m)) {
    throw std::invalid_argument(
        "an L needs 0 < notch_length_m < length_m and "
        "0 < notch_width_m < width_m");
  }
  if (p.shape == BuildingShape::kT && !(p.bar_width_m > 0.0 && p.bar_width_m < p.width_m &&
                                        p.stem_width_m > 0.0 && p.stem_width_m < p.length_m)) {
    throw std::invalid_argument(
        "a T needs 0 < bar_width_m < width_m and "
        "0 < stem_width_m < length_m");
  }
}

BuildingShape parse_shape(TableReader& table) {
  const std::string name = table.string("shape");
  if (name == "rect") {
    return BuildingShape::kRect;
  }
  if (name == "L") {
    return BuildingShape::kL;
  }
  if (name == "T") {
    return BuildingShape::kT;
  }
  table.fail("shape", R"(expected "rect", "L" or "T", not ")" + name + "\"");
}

Building parse_building(TableReader& table, int default_id) {
  Building building;
  building.id = static_cast<int>(table.integer_or("id", default_id));
  FootprintParameters p;
  p.shape = parse_shape(table);
  building.shape = p.shape;
  p.length_m = table.positive("length_m", table.number("length_m"));
  p.width_m = table.positive("width_m", table.number("width_m"));
  if (p.shape == BuildingShape::kL) {
    p.notch_length_m = table.number("notch_length_m");
    p.notch_width_m = table.number("notch_width_m");
  } else if (p.shape == BuildingShape::kT) {
    p.bar_width_m = table.number("bar_width_m");
    p.stem_width_m = table.number("stem_width_m");
  }
  const Vec2 centre = table.vec2("centre_m");
  const double yaw_rad = table.number_or("yaw_deg", 0.0) * kRadiansPerDegree;
  building.height_m = table.positive("height_m", table.number("height_m"));
  try {
    building.footprint_m = make_footprint(p, centre, yaw_rad);
  } catch (const std::invalid_argument& error) {
    table.fail("shape", error.what());
  }
  table.finish();
  return building;
}

Tree parse_tree_parameters(TableReader& table) {
  Tree tree;
  tree.trunk_radius_m = table.positive_or("trunk_radius_m", tree.trunk_radius_m);
  tree.trunk_height_m = table.positive_or("trunk_height_m", tree.trunk_height_m);
  tree.canopy_radius_m = table.non_negative_or("canopy_radius_m", tree.canopy_radius_m);
  tree.canopy_centre_height_m =
      table.positive_or("canopy_centre_height_m", tree.canopy_centre_height_m);
  tree.canopy_density_per_m =
      table.non_negative_or("canopy_density_per_m", tree.canopy_density_per_m);
  return tree;
}

Bush parse_bush_parameters(TableReader& table) {
  Bush bush;
  bush.radius_m = table.positive_or("radius_m", bush.radius_m);
  bush.height_m = table.positive_or("height_m", bush.height_m);
  bush.density_per_m = table.non_negative_or("density_per_m", bush.density_per_m);
  return bush;
}

Car parse_car_parameters(TableReader& table) {
  Car car;
  car.yaw_rad = table.number_or("yaw_deg", 0.0) * kRadiansPerDegree;
  car.length_m = table.positive_or("length_m", car.length_m);
  car.width_m = table.positive_or("width_m", car.width_m);
  car.height_m = table.positive_or("height_m", car.height_m);
  return car;
}

// Evenly spaced copies along a line: `count` items from `from_m` to `to_m` inclusive.
template <typename Item, typename ParseParameters>
void parse_rows(TableReader& world, std::string_view key, ParseParameters parse_parameters,
                std::vector<Item>& out) {
  for (TableReader& row : world.tables(key)) {
    Item item = parse_parameters(row);
    const Vec2 from = row.vec2("from_m");
    const Vec2 to = row.vec2("to_m");
    const std::int64_t count = row.integer("count");
    if (count < 1 || count > 10000) {
      row.fail("count", "must lie in [1, 10000]");
    }
    for (std::int64_t i = 0; i < count; ++i) {
      const double s = count == 1 ? 0.0 : static_cast<double>(i) / static_cast<double>(count - 1);
      item.position_m = from + s * (to - from);
      out.push_back(item);
    }
    row.finish();
  }
}

template <typename Item, typename ParseParameters>
void parse_singles(TableReader& world, std::string_view key, ParseParameters parse_parameters,
                   std::vector<Item>& out) {
  for (TableReader& table : world.tables(key)) {
    Item item = parse_parameters(table);
    item.position_m = table.vec2("position_m");
    out.push_back(item);
    table.finish();
  }
}

Site parse_site(TableReader& world) {
  std::optional<TableReader> table = world.table("site");
  if (!table) {
    world.fail("site", "missing (latitude_deg, longitude_deg, height_m, start_utc)");
  }
  Site site;
  site.origin.latitude_deg =
      table->in_range("latitude_deg", table->number("latitude_deg"), -89.0, 89.0);
  site.origin.longitude_deg =
      table->in_range("longitude_deg", table->number("longitude_deg"), -180.0, 180.0);
  site.origin.height_m = table->number_or("height_m", 0.0);
  site.geoid_separation_m = table->number_or("geoid_separation_m", 0.0);
  site.start_unix_s = table->unix_time("start_utc");
  table->finish();
  return site;
}

Ground parse_ground(TableReader& world) {
  Ground ground;
  std::optional<TableReader> table = world.table("ground");
  if (!table) {
    return ground;
  }
  ground.roughness_m = table->non_negative_or("roughness_m", 0.0);
  ground.roughness_wavelength_m =
      table->positive_or("roughness_wavelength_m", ground.roughness_wavelength_m);
  ground.cell_m = table->in_range("cell_m", table->number_or("cell_m", ground.cell_m), 0.02, 1.0);
  for (TableReader& bump : table->tables("bumps")) {
    Bump b;
    b.position_m = bump.vec2("position_m");
    b.radius_m = bump.positive("radius_m", bump.number("radius_m"));
    b.height_m = bump.number("height_m");
    ground.bumps.push_back(b);
    bump.finish();
  }
  for (TableReader& kerb : table->tables("kerbs")) {
    Kerb k;
    k.from_m = kerb.vec2("from_m");
    k.to_m = kerb.vec2("to_m");
    if ((k.to_m - k.from_m).norm() < 0.1) {
      kerb.fail("to_m", "must be at least 0.1 m from from_m");
    }
    k.height_m = kerb.number("height_m");
    k.width_m = kerb.positive_or("width_m", k.width_m);
    ground.kerbs.push_back(k);
    kerb.finish();
  }
  table->finish();
  return ground;
}

Path parse_path(TableReader& world) {
  std::optional<TableReader> table = world.table("path");
  if (!table) {
    world.fail("path", "missing (waypoints_m, cruise_speed_mps)");
  }
  Path path;
  path.waypoints_m = table->vec2_list("waypoints_m");
  if (path.waypoints_m.size() < 2) {
    table->fail("waypoints_m", "needs at least two waypoints");
  }
  for (std::size_t i = 1; i < path.waypoints_m.size(); ++i) {
    if ((path.waypoints_m[i] - path.waypoints_m[i - 1]).norm() < 0.5) {
      table->fail("waypoints_m", "waypoints " + std::to_string(i - 1) + " and " +
                                     std::to_string(i) + " are less than 0.5 m apart");
    }
  }
  if (table->boolean_or("loop", false)) {
    path.waypoints_m.push_back(path.waypoints_m.front());
  }
  path.cruise_speed_mps =
      table->in_range("cruise_speed_mps", table->number("cruise_speed_mps"), 0.1, 10.0);
  table->finish();
  return path;
}

}  // namespace

const char* to_string(BuildingShape shape) noexcept {
  switch (shape) {
    case BuildingShape::kRect:
      return "rect";
    case BuildingShape::kL:
      return "L";
    case BuildingShape::kT:
      return "T";
  }
  return "unknown";
}

std::vector<Vec2> make_footprint(const FootprintParameters& parameters, const Vec2& centre_m,
                                 double yaw_rad) {
  check_footprint_parameters(parameters);
  std::vector<Vec2> vertices = shape_vertices(parameters);
  const Eigen::Rotation2Dd rotation(yaw_rad);
  for (Vec2& vertex : vertices) {
    vertex = centre_m + rotation * vertex;
  }
  return vertices;
}

World parse_world(std::string_view toml_text, std::string_view source_name) {
  const toml::table document = config::parse_document(toml_text, source_name);
  TableReader root(document, std::string(source_name), "");
  World world;
  world.name = root.string("name");
  world.description = root.string_or("description", "");
  world.site = parse_site(root);
  world.ground = parse_ground(root);
  int next_id = 1;
  for (TableReader& table : root.tables("buildings")) {
    world.buildings.push_back(parse_building(table, next_id));
    next_id = world.buildings.back().id + 1;
  }
  for (std::size_t i = 0; i < world.buildings.size(); ++i) {
    for (std::size_t j = 0; j < i; ++j) {
      if (world.buildings[i].id == world.buildings[j].id) {
        root.fail("buildings[" + std::to_string(i) + "].id",
                  "id " + std::to_string(world.buildings[i].id) + " is used twice");
      }
    }
  }
  parse_singles(root, "trees", parse_tree_parameters, world.trees);
  parse_rows(root, "tree_rows", parse_tree_parameters, world.trees);
  parse_singles(root, "bushes", parse_bush_parameters, world.bushes);
  parse_rows(root, "bush_rows", parse_bush_parameters, world.bushes);
  parse_singles(root, "cars", parse_car_parameters, world.cars);
  parse_rows(root, "car_rows", parse_car_parameters, world.cars);
  for (TableReader& table : root.tables("people")) {
    Person person;
    person.from_m = table.vec2("from_m");
    person.to_m = table.vec2("to_m");
    person.speed_mps =
        table.in_range("speed_mps", table.number_or("speed_mps", person.speed_mps), 0.0, 5.0);
    person.radius_m = table.positive_or("radius_m", person.radius_m);
    person.height_m = table.positive_or("height_m", person.height_m);
    world.people.push_back(person);
    table.finish();
  }
  world.path = parse_path(root);
  root.finish();
  return world;
}

std::span<const std::string_view> builtin_world_names() noexcept {
  return kBuiltinWorldNames;
}

std::string world_text(std::string_view name_or_path, std::string& source) {
  return config::builtin_or_file_text(kBuiltinWorldNames, kBuiltinWorldTexts, name_or_path, "world",
                                      source);
}

std::string repeat_laps(World& world, int laps) {
  if (laps <= 1) {
    return {};
  }
  std::vector<Vec2>& waypoints = world.path.waypoints_m;
  if (waypoints.empty() || (waypoints.front() - waypoints.back()).norm() > 1e-9) {
    return "--laps needs a world whose path is a loop";
  }
  const std::vector<Vec2> lap(waypoints.begin() + 1, waypoints.end());
  for (int i = 1; i < laps; ++i) {
    waypoints.insert(waypoints.end(), lap.begin(), lap.end());
  }
  return {};
}

World load_world(std::string_view name_or_path) {
  std::string source;
  const std::string text = world_text(name_or_path, source);
  return parse_world(text, source);
}

}  // namespace blockmap::hal::sim
