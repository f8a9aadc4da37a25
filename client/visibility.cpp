#include "visibility.h"

#include <algorithm>
#include <cmath>
#include <iterator>

#include "draw.h"

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

bool guessCollapsed(uint64_t last_triangles, uint64_t before_triangles) {
  return last_triangles < before_triangles / 4;
}

std::vector<uint32_t> mergeSorted(const std::vector<std::vector<uint32_t>>& lists) {
  // The lists are sorted already: merge them pairwise (callers pass one to
  // three) in linear time instead of sorting their concatenation.
  size_t total = 0;
  for (const auto& l : lists) total += l.size();
  std::vector<uint32_t> out, tmp;
  out.reserve(total);
  for (const auto& l : lists) {
    if (out.empty()) {
      out.assign(l.begin(), l.end());
      continue;
    }
    tmp.clear();
    tmp.reserve(total);
    std::merge(out.begin(), out.end(), l.begin(), l.end(), std::back_inserter(tmp));
    out.swap(tmp);
  }
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

bool boxReachesNearPlane(const Box3d& box, const Camera& camera, int height) {
  // Every point of the near rectangle lies within `reach` of the eye.
  double ty = std::tan(camera.fovy_deg * M_PI / 360.0), tx = ty * camera.aspect;
  double reach = camera.near * std::sqrt(1 + tx * tx + ty * ty) * 1.01;
  Vec3d e = camera.eye;
  // Test the box Renderer::queryBox draws, widened once more for margin,
  // since it is the one the near plane would clip.
  Box3d q = queryBoxBounds(queryBoxBounds(box, camera, height), camera, height);
  Vec3d nearest{std::clamp(e.x, q.lo.x, q.hi.x), std::clamp(e.y, q.lo.y, q.hi.y),
                std::clamp(e.z, q.lo.z, q.hi.z)};
  return length(nearest - e) <= reach;
}

double CullingGovernor::net(const CullCost& c) {
  if (c.drawn_triangles == 0) return c.region_triangles > 0 ? INFINITY : -c.decide_ms;
  double all = c.draw_ms * double(c.region_triangles) / double(c.drawn_triangles);
  return all - c.draw_ms - c.decide_ms;
}

void CullingGovernor::culled(const CullCost& c) {
  // Frames culled before the pause began are recorded during it (the
  // stages run frames ahead of each other): they must not extend it.
  if (off_left_ > 0 || c.region_triangles == 0) return;
  if (net(c) >= 0) {
    bad_ = 0;
    bad_region_ = 0;
    off_len_ = min_off_;
    return;
  }
  bad_region_ = std::max(bad_region_, c.region_triangles);
  if (++bad_ < patience_) return;
  off_left_ = off_len_;
  off_len_ = std::min(max_off_, off_len_ * 2);
  since_probe_ = 0;
  paused_region_ = bad_region_;
  bad_region_ = 0;
}

void CullingGovernor::region(uint64_t triangles) {
  if (off_left_ == 0 || paused_region_ == 0) return;
  if (double(triangles) > kRegrowth * double(paused_region_)) {
    off_left_ = 0;  // full patience again, as after a pause
    bad_ = 0;
  }
}

void CullingGovernor::unculled(uint64_t region_triangles) {
  if (region_triangles == 0) return;
  // Back on with full patience: the first frame after a pause decides
  // against a stale occluder set and costs more than culling will.
  if (off_left_ > 0 && --off_left_ == 0) bad_ = 0;
  ++since_probe_;
}

void CullingGovernor::probed(const CullCost& c) {
  if (c.region_triangles == 0) return;  // nothing to learn; the next frame probes
  since_probe_ = 0;
  if (off_left_ == 0) return;
  if (net(c) < 0) {  // a probe that does not pay is a frame that did not: its region counts
    paused_region_ = std::max(paused_region_, c.region_triangles);
    return;
  }
  off_left_ = 0;
  bad_ = 0;
}

StageMode StageTrial::modeFor(uint32_t frame) const {
  if (decided_) return chosen_;
  if (frame == 0 || frame > kBlocks * block_) return StageMode::Split;
  return ((frame - 1) / block_) % 2 == 0 ? StageMode::Split : StageMode::Fused;
}

void StageTrial::finished(uint32_t frame, double ms) {
  if (decided_ || frame == 0) return;
  done_.push_back({frame, ms});
  if (frame < kBlocks * block_) return;
  // Intervals between consecutive frames of one block; the first frame of
  // a block is left out (its interval spans the switch).
  std::vector<double> gaps[2];
  for (size_t i = 1; i < done_.size(); ++i) {
    uint32_t f = done_[i].first;
    if (f > kBlocks * block_ || done_[i - 1].first != f - 1 || (f - 1) % block_ == 0) continue;
    gaps[modeFor(f) == StageMode::Fused].push_back(done_[i].second - done_[i - 1].second);
  }
  if (gaps[0].empty() || gaps[1].empty()) return;  // frames came out of order: keep split
  auto median = [](std::vector<double>& v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  split_ms_ = median(gaps[0]);
  fused_ms_ = median(gaps[1]);
  decided_ = true;
  chosen_ = fused_ms_ < split_ms_ ? StageMode::Fused : StageMode::Split;
}

size_t partBounds(const ObjectBounds& o, const GeometryParts& g, const ScreenProjector& projector,
                  const Camera& camera, int height, const ScreenBound& ob,
                  std::array<ScreenBound, kMaxParts>* out) {
  Box3d q = queryBoxBounds(o.box, camera, height);
  for (size_t k = 0; k < g.parts.size(); ++k) {
    Box3d part = queryPartBounds(transformBox(o.transform, partBox(g, k)), o.box, q);
    (*out)[k] = partBound(ob, projector.rect(part));
  }
  return g.parts.size();
}

uint8_t partsMeeting(const ScreenBound* parts, size_t count, const Rect& region) {
  uint8_t mask = 0;
  for (size_t k = 0; k < count; ++k) {
    const ScreenBound& p = parts[k];
    bool meets = p.reaches_near || (!p.empty() && p.x0 < region.x1() && p.x1 >= region.x &&
                                    p.y0 < region.y1() && p.y1 >= region.y);
    if (meets) mask = uint8_t(mask | 1u << k);
  }
  return mask;
}

uint8_t partsInRegion(const ObjectBounds& o, const GeometryParts& g,
                      const ScreenProjector& projector, const Camera& camera, int width, int height,
                      const ScreenBound& ob, const Rect& region) {
  if (!drawnByParts(o, g) || ob.reaches_near) return kAllParts;
  bool inside = ob.x0 >= region.x && ob.x1 < region.x1() && ob.y0 >= region.y &&
                ob.y1 < region.y1() && ob.x0 > 0 && ob.y0 > 0 && ob.x1 < width - 1 &&
                ob.y1 < height - 1;
  if (inside) return kAllParts;
  std::array<ScreenBound, kMaxParts> parts;
  size_t n = partBounds(o, g, projector, camera, height, ob, &parts);
  return partsMeeting(parts.data(), n, region);
}

}  // namespace dmmr
