#include "plan.h"

#include "tiles.h"

#include <algorithm>
#include <chrono>

namespace dmmr {

FramePlanner::FramePlanner(const Scene& scene)
    : scene_(scene), drawn_in_(new std::atomic<uint32_t>[scene.objects.size()]) {
  boxes_.reserve(scene.objects.size());
  for (size_t i = 0; i < scene.objects.size(); ++i) {
    boxes_.push_back({tightBox(scene.objects[i]), scene.objects[i].weight});
    drawn_in_[i].store(0, std::memory_order_relaxed);
  }
}

void FramePlanner::reportDrawn(uint32_t frame, const std::vector<uint32_t>& objects) {
  for (uint32_t o : objects)
    if (o < boxes_.size()) {
      uint32_t v = frame + 1, old = drawn_in_[o].load(std::memory_order_relaxed);
      while (old < v && !drawn_in_[o].compare_exchange_weak(old, v, std::memory_order_relaxed)) {
      }
    }
  feedback_.store(true, std::memory_order_relaxed);
}

uint64_t FramePlanner::weightOf(uint32_t o) const {
  uint64_t tris = boxes_[o].weight;
  if (!feedback_.load(std::memory_order_relaxed)) return tris;
  uint32_t seen = drawn_in_[o].load(std::memory_order_relaxed);  // frame + 1, or 0
  bool recent = seen != 0 && seen + kSeenFrames > frame_;
  return recent ? tris : std::min(tris, kHiddenWeight);
}

std::vector<Footprint> FramePlanner::footprints(const std::vector<uint32_t>& visible,
                                                const Camera& camera, int width, int height) const {
  FootprintProjector project(camera, width, height);
  return projectInSlices(visible.size(), footprintThreads(visible.size()),
                         [&](size_t k, Footprint* f) {
                           uint32_t o = visible[k];
                           return project(boxes_[o].box, weightOf(o), o, f);
                         });
}

FramePlan planFrame(const Scene& scene, const Camera& camera, int width, int height, int clients) {
  return FramePlanner(scene).plan(camera, width, height, clients);
}

std::vector<uint32_t> FramePlanner::cull(const Camera& camera, uint64_t* objects,
                                         uint64_t* triangles) const {
  std::vector<uint32_t> visible;
  CullStats cs;
  cullObjects(scene_.skeleton, scene_.objects, frustumPlanes(camera), &visible, &cs);
  *objects = cs.objects;
  *triangles = cs.triangles;
  return visible;
}

namespace {
double msBetween(std::chrono::steady_clock::time_point a, std::chrono::steady_clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}
}  // namespace

FramePlan FramePlanner::plan(const Camera& camera, int width, int height, int clients) const {
  using Clock = std::chrono::steady_clock;
  FramePlan plan;
  auto t0 = Clock::now();
  std::vector<uint32_t> visible =
      cull(camera, &plan.objects_in_frustum, &plan.triangles_in_frustum);
  auto t1 = Clock::now();
  std::vector<Footprint> items = footprints(visible, camera, width, height);
  auto tp = Clock::now();
  plan.regions = divideFrame(items, Rect{0, 0, width, height}, clients);
  auto t2 = Clock::now();
  plan.project_ms = msBetween(t1, tp);
  plan.cull_ms = msBetween(t0, t1);
  plan.divide_ms = msBetween(t1, t2);
  return plan;
}

TilePlan FramePlanner::planTiles(const Camera& camera, int width, int height, int tile_w,
                                 int tile_h) const {
  using Clock = std::chrono::steady_clock;
  TilePlan plan;
  auto t0 = Clock::now();
  std::vector<uint32_t> visible =
      cull(camera, &plan.objects_in_frustum, &plan.triangles_in_frustum);
  auto t1 = Clock::now();
  Rect frame{0, 0, width, height};
  plan.tiles = makeTiles(frame, tile_w, tile_h);
  plan.columns = (width + tile_w - 1) / tile_w;
  plan.objects = objectsPerTile(footprints(visible, camera, width, height), frame, tile_w, tile_h);
  auto t2 = Clock::now();
  plan.cull_ms = msBetween(t0, t1);
  plan.divide_ms = msBetween(t1, t2);
  return plan;
}

}  // namespace dmmr
