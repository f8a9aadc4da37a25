// Helpers shared by the server tests: a seeded random source with our own
// integer and real mappings (so values do not depend on the standard
// library's distributions), projection with the shared camera's matrices, and
// checks that a division tiles its frame and hands out objects correctly.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <random>
#include <sstream>
#include <vector>

#include "camera.h"
#include "divide.h"
#include "math.h"

namespace dmmr::test {

// ---- random values --------------------------------------------------------

class Rng {
 public:
  explicit Rng(uint64_t seed) : g_(seed) {}
  // An integer in [lo, hi] (inclusive). The modulo bias is irrelevant here.
  int64_t range(int64_t lo, int64_t hi) { return lo + int64_t(g_() % uint64_t(hi - lo + 1)); }
  int integer(int lo, int hi) { return int(range(lo, hi)); }
  // A real in [0, 1), from the top 53 bits.
  double unit() { return double(g_() >> 11) * 0x1.0p-53; }
  double real(double lo, double hi) { return lo + (hi - lo) * unit(); }
  bool chance(double p) { return unit() < p; }
  Vec3d inBox(const Box3d& b) {
    return {real(b.lo.x, b.hi.x), real(b.lo.y, b.hi.y), real(b.lo.z, b.hi.z)};
  }
  // A point uniformly inside a sphere (by rejection from its cube).
  Vec3d inSphere(const Sphere3d& s) {
    for (;;) {
      Vec3d d{real(-1, 1), real(-1, 1), real(-1, 1)};
      if (dot(d, d) <= 1) return s.center + d * s.radius;
    }
  }
  Quatd rotation() {  // a random unit quaternion (rejection from the 4-cube)
    for (;;) {
      double x = real(-1, 1), y = real(-1, 1), z = real(-1, 1), w = real(-1, 1);
      double n = x * x + y * y + z * z + w * w;
      if (n > 0.01 && n <= 1) {
        n = std::sqrt(n);
        return {x / n, y / n, z / n, w / n};
      }
    }
  }
  template <class T>
  void shuffle(std::vector<T>& v) {
    for (size_t i = v.size(); i > 1; --i) std::swap(v[i - 1], v[size_t(range(0, int64_t(i) - 1))]);
  }

 private:
  std::mt19937_64 g_;
};

// ---- projection -----------------------------------------------------------

// A point through projectionMatrix(camera) * viewMatrix(camera), as window
// pixel coordinates (x, y) and the clip w (the distance in front of the eye).
struct Projected {
  double x = 0, y = 0, w = 0;
};
inline Projected project(const Camera& camera, Vec3d p, int width, int height) {
  Mat4d m = projectionMatrix(camera) * viewMatrix(camera);
  double v[4] = {p.x, p.y, p.z, 1}, clip[4];
  for (int r = 0; r < 4; ++r) {
    clip[r] = 0;
    for (int c = 0; c < 4; ++c) clip[r] += m.at(r, c) * v[c];
  }
  return {(clip[0] / clip[3] * 0.5 + 0.5) * width, (clip[1] / clip[3] * 0.5 + 0.5) * height,
          clip[3]};
}
// True when the point is in front of the near plane and inside the view.
inline bool inView(const Camera& camera, Vec3d p, int width, int height) {
  Projected q = project(camera, p, width, height);
  return q.w >= camera.near && q.x >= 0 && q.x <= width && q.y >= 0 && q.y <= height;
}
// The pixel (column, row) holding window coordinates, kept inside the frame.
inline int pixelOf(double v, int size) {
  return std::clamp(int(std::floor(v)), 0, size - 1);
}

// ---- rectangles and footprints --------------------------------------------

inline bool overlaps(const Footprint& f, const Rect& r) {
  return !r.empty() && f.x0 < f.x1 && f.y0 < f.y1 && f.x0 < r.x1() && f.x1 > r.x && f.y0 < r.y1() &&
         f.y1 > r.y;
}
inline bool overlaps(const Rect& a, const Rect& b) {
  return !a.empty() && !b.empty() && a.x < b.x1() && b.x < a.x1() && a.y < b.y1() && b.y < a.y1();
}
inline bool contains(const Rect& outer, const Rect& inner) {
  return inner.x >= outer.x && inner.y >= outer.y && inner.x1() <= outer.x1() &&
         inner.y1() <= outer.y1();
}
inline bool containsPixel(const Rect& r, int x, int y) {
  return x >= r.x && x < r.x1() && y >= r.y && y < r.y1();
}
inline int nonEmpty(const std::vector<Region>& regions) {
  return int(std::count_if(regions.begin(), regions.end(),
                           [](const Region& r) { return !r.rect.empty(); }));
}

// The regions are `clients` rectangles that tile `frame`: each non-empty one
// lies inside it, none overlap, and together they cover every pixel. Small
// frames are checked pixel by pixel; large ones by area and pairwise
// disjointness (disjoint pieces inside the frame whose areas add up to the
// frame's cover it). Empty rectangles hold no objects and no weight.
inline ::testing::AssertionResult tilesFrame(const std::vector<Region>& regions, Rect frame,
                                             int clients) {
  if (int(regions.size()) != clients)
    return ::testing::AssertionFailure()
           << regions.size() << " regions for " << clients << " clients";
  for (size_t i = 0; i < regions.size(); ++i) {
    const Region& r = regions[i];
    if (r.rect.w < 0 || r.rect.h < 0)
      return ::testing::AssertionFailure() << "region " << i << " has negative size: " << r;
    if (r.rect.empty()) {
      if (!r.objects.empty() || r.weight != 0)
        return ::testing::AssertionFailure() << "empty region " << i << " has work: " << r;
      continue;
    }
    if (!contains(frame, r.rect))
      return ::testing::AssertionFailure()
             << "region " << i << " " << r.rect << " leaves " << frame;
  }
  if (frame.area() <= (1 << 16)) {
    std::vector<int> count(size_t(frame.area()), 0);
    for (const Region& r : regions)
      for (int y = r.rect.y; y < r.rect.y1(); ++y)
        for (int x = r.rect.x; x < r.rect.x1(); ++x)
          ++count[size_t(y - frame.y) * size_t(frame.w) + size_t(x - frame.x)];
    for (int y = 0; y < frame.h; ++y)
      for (int x = 0; x < frame.w; ++x) {
        int c = count[size_t(y) * size_t(frame.w) + size_t(x)];
        if (c != 1)
          return ::testing::AssertionFailure()
                 << "pixel (" << frame.x + x << "," << frame.y + y << ") of " << frame
                 << " is covered " << c << " times";
      }
    return ::testing::AssertionSuccess();
  }
  int64_t area = 0;
  for (size_t i = 0; i < regions.size(); ++i) {
    area += regions[i].rect.empty() ? 0 : regions[i].rect.area();
    for (size_t j = i + 1; j < regions.size(); ++j)
      if (overlaps(regions[i].rect, regions[j].rect))
        return ::testing::AssertionFailure() << "regions " << i << " " << regions[i].rect << " and "
                                             << j << " " << regions[j].rect << " overlap";
  }
  if (area != frame.area())
    return ::testing::AssertionFailure()
           << "regions cover " << area << " pixels of " << frame << " (" << frame.area() << ")";
  return ::testing::AssertionSuccess();
}

// Each region lists, ascending and once each, exactly the objects whose
// footprints overlap its rectangle, and its weight is theirs summed. Needs
// distinct object indices in `items`.
inline ::testing::AssertionResult assignsObjects(const std::vector<Footprint>& items,
                                                 const std::vector<Region>& regions) {
  std::map<uint32_t, const Footprint*> byObject;
  for (const Footprint& f : items) byObject[f.object] = &f;
  for (size_t i = 0; i < regions.size(); ++i) {
    const Region& r = regions[i];
    for (size_t k = 1; k < r.objects.size(); ++k)
      if (r.objects[k - 1] >= r.objects[k])
        return ::testing::AssertionFailure()
               << "region " << i << " objects not ascending and "
               << "unique at " << k << ": " << r.objects[k - 1] << ", " << r.objects[k];
    uint64_t weight = 0;
    for (uint32_t o : r.objects) {
      auto it = byObject.find(o);
      if (it == byObject.end())
        return ::testing::AssertionFailure() << "region " << i << " lists unknown object " << o;
      if (!overlaps(*it->second, r.rect))
        return ::testing::AssertionFailure() << "region " << i << " " << r.rect << " lists "
                                             << *it->second << " which does not overlap it";
      weight += it->second->weight;
    }
    if (weight != r.weight)
      return ::testing::AssertionFailure()
             << "region " << i << " weight " << r.weight << ", its objects weigh " << weight;
  }
  for (const Footprint& f : items)
    for (size_t i = 0; i < regions.size(); ++i)
      if (overlaps(f, regions[i].rect) &&
          !std::binary_search(regions[i].objects.begin(), regions[i].objects.end(), f.object))
        return ::testing::AssertionFailure()
               << f << " overlaps region " << i << " " << regions[i].rect << " but is not in it";
  return ::testing::AssertionSuccess();
}

// The index of the region whose rectangle holds pixel (x, y), or -1.
inline int regionAt(const std::vector<Region>& regions, int x, int y) {
  for (size_t i = 0; i < regions.size(); ++i)
    if (containsPixel(regions[i].rect, x, y)) return int(i);
  return -1;
}

}  // namespace dmmr::test
