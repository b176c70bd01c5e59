#include "commands/mapping.hpp"

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <ostream>

#include "blockmap/hal/cloud/point_cloud_file.hpp"
#include "blockmap/hal/config/mapper_config.hpp"
#include "blockmap/hal/sim/simulated_robot.hpp"

namespace blockmap::cli {
namespace {

constexpr double kMiB = 1024.0 * 1024.0;

}  // namespace

void add_udp_option(CLI::App& command, std::string& destination) {
  command
      .add_option("--udp", destination, "also send each binary plane-stream record to HOST:PORT")
      ->check(CLI::Validator(&hal::linux_backend::UdpSender::check_destination, ""));
}

pipeline::MapperConfig with_config_file(const pipeline::MapperConfig& config,
                                        const MappingOptions& options) {
  return options.config.empty() ? config : hal::config::load_mapper_config(options.config, config);
}

pipeline::MapperConfig mapper_config_for(const hal::config::RobotSpec& robot,
                                         const MappingOptions& options) {
  return with_config_file(hal::config::mapper_config_for(robot), options);
}

std::string MappingSession::start(const pipeline::MapperConfig& config,
                                  const MappingOptions& options, std::ostream& err) {
  if (std::string problem = pipeline::validate(config); !problem.empty()) {
    return problem;
  }
  const std::size_t needed = pipeline::Mapper::arena_bytes(config);
  if (needed > mib_bytes(options.budget_mib)) {
    return over_budget(needed, options.budget_mib);
  }
  arena_ = std::make_unique<Arena>(needed);
  mapper_.init(*arena_, config);
  arena_->seal();
  // The memory report: every owner's bytes, against the budget.
  char line[200];
  std::snprintf(line, sizeof line, "memory: %.1f MiB of the %.1f MiB budget, taken at start-up:",
                static_cast<double>(arena_->used_bytes()) / kMiB, options.budget_mib);
  err << line;
  for (const Arena::OwnerBytes& owner : arena_->owners()) {
    std::snprintf(line, sizeof line, " %s %.2f,", owner.owner,
                  static_cast<double>(owner.bytes) / kMiB);
    err << line;
  }
  err << " MiB\n";
  poses_.resize(config.localizer.filter.history_steps + 1);
  started_ = std::chrono::steady_clock::now();
  return {};
}

std::string MappingSession::open_outputs(const MappingOptions& options, std::ostream& out) {
  if (options.out.empty()) {
    outputs_.open_trajectory_only(out);
    return {};
  }
  if (options.trajectory_only) {
    return outputs_.open_trajectory_only(options.out);
  }
  if (options.cloud) {
    cloud_.emplace();
    mapper_.set_point_sink(&*cloud_);
  }
  return outputs_.open(options.out, mapper_.registry().change_capacity(), options.udp,
                       options.resume);
}

void MappingSession::pump() {
  while (mapper_.step()) {
    const pipeline::PlaneUpdate update = mapper_.update();
    if (output_thread_ != nullptr) {
      output_thread_->put_update(update.stamp_ns, update.changes);
      output_thread_->put_buildings(update.stamp_ns, mapper_.buildings());
    } else {
      outputs_.write_update(update.stamp_ns, update.changes);
      outputs_.write_buildings(update.stamp_ns, mapper_.buildings());
    }
  }
  const std::span<const localize::Pose3> poses(poses_.data(), mapper_.drain_final_poses(poses_));
  if (output_thread_ != nullptr) {
    output_thread_->put_poses(poses);
  } else {
    outputs_.write_poses(poses);
  }
}

std::string MappingSession::finish(const std::optional<hal::GeodeticPoint>& origin) {
  mapper_.end_of_input();
  pump();
  outputs_.write_poses(
      std::span<const localize::Pose3>(poses_.data(), mapper_.smoothed_poses(poses_)));
  wall_s_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
  std::string problem = outputs_.finish(mapper_.final_planes(), mapper_.buildings(), origin,
                                        mapper_.counters().points, wall_s_,
                                        cloud_ ? std::span<const Eigen::Vector3f>(cloud_->points())
                                               : std::span<const Eigen::Vector3f>{});
  if (problem.empty()) {
    problem = outputs_.write_map_path(mapper_.rigid_path());
  }
  if (problem.empty() && cloud_) {
    hal::cloud::write_ply(outputs_.dir() / "cloud.ply", cloud_->points());
  }
  return problem;
}

void MappingSession::report(std::ostream& err, double data_s) const {
  const double wall_s = wall_s_;
  const pipeline::MapperCounters& c = mapper_.counters();
  const map::VoxelWindowCounters& w = mapper_.window().counters();
  const map::PlaneRegistryCounters& r = mapper_.registry().counters();
  char text[768];
  std::snprintf(
      text, sizeof text,
      "mapped %.1f s of data in %.2f s (%.0fx real time): %llu scans projected, %llu points "
      "(%llu outside the window, %llu with no room; %llu far ground returns dropped); %llu "
      "extractions (%llu on kept samples; "
      "%llu of %llu sections as before, %llu of them barren still, %llu settled); planes: %llu "
      "added, %llu "
      "changes, %llu final; window peak %zu samples of %zu; %llu updates, %llu bytes of binary "
      "stream -> %s\n",
      data_s, wall_s, wall_s > 0.0 ? data_s / wall_s : 0.0,
      static_cast<unsigned long long>(c.scans_projected), static_cast<unsigned long long>(c.points),
      static_cast<unsigned long long>(w.points_outside),
      static_cast<unsigned long long>(w.points_dropped_full),
      static_cast<unsigned long long>(mapper_.far_ground_returns()),
      static_cast<unsigned long long>(c.extractions),
      static_cast<unsigned long long>(c.incremental_extractions),
      static_cast<unsigned long long>(c.sections_replayed),
      static_cast<unsigned long long>(c.sections_searched),
      static_cast<unsigned long long>(c.sections_still_barren),
      static_cast<unsigned long long>(c.sections_settled), static_cast<unsigned long long>(r.added),
      static_cast<unsigned long long>(r.changed),
      static_cast<unsigned long long>(mapper_.final_planes().size()), w.peak_samples,
      mapper_.window().capacity(), static_cast<unsigned long long>(outputs_.updates()),
      static_cast<unsigned long long>(outputs_.binary_bytes()), outputs_.dir().c_str());
  err << text;
  if (w.tiles_left_early > 0) {
    std::snprintf(text, sizeof text,
                  "window: %llu tiles beyond its core of %u left early for room, %llu points "
                  "dropped in them\n",
                  static_cast<unsigned long long>(w.tiles_left_early),
                  mapper_.window().config().core_tiles_across,
                  static_cast<unsigned long long>(w.points_in_closed_tiles));
    err << text;
  }
  const std::uint64_t lost = c.scans_refused_full + c.scans_too_many_beams + c.scans_without_pose +
                             c.messages_late + c.reorder_forced + r.refused_full +
                             r.finalized_early + r.final_dropped;
  if (lost > 0) {
    std::snprintf(
        text, sizeof text,
        "mapper: %llu scans refused (queue full), %llu with too many beams, %llu without a "
        "pose, %llu late "
        "messages, %llu forced out of the reorder buffer; registry: %llu refused, %llu "
        "finalized early, %llu final planes dropped (capacity)\n",
        static_cast<unsigned long long>(c.scans_refused_full),
        static_cast<unsigned long long>(c.scans_too_many_beams),
        static_cast<unsigned long long>(c.scans_without_pose),
        static_cast<unsigned long long>(c.messages_late),
        static_cast<unsigned long long>(c.reorder_forced),
        static_cast<unsigned long long>(r.refused_full),
        static_cast<unsigned long long>(r.finalized_early),
        static_cast<unsigned long long>(r.final_dropped));
    err << text;
  }
  if (mapper_.scan_matcher().enabled()) {
    const localize::ScanMatchCounters& m = mapper_.scan_matcher().counters();
    std::snprintf(
        text, sizeof text,
        "scan matching: %llu scans, %llu matched, %llu with too few points, %llu off "
        "the map, %llu stepping too far; %llu restarts; %llu times paused for RTK fixes\n",
        static_cast<unsigned long long>(m.scans), static_cast<unsigned long long>(m.matched),
        static_cast<unsigned long long>(m.few_points), static_cast<unsigned long long>(m.off_map),
        static_cast<unsigned long long>(m.too_far), static_cast<unsigned long long>(m.resets),
        static_cast<unsigned long long>(c.scan_matching_pauses));
    err << text;
  }
  if (mapper_.rigid_path_on()) {
    const localize::PathSmootherCounters& p = mapper_.rigid_path().counters();
    const pipeline::RigidPathCounters rigid = mapper_.rigid_path_counters();
    std::snprintf(
        text, sizeof text,
        "rigid path: %zu keyframes (%llu thinnings), %llu fixes, %zu ties between passes "
        "(full: %llu new ones dropped, %llu kept ones replaced), %llu solves; %llu final planes "
        "moved by it, %llu of them joined to a bigger one it laid them on, %llu times a plane "
        "was shown again where a solve moved it, %llu fixes dropped waiting\n",
        mapper_.rigid_path().keyframe_count(), static_cast<unsigned long long>(p.thinnings),
        static_cast<unsigned long long>(p.fixes), mapper_.rigid_path().tie_count(),
        static_cast<unsigned long long>(p.ties_dropped),
        static_cast<unsigned long long>(p.ties_replaced), static_cast<unsigned long long>(p.solves),
        static_cast<unsigned long long>(rigid.planes_moved),
        static_cast<unsigned long long>(mapper_.registry().counters().finals_joined),
        static_cast<unsigned long long>(mapper_.registry().counters().view_moved),
        static_cast<unsigned long long>(rigid.fixes_dropped));
    err << text;
    const localize::LoopCloser& closer = mapper_.loop_closer();
    if (closer.enabled()) {
      const localize::LoopClosureCounters& l = closer.counters();
      std::snprintf(
          text, sizeof text,
          "loop closing: %llu submaps (%zu kept, %llu thinnings), %llu matched against "
          "an earlier one, %llu closures (%llu by the wider search; %llu with too few cells on "
          "it, %llu leaving the window), %zu in the path (%llu dropped when full)\n",
          static_cast<unsigned long long>(l.submaps), closer.submap_count(),
          static_cast<unsigned long long>(l.thinnings), static_cast<unsigned long long>(l.searches),
          static_cast<unsigned long long>(l.closures),
          static_cast<unsigned long long>(l.wide_closures),
          static_cast<unsigned long long>(l.low_score),
          static_cast<unsigned long long>(l.off_window), mapper_.rigid_path().closure_count(),
          static_cast<unsigned long long>(p.closures_dropped));
      err << text;
    }
    const localize::MapLocalizer& on_map = mapper_.map_localizer();
    if (on_map.ready()) {
      const localize::MapLocalizerCounters& m = on_map.counters();
      const pipeline::RigidPathCounters guards = mapper_.rigid_path_counters();
      std::snprintf(text, sizeof text,
                    "prior map: %zu walls, %llu scans weighed, %llu placings (%llu refused as "
                    "far from the path; not given: %llu updates with the particles apart, %llu "
                    "with the returns off its walls, %llu whose walls pinned nothing), %llu "
                    "resamplings, %llu restarts\n",
                    on_map.map().wall_count(), static_cast<unsigned long long>(m.updates),
                    static_cast<unsigned long long>(m.placings),
                    static_cast<unsigned long long>(guards.placings_refused),
                    static_cast<unsigned long long>(m.spread_too_wide),
                    static_cast<unsigned long long>(m.off_the_map),
                    static_cast<unsigned long long>(m.unpinned),
                    static_cast<unsigned long long>(m.resamplings),
                    static_cast<unsigned long long>(guards.map_restarts));
      err << text;
    }
  }
  // Each capacity against the most it held, for sizing a robot's config (config/README.md).
  const planes::PlanesConfig& detector = mapper_.detector().config();
  std::snprintf(text, sizeof text,
                "capacities, most used of: section planes %zu of %zu ([planes] max_patches), "
                "planes of an extraction %zu of %zu (max_planes), detector blocks %zu of %zu; "
                "live planes %zu of %zu, changes of an update %zu of %zu, final planes %zu of "
                "%zu\n",
                c.peak_section_planes, detector.max_patches, c.peak_detected_planes,
                detector.max_planes, c.peak_blocks, planes::block_capacity(detector), r.peak_live,
                mapper_.registry().live_capacity(), r.peak_changes,
                mapper_.registry().change_capacity(), mapper_.final_planes().size(),
                mapper_.registry().final_capacity());
  err << text;
  if (c.peak_samples_without_room > 0) {
    std::snprintf(text, sizeof text,
                  "mapper: the detector had no room for up to %zu of the window's samples at "
                  "once (its %zu blocks full: [planes] max_blocks)\n",
                  c.peak_samples_without_room, planes::block_capacity(mapper_.detector().config()));
    err << text;
  }
}

}  // namespace blockmap::cli
