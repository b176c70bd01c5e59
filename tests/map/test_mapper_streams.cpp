// The mapper's stream over the simulated robot: the same run gives the same bytes however it
// is fed or extracted, and what a consumer of the stream holds is the final plane list.
#include <gtest/gtest.h>

#include <random>

#include "long_test.hpp"
#include "mapper_runs.hpp"
#include "recorded_mapper_inputs.hpp"

namespace blockmap::pipeline {
namespace {

// The same run twice gives the same bytes. And the detector keeps the window's samples, their
// shapes and its sections' results: it takes only the samples that gained points, lets go of
// those whose tile left, and replays every section whose inputs are as they were. What it
// keeps is what it would find again, so with sections searched again at every change
// (barren_section_growth and settled_section_growth 0) the stream is also the same, byte for byte,
// as with every window detected afresh (incremental_extraction off).
TEST(MapperSim, TheSameRunGivesTheSameStreamWithOrWithoutKeptShapes) {
  BLOCKMAP_LONG_TEST();
  const MapperRun a = map_world(
      {.world = "usc_block", .duration_s = kDeterminismDurationS, .window = &kDeterminismWindow});
  const MapperRun b = map_world(
      {.world = "usc_block", .duration_s = kDeterminismDurationS, .window = &kDeterminismWindow});
  ASSERT_EQ(a.stream.size(), b.stream.size());
  EXPECT_GT(a.stream.size(), 0u);
  EXPECT_TRUE(a.stream == b.stream) << "the plane stream's bytes differ";
  EXPECT_GT(a.counters.sections_still_barren, 0u) << "the default lets barren sections wait";
  EXPECT_GT(a.counters.sections_settled, 0u) << "... and sections that gave planes";

  const MapperRun exact = map_world({.world = "usc_block",
                                     .duration_s = kDeterminismDurationS,
                                     .sections_wait = false,
                                     .window = &kDeterminismWindow});
  const MapperRun afresh = map_world({.world = "usc_block",
                                      .duration_s = kDeterminismDurationS,
                                      .incremental_extraction = false,
                                      .window = &kDeterminismWindow});
  EXPECT_EQ(exact.counters.incremental_extractions, exact.counters.extractions - 1)
      << "all but the first";
  EXPECT_GT(exact.tiles_evicted, 0u);
  // A quarter or more: the map is drawn in the scan matcher's frame, turned as the filter's
  // first heading was (105 degrees on this run), and a street across the sections' axes
  // touches more of them a second than one along them (31 % here; 91 % on the benning replay).
  EXPECT_GT(exact.counters.sections_replayed, exact.counters.sections_searched / 4);
  EXPECT_EQ(exact.counters.sections_still_barren, 0u);
  EXPECT_EQ(exact.counters.sections_settled, 0u);
  EXPECT_EQ(afresh.counters.incremental_extractions, 0u);
  EXPECT_EQ(afresh.counters.sections_replayed, 0u);
  ASSERT_EQ(exact.stream.size(), afresh.stream.size());
  EXPECT_TRUE(exact.stream == afresh.stream) << "the kept shapes changed the stream";
}

// The same messages in the same order give the same stream however they were batched between
// two steps: one message a step (blockmap replay), or whatever arrived since the last step (the
// daemon's pipeline thread, whose batches grow when it falls behind).
TEST(MapperSim, TheSameMessagesBatchedAnyWayGiveTheSameStream) {
  BLOCKMAP_LONG_TEST();
  testing::RecordedMapperInputs inputs("usc_block", kDeterminismDurationS + 40.0);
  ASSERT_TRUE(inputs.started);
  // In time order, as blockmap replay and the daemon's replay source hand them over.
  using Event = testing::RecordedMapperInputs::Event;
  const auto stamp_of = [&](const Event& e) -> TimestampNs {
    switch (e.kind) {
      case Event::kBase:
        return inputs.bases[e.index].first.header.stamp_ns;
      case Event::kFix:
        return inputs.fixes[e.index].first.stamp_ns;
      case Event::kPose:
        return inputs.poses[e.index].stamp_ns;
      case Event::kScan:
        return inputs.scans[e.index].second->header.stamp_ns;
    }
    return 0;
  };
  std::stable_sort(inputs.events.begin(), inputs.events.end(),
                   [&](const Event& a, const Event& b) { return stamp_of(a) < stamp_of(b); });
  // A scan queue of 64 (128 by default): the scans from before the filter's first pose (35
  // here) and those waiting out the reorder window would overflow it if the first ones
  // waited for the first pose to be dropped, and how far would depend on the batches.
  MapperConfig config = inputs.config;
  config.scan_queue_capacity = 64;
  const auto stream_of = [&](std::uint32_t seed) {
    Arena arena(Mapper::arena_bytes(config));
    auto mapper = std::make_unique<Mapper>();
    mapper->init(arena, config);
    std::vector<std::uint8_t> stream;
    const auto drain = [&] {
      while (mapper->step()) {
        static_cast<void>(append_encoded(stream, mapper->update()));
      }
    };
    // Batches of up to 20 messages, 0.1 s (the daemon's batches grow to what its queues from
    // the devices hold, about 0.4 s, which the default queue takes).
    std::mt19937 random(seed);
    std::uniform_int_distribution<int> batch(1, 20);
    int left = seed == 0 ? 1 : batch(random);
    inputs.feed(*mapper, [&](bool) {
      if (--left > 0) {
        return;  // the batch goes on: no step
      }
      left = seed == 0 ? 1 : batch(random);
      drain();
    });
    drain();  // what the end of the input left
    EXPECT_EQ(mapper->counters().scans_refused_full, 0u) << "batches of seed " << seed;
    // The rigid path's view was refreshed: its updates are in the stream compared.
    EXPECT_GT(mapper->registry().counters().view_moved, 0u) << "batches of seed " << seed;
    return stream;
  };
  const std::vector<std::uint8_t> one_by_one = stream_of(0);
  EXPECT_GT(one_by_one.size(), 0u);
  for (std::uint32_t seed = 1; seed <= 6; ++seed) {
    EXPECT_TRUE(stream_of(seed) == one_by_one) << "batches of seed " << seed;
  }
}

// With the rigid path the stream shows each plane where the latest solve puts it, so what a
// consumer holds as the run goes is the final map, not the map drawn with the poses of the
// moment that the end moves by a metre or two; the final list is the same, bit for bit.
TEST(MapperSim, TheStreamShowsTheRigidMapAsTheRunGoes) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive usc_block with the rigid path";
#endif
  const MapperRun shown = map_world({.world = "usc_block", .rigid_path = RigidPath::kOn});
  const MapperRun drawn =
      map_world({.world = "usc_block", .rigid_path = RigidPath::kOn, .rigid_view = false});
  for (const double fraction : {0.5, 0.75}) {
    std::printf("after %.0f %% of the updates: %.3f m off the final list as shown, %.3f m drawn\n",
                100.0 * fraction, stream_off_final_m(shown, fraction),
                stream_off_final_m(drawn, fraction));
  }
  // Before the end's updates: its last solve (with the last metres' loop closures), the move
  // of every final plane, and the joins of those it lays on one surface.
  const double shown_end_m = stream_off_final_after_m(shown, shown.updates_before_end);
  const double drawn_end_m = stream_off_final_after_m(drawn, drawn.updates_before_end);
  std::printf("before the end's updates: %.3f m off the final list as shown, %.3f m drawn\n",
              shown_end_m, drawn_end_m);
  std::printf(
      "%zu updates, %zu bytes shown; %zu updates, %zu bytes drawn; %llu planes moved by "
      "the view\n",
      shown.updates, shown.stream.size(), drawn.updates, drawn.stream.size(),
      static_cast<unsigned long long>(shown.registry.view_moved));
  EXPECT_GT(drawn_end_m, 0.5) << "the end's move is the receiver's error";
  EXPECT_LT(shown_end_m, 0.25 * drawn_end_m);
  EXPECT_LT(stream_off_final_m(shown, 0.75), 0.5 * stream_off_final_m(drawn, 0.75));
  EXPECT_GT(shown.registry.view_moved, 0u);
  EXPECT_EQ(drawn.registry.view_moved, 0u);
  expect_stream_gives_final_list(shown);
  expect_stream_gives_final_list(drawn);
  ASSERT_EQ(shown.final_planes.size(), drawn.final_planes.size());
  for (std::size_t i = 0; i < shown.final_planes.size(); ++i) {
    EXPECT_EQ(shown.final_planes[i].id, drawn.final_planes[i].id);
    EXPECT_EQ(shown.final_planes[i].d_m, drawn.final_planes[i].d_m);
    EXPECT_EQ(shown.final_planes[i].centroid_m, drawn.final_planes[i].centroid_m);
  }
}

// A final list too small for the block (8 of its 39 planes): each plane it leaves out, the
// new one or a smaller one it held, the stream reports removed, through the view's refreshes
// and the end's move, so a consumer still holds exactly the final list.
TEST(MapperSim, AFullFinalListKeepsTheStreamAndTheListOneMap) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive usc_block with the rigid path";
#endif
  constexpr std::size_t kFinalPlanes = 8;
  const MapperRun run = map_world(
      {.world = "usc_block", .rigid_path = RigidPath::kOn, .max_final_planes = kFinalPlanes});
  std::printf("%llu final planes dropped for %zu kept; %llu shown again by the view\n",
              static_cast<unsigned long long>(run.registry.final_dropped), run.final_planes.size(),
              static_cast<unsigned long long>(run.registry.view_moved));
  // Full, less those the end's move laid on a bigger one's surface and joined to it.
  EXPECT_EQ(run.final_planes.size() + run.registry.finals_joined, kFinalPlanes);
  EXPECT_GT(run.registry.final_dropped, 20u);
  EXPECT_GT(run.registry.view_moved, 0u);
  expect_stream_gives_final_list(run);
  // The biggest planes are the ones kept: the block's four walls among them.
  std::size_t walls = 0;
  for (const msg::PlanePatch& plane : run.final_planes) {
    walls += plane.kind == msg::PlaneKind::kWall && plane.support > 1000.0 ? 1U : 0U;
  }
  EXPECT_GE(walls, 4u);
}

}  // namespace
}  // namespace blockmap::pipeline
