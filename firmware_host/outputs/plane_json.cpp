#include "outputs/plane_json.hpp"

#include <cmath>
#include <stdexcept>
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

namespace {

[[noreturn]] void fail(std::size_t index, const char* key, const char* problem) {
  throw std::invalid_argument("planes[" + std::to_string(index) + "]." + key + ": " + problem);
}

double number_at(const nlohmann::json& entry, std::size_t index, const char* key) {
  const auto it = entry.find(key);
  if (it == entry.end() || !it->is_number() || !std::isfinite(it->get<double>())) {
    fail(index, key, "must be a finite number");
  }
  return it->get<double>();
}

Eigen::Vector3d vector_at(const nlohmann::json& value, std::size_t index, const char* key) {
  if (!value.is_array() || value.size() != 3) {
    fail(index, key, "must be 3 numbers");
  }
  Eigen::Vector3d v;
  for (std::size_t k = 0; k < 3; ++k) {
    if (!value[k].is_number() || !std::isfinite(value[k].get<double>())) {
      fail(index, key, "must be 3 numbers");
    }
    v[static_cast<Eigen::Index>(k)] = value[k].get<double>();
  }
  return v;
}

msg::PlaneKind kind_at(const nlohmann::json& entry, std::size_t index) {
  const auto it = entry.find("kind");
  if (it != entry.end() && it->is_string()) {
    for (const msg::PlaneKind kind : {msg::PlaneKind::kWall, msg::PlaneKind::kRoof,
                                      msg::PlaneKind::kGround, msg::PlaneKind::kOther}) {
      if (it->get<std::string>() == msg::to_string(kind)) {
        return kind;
      }
    }
  }
  fail(index, "kind", "must be wall, roof, ground or other");
}

}  // namespace

std::vector<msg::PlanePatch> planes_from_json(const nlohmann::json& document) {
  if (!document.is_object() || !document.contains("planes") || !document["planes"].is_array()) {
    throw std::invalid_argument("not a plane list: no \"planes\" array");
  }
  std::vector<msg::PlanePatch> planes;
  const nlohmann::json& list = document["planes"];
  for (std::size_t i = 0; i < list.size(); ++i) {
    const nlohmann::json& entry = list[i];
    if (!entry.is_object()) {
      throw std::invalid_argument("planes[" + std::to_string(i) + "]: must be an object");
    }
    msg::PlanePatch plane;
    const double id = number_at(entry, i, "id");
    if (id < 0.0 || id > 4294967295.0 || id != std::floor(id)) {
      fail(i, "id", "must be a whole number >= 0");
    }
    plane.id = static_cast<std::uint32_t>(id);
    plane.kind = kind_at(entry, i);
    plane.normal =
        vector_at(entry.contains("normal") ? entry["normal"] : nlohmann::json(), i, "normal");
    if (std::abs(plane.normal.norm() - 1.0) > 1e-3) {
      fail(i, "normal", "must be a unit vector");
    }
    plane.d_m = number_at(entry, i, "d");
    plane.support = entry.contains("support") ? number_at(entry, i, "support") : 0.0;
    plane.rmse_m = entry.contains("rmse") ? number_at(entry, i, "rmse") : 0.0;
    const nlohmann::json polygon = entry.contains("polygon") ? entry["polygon"] : nlohmann::json();
    if (!polygon.is_array() || polygon.size() > msg::kMaxPolygonVertices) {
      fail(i, "polygon", "must be a list of at most 32 points");
    }
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (std::size_t k = 0; k < polygon.size(); ++k) {
      plane.polygon_m[k] = vector_at(polygon[k], i, "polygon");
      sum += plane.polygon_m[k];
    }
    plane.polygon_size = static_cast<std::uint8_t>(polygon.size());
    plane.centroid_m =
        entry.contains("centroid")
            ? vector_at(entry["centroid"], i, "centroid")
            : (polygon.empty() ? Eigen::Vector3d(plane.d_m * plane.normal)
                               : Eigen::Vector3d(sum / static_cast<double>(polygon.size())));
    planes.push_back(plane);
  }
  return planes;
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
