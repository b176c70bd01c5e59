// A building of the map (seed, section IV): its footprint, the shape model it was fitted to,
// and its walls, each observed (drawn from a plane of the plane list) or virtual (estimated
// where the robot never saw a wall). The buildings JSON of docs/formats.md, buildings.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string_view>

#include <Eigen/Core>

namespace blockmap::buildings {

// The models a footprint is fitted to, in the order the paper tries them; kUnknown when the
// walls do not make a corner (nothing to complete from) or no model explains them, or for a
// block traced from free space (BlockTracer) whose outline is none of the three.
enum class BuildingShape : std::uint8_t { kRect, kL, kT, kUnknown };

[[nodiscard]] constexpr std::string_view to_string(BuildingShape shape) noexcept {
  switch (shape) {
    case BuildingShape::kRect:
      return "rect";
    case BuildingShape::kL:
      return "L";
    case BuildingShape::kT:
      return "T";
    case BuildingShape::kUnknown:
      return "unknown";
  }
  return "unknown";
}

// A T has eight corners; a traced block (BlockTracer) of four bands sixteen.
inline constexpr std::size_t kMaxFootprintVertices = 16;
// Each footprint edge can be cut into observed pieces and virtual gaps between them.
inline constexpr std::size_t kMaxBuildingWalls = 40;

struct BuildingWall {
  Eigen::Vector2d p0_m = Eigen::Vector2d::Zero();  // the footprint's order: counter-clockwise
  Eigen::Vector2d p1_m = Eigen::Vector2d::Zero();
  double z0_m = 0.0;
  double z1_m = 0.0;
  bool is_virtual = true;
  std::uint32_t plane_id = 0;  // the plane it was drawn from; 0 for a virtual wall
};

struct Building {
  std::uint32_t id = 0;
  BuildingShape shape = BuildingShape::kUnknown;
  double ground_z_m = 0.0;
  double height_m = 0.0;  // above ground_z_m: from the roof planes when seen, else the walls
  bool height_from_roof = false;
  // Share of the footprint's perimeter that was observed (0-1): how much of the building is
  // measurement rather than model.
  double confidence = 0.0;
  // Counter-clockwise; empty for kUnknown fitted from walls (its observed walls are still
  // listed), the traced outline for a traced block.
  std::array<Eigen::Vector2d, kMaxFootprintVertices> footprint_m{};
  std::uint8_t footprint_size = 0;
  std::array<BuildingWall, kMaxBuildingWalls> walls{};
  std::uint8_t wall_count = 0;
};

}  // namespace blockmap::buildings
