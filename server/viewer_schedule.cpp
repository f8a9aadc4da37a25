#include "viewer_schedule.h"

namespace dmmr {

ViewerSchedule::ViewerSchedule(int max_rendering, double still_ms)
    : max_rendering_(max_rendering), still_ms_(still_ms) {}

void ViewerSchedule::add(uint64_t viewer) {
  viewers_.try_emplace(viewer);
}

void ViewerSchedule::remove(uint64_t viewer) {
  viewers_.erase(viewer);
}

bool ViewerSchedule::pose(uint64_t viewer, const Pose& p, double now_ms) {
  auto it = viewers_.find(viewer);
  if (it == viewers_.end()) return false;
  Viewer& v = it->second;
  if (v.latest && p.seq <= v.latest->seq) return false;
  v.latest = p;
  v.latest_ms = now_ms;
  return true;
}

std::optional<ViewerSchedule::Pick> ViewerSchedule::next() {
  if (viewers_.empty()) return std::nullopt;
  // Round robin: start after the last viewer picked, wrap around once.
  auto start = last_picked_ ? viewers_.upper_bound(*last_picked_) : viewers_.begin();
  for (size_t n = 0; n < viewers_.size(); ++n, ++start) {
    if (start == viewers_.end()) start = viewers_.begin();
    Viewer& v = start->second;
    if (!v.latest || v.rendering >= max_rendering_) continue;
    if (v.picked_seq && *v.picked_seq >= v.latest->seq) continue;
    v.picked_seq = v.latest->seq;
    ++v.rendering;
    last_picked_ = start->first;
    return Pick{start->first, *v.latest, v.latest_ms};
  }
  return std::nullopt;
}

ViewerSchedule::Delivery ViewerSchedule::rendered(uint64_t viewer, uint32_t frame, uint32_t seq) {
  auto it = viewers_.find(viewer);
  if (it == viewers_.end()) return Delivery::Gone;
  Viewer& v = it->second;
  --v.rendering;
  v.rendered_seq = seq;
  v.last_frame = frame;
  if (v.in_flight) {
    v.held = frame;
    return Delivery::Hold;
  }
  v.in_flight = frame;
  return Delivery::Send;
}

std::optional<uint32_t> ViewerSchedule::acked(uint64_t viewer, uint32_t frame) {
  auto it = viewers_.find(viewer);
  if (it == viewers_.end()) return std::nullopt;
  Viewer& v = it->second;
  if (v.in_flight != frame) return std::nullopt;
  v.in_flight = v.held;
  v.held.reset();
  return v.in_flight;
}

std::vector<ViewerSchedule::Still> ViewerSchedule::dueStills(double now_ms) {
  std::vector<Still> due;
  for (auto& [id, v] : viewers_) {
    if (!v.latest || v.rendered_seq != v.latest->seq || v.rendering > 0) continue;
    if (v.in_flight || v.held || v.still_seq == v.rendered_seq) continue;
    if (now_ms - v.latest_ms < still_ms_) continue;
    v.still_seq = v.rendered_seq;
    v.in_flight = v.last_frame;
    due.push_back({id, *v.last_frame});
  }
  return due;
}

std::optional<uint32_t> ViewerSchedule::inFlight(uint64_t viewer) const {
  auto it = viewers_.find(viewer);
  return it == viewers_.end() ? std::nullopt : it->second.in_flight;
}

std::optional<uint32_t> ViewerSchedule::held(uint64_t viewer) const {
  auto it = viewers_.find(viewer);
  return it == viewers_.end() ? std::nullopt : it->second.held;
}

}  // namespace dmmr
