// The map as a VRML 2.0 world (ISO/IEC 14772), as the paper showed its maps: each plane a
// flat polygon coloured by its kind (walls grey, roofs red, ground green, other blue), and the
// robot's path as a yellow line. Buildings, when given, draw their walls instead of the wall
// planes they were made from: observed walls dark, virtual walls (estimated, never seen) light
// and half transparent, as the paper's figures 3 and 4 colour them. Any VRML viewer opens it
// (view3dscene, FreeWRL, MeshLab).
#pragma once

#include <iosfwd>
#include <span>

#include "blockmap/buildings/building.hpp"
#include "blockmap/localize/localizer.hpp"
#include "blockmap/msg/plane_patch.hpp"

namespace blockmap::cli {

void write_vrml(std::ostream& out, std::span<const msg::PlanePatch> planes,
                std::span<const localize::Pose3> path,
                std::span<const buildings::Building> buildings = {});

}  // namespace blockmap::cli
