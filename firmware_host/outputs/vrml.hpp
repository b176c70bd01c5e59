// The map as a VRML 2.0 world (ISO/IEC 14772), as the paper showed its maps: each plane a
// flat polygon coloured by its kind (walls grey, roofs red, ground green, other blue), and the
// robot's path as a yellow line. Any VRML viewer opens it (view3dscene, FreeWRL, MeshLab).
#pragma once

#include <iosfwd>
#include <span>

#include "blockmap/localize/localizer.hpp"
#include "blockmap/msg/plane_patch.hpp"

namespace blockmap::cli {

void write_vrml(std::ostream& out, std::span<const msg::PlanePatch> planes,
                std::span<const localize::Pose3> path);

}  // namespace blockmap::cli
