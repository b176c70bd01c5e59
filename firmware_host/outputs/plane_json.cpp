#include "outputs/plane_json.hpp"

#include <cmath>
#include <string>

namespace blockmap::cli {
namespace {

nlohmann::json vector_json(const Eigen::Vector3d& v, double unit) {
  return nlohmann::json::array(
      {rounded_to(v.x(), unit), rounded_to(v.y(), unit), rounded_to(v.z(), unit)});
}

const char* change_key(hal::protocol::plane_stream::Change change) {
  switch (change) {
    case hal::protocol::plane_stream::Change::kAdded:
      return "added";
    case hal::protocol::plane_stream::Change::kChanged:
      return "changed";
    case hal::protocol::plane_stream::Change::kFinalized:
      return "finalized";
    case hal::protocol::plane_stream::Change::kRemoved:
      return "removed";
  }
  return "changed";
}

}  // namespace

double rounded_to(double value, double unit) {
  // Dividing by the inverse gives the double nearest the decimal, which prints short.
  const double per_unit = std::round(1.0 / unit);
  return std::round(value * per_unit) / per_unit;
}

nlohmann::json plane_json(const msg::PlanePatch& plane, const Eigen::Vector3d& origin_m) {
  nlohmann::json polygon = nlohmann::json::array();
  for (std::size_t i = 0; i < plane.polygon_size; ++i) {
    polygon.push_back(vector_json(plane.polygon_m[i] + origin_m, 1e-4));
  }
  return {{"id", plane.id},
          {"kind", std::string(msg::to_string(plane.kind))},
          {"normal", vector_json(plane.normal, 1e-6)},
          {"d", rounded_to(plane.d_m + plane.normal.dot(origin_m), 1e-4)},
          {"support", plane.support},
          {"rmse", rounded_to(plane.rmse_m, 1e-4)},
          {"centroid", vector_json(plane.centroid_m + origin_m, 1e-4)},
          {"polygon", polygon}};
}

nlohmann::json plane_update_json(
    TimestampNs stamp_ns, std::span<const hal::protocol::plane_stream::PlaneChange> changes) {
  nlohmann::json update = {{"t_s", rounded_to(seconds_from_ns(stamp_ns), 1e-6)},
                           {"added", nlohmann::json::array()},
                           {"changed", nlohmann::json::array()},
                           {"finalized", nlohmann::json::array()},
                           {"removed", nlohmann::json::array()}};
  for (const hal::protocol::plane_stream::PlaneChange& change : changes) {
    update[change_key(change.change)].push_back(plane_json(change.plane));
  }
  return update;
}

}  // namespace blockmap::cli
