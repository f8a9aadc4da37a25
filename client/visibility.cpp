#include "visibility.h"

#include <algorithm>
#include <cmath>

namespace dmmr {

VisibilityPlan planVisibility(const std::vector<uint32_t>& region,
                              const std::vector<uint32_t>& previous,
                              const std::vector<uint32_t>& potential,
                              const std::vector<uint32_t>& marked_until, uint32_t frame) {
  VisibilityPlan p;
  auto prev = previous.begin(), pot = potential.begin();
  for (uint32_t o : region) {
    while (prev != previous.end() && *prev < o) ++prev;
    while (pot != potential.end() && *pot < o) ++pot;
    bool occluder = (prev != previous.end() && *prev == o) || (pot != potential.end() && *pot == o);
    if (occluder)
      p.occluders.push_back(o);
    else if (o < marked_until.size() && frame < marked_until[o])
      p.marked.push_back(o);
    else
      p.queried.push_back(o);
  }
  return p;
}

std::vector<uint32_t> mergeSorted(const std::vector<std::vector<uint32_t>>& lists) {
  std::vector<uint32_t> out;
  for (const auto& l : lists) out.insert(out.end(), l.begin(), l.end());
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

bool boxReachesNearPlane(const Box3d& box, const Camera& camera) {
  // Every point of the near rectangle lies within `reach` of the eye.
  double ty = std::tan(camera.fovy_deg * M_PI / 360.0), tx = ty * camera.aspect;
  double reach = camera.near * std::sqrt(1 + tx * tx + ty * ty) * 1.01;
  Vec3d e = camera.eye;
  // Renderer::queryBox draws the box widened (half extents * 1.001 plus 1e-5
  // of the distance to its centre and of its half diagonal): test that box,
  // with twice the margin, since it is the one the near plane would clip.
  Vec3d c = box.center() - e, h = box.extent() * 0.5;
  double slack = 2e-5 * (length(c) + length(h)) + 1e-9;
  Vec3d lo = box.center() - (h * 1.002 + Vec3d{slack, slack, slack});
  Vec3d hi = box.center() + (h * 1.002 + Vec3d{slack, slack, slack});
  Vec3d nearest{std::clamp(e.x, lo.x, hi.x), std::clamp(e.y, lo.y, hi.y),
                std::clamp(e.z, lo.z, hi.z)};
  return length(nearest - e) <= reach;
}

}  // namespace dmmr
