// The plane stream as JSON Lines: one object per update, with every change in its list, the
// planes in the plane list's own form (docs/formats.md, plane list and run outputs).
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "outputs/plane_json.hpp"

namespace blockmap::cli {
namespace {

using hal::protocol::plane_stream::Change;
using hal::protocol::plane_stream::PlaneChange;

msg::PlanePatch roof(std::uint32_t id) {
  msg::PlanePatch plane;
  plane.id = id;
  plane.kind = msg::PlaneKind::kRoof;
  plane.normal = Eigen::Vector3d(0.0, 0.0, 1.0);
  plane.d_m = 9.87654321;
  plane.support = 1200;
  plane.rmse_m = 0.0123456;
  plane.centroid_m = Eigen::Vector3d(1.0, 2.0, 9.87654321);
  plane.polygon_size = 3;
  plane.polygon_m[0] = Eigen::Vector3d(0.0, 0.0, 9.9);
  plane.polygon_m[1] = Eigen::Vector3d(4.0, 0.0, 9.9);
  plane.polygon_m[2] = Eigen::Vector3d(4.0, 3.0, 9.9);
  return plane;
}

TEST(PlaneJson, AnUpdateIsOneLineWithEachChangeInItsList) {
  const std::vector<PlaneChange> changes = {
      {Change::kAdded, roof(1)}, {Change::kFinalized, roof(2)}, {Change::kAdded, roof(3)}};
  const std::string line = plane_update_json(12'345'678'901, changes).dump();
  EXPECT_EQ(line.find('\n'), std::string::npos);
  const nlohmann::json update = nlohmann::json::parse(line);
  EXPECT_DOUBLE_EQ(update["t_s"].get<double>(), 12.345679);
  ASSERT_EQ(update["added"].size(), 2u);
  EXPECT_EQ(update["added"][0]["id"], 1);
  EXPECT_EQ(update["added"][1]["id"], 3);
  EXPECT_TRUE(update["changed"].empty());
  ASSERT_EQ(update["finalized"].size(), 1u);
  // The plane list's form: kind by name, numbers to what they mean.
  const nlohmann::json& plane = update["finalized"][0];
  EXPECT_EQ(plane["id"], 2);
  EXPECT_EQ(plane["kind"], "roof");
  EXPECT_DOUBLE_EQ(plane["d"].get<double>(), 9.8765);
  EXPECT_DOUBLE_EQ(plane["rmse"].get<double>(), 0.0123);
  EXPECT_EQ(plane["polygon"].size(), 3u);
  EXPECT_EQ(plane["normal"], nlohmann::json::array({0.0, 0.0, 1.0}));
}

TEST(PlaneJson, AnUpdateWithNothingInItStillHasEveryKey) {
  const nlohmann::json update = plane_update_json(0, {});
  for (const char* key : {"t_s", "added", "changed", "finalized", "removed"}) {
    EXPECT_TRUE(update.contains(key)) << key;
  }
}

}  // namespace
}  // namespace blockmap::cli
