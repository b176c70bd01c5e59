// PlaneRegistry's final list: the planes that left the window, kept (the biggest when full),
// saved for snapshots and restored, and moved where the rigid path's view puts them.
#include <algorithm>
#include <array>
#include <utility>

#include "blockmap/map/plane_registry.hpp"
#include "plane_extent.hpp"

namespace blockmap::map {

void PlaneRegistry::remove_final(std::size_t index) noexcept {
  --final_count_;
  final_[index] = final_[final_count_];
  final_moments_[index] = final_moments_[final_count_];
  final_seen_[index] = final_seen_[final_count_];
  final_shown_[index] = final_shown_[final_count_];
}

bool PlaneRegistry::store_final(const msg::PlanePatch& plane, const planes::PointMoments& moments,
                                const SeenSpans& seen, const PlaneMove& shown) noexcept {
  if (final_count_ < final_.size()) {
    put_final(final_count_++, plane, moments, seen, shown);
    return true;
  }
  ++counters_.final_dropped;
  const std::size_t smallest = smallest_final();
  if (!(final_[smallest].support < plane.support) || !take_extra_change()) {
    return false;
  }
  emit(msg::PlaneChangeKind::kRemoved, final_[smallest], final_shown_[smallest]);
  put_final(smallest, plane, moments, seen, shown);
  return true;
}

std::size_t PlaneRegistry::smallest_final() const noexcept {
  return static_cast<std::size_t>(
      std::min_element(final_.begin(), final_.begin() + static_cast<std::ptrdiff_t>(final_count_),
                       [](const msg::PlanePatch& a, const msg::PlanePatch& b) {
                         return a.support < b.support;
                       }) -
      final_.begin());
}

void PlaneRegistry::put_final(std::size_t index, const msg::PlanePatch& plane,
                              const planes::PointMoments& moments, const SeenSpans& seen,
                              const PlaneMove& shown) noexcept {
  final_[index] = plane;
  final_moments_[index] = moments;
  final_seen_[index] = seen;
  final_shown_[index] = shown;
}

bool PlaneRegistry::shown_off(const msg::PlanePatch& plane, const PlaneMove& shown,
                              const PlaneMove& now) const noexcept {
  const Eigen::Matrix3d shown_rotation = shown.rotation();
  const Eigen::Matrix3d now_rotation = now.rotation();
  const auto off_m = [&](const Eigen::Vector3d& p) {
    return ((shown_rotation * p + shown.shift_m) - (now_rotation * p + now.shift_m)).norm();
  };
  if (plane.polygon_size == 0) {
    return off_m(plane.centroid_m) > view_change_m_;
  }
  return std::any_of(plane.polygon_m.begin(), plane.polygon_m.begin() + plane.polygon_size,
                     [&](const Eigen::Vector3d& vertex) { return off_m(vertex) > view_change_m_; });
}

std::size_t PlaneRegistry::save(std::span<SavedPlane> out) noexcept {
  std::size_t count = 0;
  const auto keep = [&](const msg::PlanePatch& plane, const planes::PointMoments& moments) {
    if (count < out.size()) {
      out[count++] = SavedPlane{plane, moments};
      return;
    }
    // Full: the smallest saved plane makes room for a bigger one (as store_final does).
    const auto smallest = std::min_element(
        out.begin(), out.end(),
        [](const SavedPlane& a, const SavedPlane& b) { return a.plane.support < b.plane.support; });
    if (smallest != out.end() && smallest->plane.support < plane.support) {
      *smallest = SavedPlane{plane, moments};
    }
  };
  // Where the stream shows them: a consumer that holds the stream holds these, and the
  // run that resumes from them leaves them there (a plane without seen spans is not moved).
  const auto keep_shown = [&](msg::PlanePatch plane, const planes::PointMoments& moments,
                              const PlaneMove& shown) {
    if (shown.is_identity()) {
      keep(plane, moments);
      return;
    }
    move_plane(plane, shown);
    keep(plane, moments.moved(shown.rotation(), shown.shift_m));
  };
  for (std::size_t i = 0; i < final_count_; ++i) {
    keep_shown(final_[i], final_moments_[i], final_shown_[i]);
  }
  for (const LivePlane& plane : live_) {
    if (plane.in_use && plane.reported.id != 0) {
      msg::PlanePatch now = plane.reported;
      combine(plane, now);
      keep_shown(now, points_of(plane), plane.shown);
    }
  }
  return count;
}

void PlaneRegistry::restore(std::span<const SavedPlane> planes) noexcept {
  for (const SavedPlane& saved : planes) {
    // Before any update: nothing to report in. A full list keeps the biggest (counted); the
    // run before reported the planes left out, and this run's stream does not remove them.
    if (final_count_ < final_.size()) {
      put_final(final_count_++, saved.plane, saved.moments, SeenSpans{}, PlaneMove{});
    } else if (const std::size_t smallest = smallest_final();
               final_[smallest].support < saved.plane.support) {
      ++counters_.final_dropped;
      put_final(smallest, saved.plane, saved.moments, SeenSpans{}, PlaneMove{});
    } else {
      ++counters_.final_dropped;
    }
    next_id_ = std::max(next_id_, saved.plane.id + 1);
  }
}

void move_plane(msg::PlanePatch& plane, const PlaneMove& move) noexcept {
  const Eigen::Matrix3d rotation = move.rotation();
  plane.normal = rotation * plane.normal;
  plane.d_m += plane.normal.dot(move.shift_m);  // n'.(R x + t) = n.x + n'.t
  plane.centroid_m = rotation * plane.centroid_m + move.shift_m;
  for (std::size_t v = 0; v < plane.polygon_size; ++v) {
    plane.polygon_m[v] = rotation * plane.polygon_m[v] + move.shift_m;
  }
}

void PlaneRegistry::move_final(std::size_t index, const PlaneMove& move) noexcept {
  BLOCKMAP_CHECK(index < final_count_);
  // The same arithmetic as the view's copy (emit()): a plane the stream shows moved by
  // `move` is, bit for bit, where it now lies, and need not be reported again.
  const bool shown_there = final_shown_[index] == move;
  move_plane(final_[index], move);
  final_moments_[index] = final_moments_[index].moved(move.rotation(), move.shift_m);
  final_shown_[index] = PlaneMove{};
  if (!shown_there) {
    emit(msg::PlaneChangeKind::kFinalized, final_[index], PlaneMove{});
  }
}

std::size_t PlaneRegistry::move_finals_by(const PlaneView& view) noexcept {
  // A live plane would keep the move it was shown with after the view is off.
  BLOCKMAP_CHECK_MSG(live_count_ == 0, "move_finals_by() before finalize_all()");
  std::size_t moved = 0;
  for (std::size_t i = 0; i < final_count_; ++i) {
    const PlaneMove move = view.move_of(final_[i], final_seen_[i]);
    if (!move.is_identity()) {
      move_final(i, move);
      ++moved;
    } else if (!final_shown_[i].is_identity()) {
      final_shown_[i] = PlaneMove{};  // the view showed it moved, and it stays as drawn
      emit(msg::PlaneChangeKind::kFinalized, final_[i], PlaneMove{});
    }
  }
  view_ = nullptr;
  return moved;
}

bool PlaneRegistry::join_finals_on_one_surface(std::size_t max_changes) noexcept {
  const std::size_t limit = std::min(max_changes, changes_.size());
  // A joined plane has grown, and may now meet one it did not: passes until one joins none.
  for (bool joined = true; joined;) {
    joined = false;
    for (std::size_t i = 0; i < final_count_; ++i) {
      Eigen::AlignedBox3d box_i = box_of(polygon_of(final_[i]));
      for (std::size_t j = i + 1; j < final_count_;) {
        if (!matches(final_[i], box_i, final_[j], box_of(polygon_of(final_[j])),
                     config_.match_distance_m)) {
          ++j;
          continue;
        }
        if (change_count_ + 2 > limit) {
          return false;
        }
        // The bigger one keeps its id; remove_final() moves the last plane into j's slot.
        if (final_[j].support > final_[i].support) {
          std::swap(final_[i], final_[j]);
          std::swap(final_moments_[i], final_moments_[j]);
          std::swap(final_seen_[i], final_seen_[j]);
          std::swap(final_shown_[i], final_shown_[j]);
        }
        join_final(i, j);
        ++counters_.finals_joined;
        joined = true;
        box_i = box_of(polygon_of(final_[i]));
      }
    }
  }
  return true;
}

void PlaneRegistry::join_final(std::size_t into, std::size_t from) noexcept {
  msg::PlanePatch& plane = final_[into];
  emit(msg::PlaneChangeKind::kRemoved, final_[from], final_shown_[from]);
  planes::PointMoments& points = final_moments_[into];
  points.merge(final_moments_[from]);
  final_seen_[into].merge(final_seen_[from]);
  const planes::PlaneFit fit = fit_of(points);
  if (fit.valid) {
    const double sign = fit.normal_unit.dot(plane.normal) < 0.0 ? -1.0 : 1.0;
    std::array<Eigen::Vector3d, msg::kMaxPolygonVertices> joined{};
    plane.polygon_size = hull_on_plane(sign * fit.normal_unit, fit.centroid_m, polygon_of(plane),
                                       polygon_of(final_[from]), joined);
    plane.polygon_m = joined;
    plane.normal = sign * fit.normal_unit;
    plane.d_m = sign * fit.d_m;
    plane.centroid_m = fit.centroid_m;
    plane.rmse_m = fit.rmse_m;
  }
  plane.support = points.weight;
  // A wall's lower part seen on another pass is labelled other (too low for a wall): the
  // joined extent is the wall's.
  if (plane.kind == msg::PlaneKind::kOther) {
    plane.kind = final_[from].kind;
  }
  remove_final(from);
  emit(msg::PlaneChangeKind::kFinalized, plane, final_shown_[into]);
}

bool PlaneRegistry::refresh_view(std::size_t max_changes) noexcept {
  if (view_ == nullptr) {
    refresh_next_ = 0;
    return true;
  }
  const std::size_t limit = std::min(max_changes, changes_.size());
  // The final planes, then the live slots, from where the last call stopped.
  for (; refresh_next_ < final_count_ + live_.size(); ++refresh_next_) {
    if (change_count_ >= limit) {
      return false;
    }
    if (refresh_next_ < final_count_) {
      const std::size_t i = refresh_next_;
      const PlaneMove now = view_move(final_[i], final_seen_[i]);
      if (shown_off(final_[i], final_shown_[i], now)) {
        final_shown_[i] = now;
        emit(msg::PlaneChangeKind::kFinalized, final_[i], now);
        ++counters_.view_moved;
      }
      continue;
    }
    LivePlane& plane = live_[refresh_next_ - final_count_];
    if (!plane.in_use || plane.reported.id == 0) {
      continue;
    }
    const PlaneMove now = view_move(plane.reported, plane.seen);
    if (shown_off(plane.reported, plane.shown, now)) {
      plane.shown = now;
      emit(msg::PlaneChangeKind::kChanged, plane.reported, now);
      ++counters_.view_moved;
    }
  }
  refresh_next_ = 0;
  return true;
}

}  // namespace blockmap::map
