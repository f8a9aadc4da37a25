#include "plan.h"

#include <chrono>

namespace dmmr {

FramePlan planFrame(const Scene& scene, const Camera& camera, int width, int height, int clients) {
  using Clock = std::chrono::steady_clock;
  FramePlan plan;
  auto t0 = Clock::now();
  std::vector<uint32_t> visible;
  CullStats cs;
  cullObjects(scene.skeleton, scene.objects, frustumPlanes(camera), &visible, &cs);
  plan.objects_in_frustum = cs.objects;
  plan.triangles_in_frustum = cs.triangles;
  auto t1 = Clock::now();
  std::vector<Footprint> items;
  items.reserve(visible.size());
  Footprint f;
  for (uint32_t i : visible)
    if (footprint(scene.objects[i], i, camera, width, height, &f)) items.push_back(f);
  plan.regions = divideFrame(items, Rect{0, 0, width, height}, clients);
  auto t2 = Clock::now();
  plan.cull_ms = std::chrono::duration<double, std::milli>(t1 - t0).count();
  plan.divide_ms = std::chrono::duration<double, std::milli>(t2 - t1).count();
  return plan;
}

}  // namespace dmmr
