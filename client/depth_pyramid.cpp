#include "depth_pyramid.h"

#include <algorithm>
#include <cmath>

#include "error.h"

namespace dmmr {

std::ostream& operator<<(std::ostream& os, const ScreenBound& b) {
  if (b.reaches_near) return os << "ScreenBound{reaches near}";
  return os << "ScreenBound{[" << b.x0 << "," << b.x1 << "]x[" << b.y0 << "," << b.y1
            << "] nearest " << b.nearest << "}";
}

ScreenBound screenBound(const Box3d& box, const Camera& camera, int width, int height) {
  return ScreenProjector(camera, width, height).bound(box);
}

ScreenBound screenRect(const Box3d& box, const Camera& camera, int width, int height) {
  return ScreenProjector(camera, width, height).rect(box);
}

ScreenProjector::ScreenProjector(const Camera& camera, int width, int height)
    : camera_(camera),
      view_(viewRotation(camera)),
      camera_to_world_(Mat4d::rotation(camera.rotation)),
      tan_half_fovy_(std::tan(camera.fovy_deg * M_PI / 360.0)),
      f_(1.0 / tan_half_fovy_),
      fx_(f_ / camera.aspect),
      width_(width),
      height_(height) {
  DMMR_CHECK(width > 0 && height > 0);
}

ScreenBound ScreenProjector::bound(const Box3d& box) const {
  ScreenBound b = rect(box);
  if (b.reaches_near) return b;
  // The entry-depth planes in pixel indices: ndc = (i + 0.5) * 2 / n - 1.
  EntryDepthPlanes p = entryDepthPlanes(box, camera_, camera_to_world_, tan_half_fovy_);
  b.has_planes = true;
  for (size_t i = 0; i < 3; ++i) {
    const auto& k = p.k[i];
    double sx = 2.0 / width_, sy = 2.0 / height_;
    b.planes[i] = {k[0] * sx, k[1] * sy, k[0] * (0.5 * sx - 1) + k[1] * (0.5 * sy - 1) + k[2]};
  }
  return b;
}

ScreenBound ScreenProjector::rect(const Box3d& box) const {
  DMMR_CHECK(box.valid());
  const Camera& camera = camera_;
  const int width = width_, height = height_;
  const double f = f_, fx = fx_;
  ScreenBound b;
  double xmin = INFINITY, xmax = -INFINITY, ymin = INFINITY, ymax = -INFINITY;
  // The corners in eye space: the centre's image plus or minus the images of
  // the three half extents (columns of the rotation, scaled).
  // Relative to the eye before halving: a box far from the origin keeps its
  // digits (box.center() would round at the coordinates' magnitude).
  Vec3d rlo = box.lo - camera.eye, rhi = box.hi - camera.eye;
  Vec3d c = view_.transformVector((rlo + rhi) * 0.5), h = (rhi - rlo) * 0.5;
  Vec3d ax{view_.at(0, 0) * h.x, view_.at(1, 0) * h.x, view_.at(2, 0) * h.x};
  Vec3d ay{view_.at(0, 1) * h.y, view_.at(1, 1) * h.y, view_.at(2, 1) * h.y};
  Vec3d az{view_.at(0, 2) * h.z, view_.at(1, 2) * h.z, view_.at(2, 2) * h.z};
  // The box is convex: all corners beyond the near plane put all of it
  // there, and its projection is the hull of the corners' projections.
  double nearestDist = -c.z - std::abs(ax.z) - std::abs(ay.z) - std::abs(az.z);
  if (!(nearestDist > camera.near)) {
    b.reaches_near = true;
    return b;
  }
  for (int i = 0; i < 8; ++i) {
    Vec3d e = c + ((i & 1) ? ax : -ax) + ((i & 2) ? ay : -ay) + ((i & 4) ? az : -az);
    double dist = -e.z;
    if (!(dist > camera.near)) {  // rounding: the sum above may differ in its last bits
      b.reaches_near = true;
      return b;
    }
    nearestDist = std::min(nearestDist, dist);
    double wx = (fx * e.x / dist + 1) * 0.5 * width, wy = (f * e.y / dist + 1) * 0.5 * height;
    xmin = std::min(xmin, wx);
    xmax = std::max(xmax, wx);
    ymin = std::min(ymin, wy);
    ymax = std::max(ymax, wy);
  }
  // The pixels whose centres (i + 0.5) lie within the corners' span, give
  // or take 1/64 pixel for this computation's rounding: the query box is
  // already wider than the object by what the GPU's float transform and the
  // rasteriser's snapping can move its geometry (queryBoxBounds).
  auto lo = [](double v, int n) {
    return int(std::ceil(std::clamp(v, -4.0, n + 4.0) - 0.5 - 1.0 / 64));
  };
  auto hi = [](double v, int n) {
    return int(std::floor(std::clamp(v, -4.0, n + 4.0) - 0.5 + 1.0 / 64));
  };
  b.x0 = std::max(0, lo(xmin, width));
  b.x1 = std::min(width - 1, hi(xmax, width));
  b.y0 = std::max(0, lo(ymin, height));
  b.y1 = std::min(height - 1, hi(ymax, height));
  // Depth = near / distance; rounded up by a relative 1e-6 for this
  // computation's own rounding.
  b.nearest = camera.near / nearestDist * (1 + 1e-6);
  return b;
}

double ScreenBound::bound(int bx0, int by0, int bx1, int by1) const {
  double d = nearest;
  if (!has_planes) return d;
  for (const auto& k : planes) {
    // A linear function's maximum over a rectangle is at a corner; rounded
    // up like `nearest`, in proportion to the terms' size.
    double ax = std::max(k[0] * bx0, k[0] * bx1), ay = std::max(k[1] * by0, k[1] * by1);
    double v = ax + ay + k[2];
    v += (std::abs(ax) + std::abs(ay) + std::abs(k[2])) * 1e-6;
    d = std::min(d, v);
  }
  return d;
}

ScreenBound partBound(const ScreenBound& object, const ScreenBound& part) {
  if (object.reaches_near) return object;
  if (part.reaches_near) return part;
  ScreenBound b = object;
  b.x0 = std::max(object.x0, part.x0);
  b.y0 = std::max(object.y0, part.y0);
  b.x1 = std::min(object.x1, part.x1);
  b.y1 = std::min(object.y1, part.y1);
  return b;
}

ScreenBound unite(const ScreenBound& a, const ScreenBound& b) {
  if (a.reaches_near) return a;
  if (b.reaches_near) return b;
  if (a.empty()) return ScreenBound{false, b.x0, b.y0, b.x1, b.y1, std::max(a.nearest, b.nearest)};
  if (b.empty()) return ScreenBound{false, a.x0, a.y0, a.x1, a.y1, std::max(a.nearest, b.nearest)};
  return ScreenBound{false,
                     std::min(a.x0, b.x0),
                     std::min(a.y0, b.y0),
                     std::max(a.x1, b.x1),
                     std::max(a.y1, b.y1),
                     std::max(a.nearest, b.nearest)};
}

bool overlaps(const Rect& a, const Rect& b) {
  return !a.empty() && !b.empty() && a.x < b.x1() && b.x < a.x1() && a.y < b.y1() && b.y < a.y1();
}

Rect intersection(const Rect& a, const Rect& b) {
  int x = std::max(a.x, b.x), y = std::max(a.y, b.y);
  Rect r{x, y, std::min(a.x1(), b.x1()) - x, std::min(a.y1(), b.y1()) - y};
  return r.empty() ? Rect{} : r;
}

Rect boundingRect(const Rect& a, const Rect& b) {
  if (a.empty()) return b;
  if (b.empty()) return a;
  int x = std::min(a.x, b.x), y = std::min(a.y, b.y);
  return Rect{x, y, std::max(a.x1(), b.x1()) - x, std::max(a.y1(), b.y1()) - y};
}

std::vector<Rect> coverRects(std::vector<Rect> rects, size_t max) {
  DMMR_CHECK(max >= 1);
  rects.erase(std::remove_if(rects.begin(), rects.end(), [](const Rect& r) { return r.empty(); }),
              rects.end());
  for (;;) {
    // The pair to merge: any overlapping pair first, else (over the limit)
    // the cheapest. Quadratic, but the lists are a frame's newly visible
    // objects.
    size_t bi = 0, bj = 0;
    int64_t best = INT64_MAX;
    for (size_t i = 0; i < rects.size() && best > INT64_MIN; ++i)
      for (size_t j = i + 1; j < rects.size(); ++j) {
        if (overlaps(rects[i], rects[j])) {
          bi = i, bj = j, best = INT64_MIN;
          break;
        }
        int64_t added = boundingRect(rects[i], rects[j]).area() - rects[i].area() - rects[j].area();
        if (added < best) bi = i, bj = j, best = added;
      }
    if (best != INT64_MIN && rects.size() <= max) return rects;
    rects[bi] = boundingRect(rects[bi], rects[bj]);
    rects.erase(rects.begin() + std::ptrdiff_t(bj));
  }
}

CellCoverage::CellCoverage(const Rect& region, int shift) : region_(region), shift_(shift) {
  DMMR_CHECK(!region.empty() && shift >= 0 && shift < 16);
  w_ = ((region.w - 1) >> shift) + 1;
  h_ = ((region.h - 1) >> shift) + 1;
  sums_.assign(size_t(w_ + 1) * size_t(h_ + 1), 0);
}

bool CellCoverage::cells(const Rect& r, int* cx0, int* cy0, int* cx1, int* cy1) const {
  Rect c = intersection(r, region_);
  if (c.empty()) return false;
  *cx0 = (c.x - region_.x) >> shift_;
  *cx1 = (c.x1() - 1 - region_.x) >> shift_;
  *cy0 = (c.y - region_.y) >> shift_;
  *cy1 = (c.y1() - 1 - region_.y) >> shift_;
  return true;
}

void CellCoverage::mark(const Rect& r) {
  int x0, y0, x1, y1;
  if (!cells(r, &x0, &y0, &x1, &y1)) return;
  auto at = [&](int x, int y) -> int32_t& { return sums_[size_t(y) * size_t(w_ + 1) + size_t(x)]; };
  at(x0, y0) += 1;
  at(x1 + 1, y0) -= 1;
  at(x0, y1 + 1) -= 1;
  at(x1 + 1, y1 + 1) += 1;
}

void CellCoverage::finish() {
  // The difference array summed gives each cell's mark count; marked cells
  // (count > 0) then become 1, summed again into the corner sums.
  const size_t stride = size_t(w_ + 1);
  std::vector<int32_t> marked(size_t(w_) * size_t(h_));
  std::vector<int32_t> row(size_t(w_ + 1), 0);
  for (int y = 0; y < h_; ++y) {
    int32_t run = 0;
    for (int x = 0; x < w_; ++x) {
      run += sums_[size_t(y) * stride + size_t(x)];
      row[size_t(x)] += run;  // column sums of the row-wise sums
      marked[size_t(y) * size_t(w_) + size_t(x)] = row[size_t(x)] > 0;
    }
  }
  std::fill(sums_.begin(), sums_.end(), 0);
  for (int y = 0; y < h_; ++y)
    for (int x = 0; x < w_; ++x)
      sums_[size_t(y + 1) * stride + size_t(x + 1)] =
          marked[size_t(y) * size_t(w_) + size_t(x)] + sums_[size_t(y) * stride + size_t(x + 1)] +
          sums_[size_t(y + 1) * stride + size_t(x)] - sums_[size_t(y) * stride + size_t(x)];
}

bool CellCoverage::meets(const Rect& r) const {
  int x0, y0, x1, y1;
  if (!cells(r, &x0, &y0, &x1, &y1)) return false;
  const size_t stride = size_t(w_ + 1);
  auto at = [&](int x, int y) { return sums_[size_t(y) * stride + size_t(x)]; };
  return at(x1 + 1, y1 + 1) - at(x0, y1 + 1) - at(x1 + 1, y0) + at(x0, y0) > 0;
}

void DepthPyramid::build(const float* depth, const Rect& region) {
  DMMR_CHECK(!region.empty());
  region_ = region;
  int w = region.w, h = region.h;
  size_t n = 1;
  while ((w > 1 || h > 1) && n < 32) {
    w = (w + 1) / 2;
    h = (h + 1) / 2;
    ++n;
  }
  levels_.resize(n);
  dims_.resize(n);
  dims_[0] = {region.w, region.h};
  levels_[0].assign(depth, depth + size_t(region.w) * size_t(region.h));
  for (size_t l = 1; l < n; ++l) {
    auto [pw, ph] = dims_[l - 1];
    int cw = (pw + 1) / 2, ch = (ph + 1) / 2;
    dims_[l] = {cw, ch};
    std::vector<float>& out = levels_[l];
    out.resize(size_t(cw) * size_t(ch));
    const float* in = levels_[l - 1].data();
    for (int y = 0; y < ch; ++y) {
      const float* r0 = in + size_t(2 * y) * size_t(pw);
      const float* r1 = 2 * y + 1 < ph ? r0 + pw : r0;  // odd height: the last row twice
      float* o = out.data() + size_t(y) * size_t(cw);
      int full = pw / 2;
      for (int x = 0; x < full; ++x)  // vectorises: four loads, three mins
        o[x] = std::min(std::min(r0[2 * x], r0[2 * x + 1]), std::min(r1[2 * x], r1[2 * x + 1]));
      if (full < cw) o[full] = std::min(r0[2 * full], r1[2 * full]);  // odd width
    }
  }
}

void DepthPyramid::update(const float* depth, const Rect& dirty) {
  DMMR_CHECK(!levels_.empty());
  Rect c = intersection(dirty, region_);
  if (c.empty()) return;
  // Region-relative and inclusive from here on.
  int x0 = c.x - region_.x, x1 = c.x1() - 1 - region_.x;
  int y0 = c.y - region_.y, y1 = c.y1() - 1 - region_.y;
  const size_t w = size_t(region_.w);
  for (int y = y0; y <= y1; ++y)
    std::copy_n(depth + size_t(y) * w + size_t(x0), size_t(x1 - x0 + 1),
                levels_[0].data() + size_t(y) * w + size_t(x0));
  for (size_t l = 1; l < levels_.size(); ++l) {
    auto [pw, ph] = dims_[l - 1];
    int cw = dims_[l].first;
    x0 >>= 1, y0 >>= 1, x1 >>= 1, y1 >>= 1;
    const float* in = levels_[l - 1].data();
    float* out = levels_[l].data();
    for (int y = y0; y <= y1; ++y) {
      const float* r0 = in + size_t(2 * y) * size_t(pw);
      const float* r1 = 2 * y + 1 < ph ? r0 + pw : r0;  // as build(): odd sizes repeat the last
      for (int x = x0; x <= x1; ++x) {
        float v = std::min(r0[2 * x], r1[2 * x]);
        if (2 * x + 1 < pw) v = std::min(v, std::min(r0[2 * x + 1], r1[2 * x + 1]));
        out[size_t(y) * size_t(cw) + size_t(x)] = v;
      }
    }
  }
}

bool DepthPyramid::refine(int level, int x, int y, const int rect[4], const ScreenBound& b,
                          int* budget, std::pair<int, int>* witness) const {
  // The texel's pixels within the rectangle, in frame pixels, and the
  // nearest the box can be there.
  int px0 = std::max(x << level, rect[0]), px1 = std::min(((x + 1) << level) - 1, rect[2]);
  int py0 = std::max(y << level, rect[1]), py1 = std::min(((y + 1) << level) - 1, rect[3]);
  double d = b.bound(px0 + region_.x, py0 + region_.y, px1 + region_.x, py1 + region_.y);
  if (double(texel(level, x, y)) > d) return true;
  if (level == 0) {  // a pixel of the rectangle at or behind the box
    if (witness) *witness = {x + region_.x, y + region_.y};
    return false;
  }
  if (--*budget < 0) return false;
  int l = level - 1;
  int cx0 = std::max(2 * x, rect[0] >> l), cx1 = std::min(2 * x + 1, rect[2] >> l);
  int cy0 = std::max(2 * y, rect[1] >> l), cy1 = std::min(2 * y + 1, rect[3] >> l);
  cx1 = std::min(cx1, width(l) - 1);
  cy1 = std::min(cy1, height(l) - 1);
  for (int cy = cy0; cy <= cy1; ++cy)
    for (int cx = cx0; cx <= cx1; ++cx)
      if (!refine(l, cx, cy, rect, b, budget, witness)) return false;
  return true;
}

bool DepthPyramid::hides(const ScreenBound& b, int budget, std::pair<int, int>* witness) const {
  if (b.reaches_near || levels_.empty()) return false;
  if (b.empty()) return true;
  // The rectangle within the region, region-relative.
  int rect[4] = {std::max(b.x0, region_.x) - region_.x, std::max(b.y0, region_.y) - region_.y,
                 std::min(b.x1, region_.x1() - 1) - region_.x,
                 std::min(b.y1, region_.y1() - 1) - region_.y};
  if (rect[2] < rect[0] || rect[3] < rect[1]) return true;  // nothing of it in the region
  // The finest level at which the rectangle spans at most 2x2 texels.
  int level = 0;
  while (level + 1 < levels() && ((rect[2] >> level) - (rect[0] >> level) > 1 ||
                                  (rect[3] >> level) - (rect[1] >> level) > 1))
    ++level;
  for (int y = rect[1] >> level; y <= rect[3] >> level; ++y)
    for (int x = rect[0] >> level; x <= rect[2] >> level; ++x)
      if (!refine(level, x, y, rect, b, &budget, witness)) return false;
  return true;
}

void reprojectDepth(const DepthPyramid& from, int level, const Camera& from_cam,
                    const Camera& to_cam, int width, int height, const Rect& to_region,
                    PredictedDepth* out) {
  DMMR_CHECK(level >= 1 && from.levels() > level && !to_region.empty());
  const int side = 1 << level;
  constexpr float kUnset = -1;  // below every depth: any point replaces it
  out->region = to_region;
  out->level = level;
  out->width = (to_region.w + side - 1) >> level;
  out->height = (to_region.h + side - 1) >> level;
  const int w = out->width, h = out->height;
  std::vector<float>& t = out->texels;
  t.assign(size_t(w) * size_t(h), kUnset);
  // A point at eye distance `dist` on the ray through normalised device
  // coordinates (u, v) of the old camera is dist * (u / fx, v / f, -1) in its
  // eye space; in the new eye space it is M times that, plus `shift`.
  auto focal = [](const Camera& c) { return 1.0 / std::tan(c.fovy_deg * M_PI / 360.0); };
  double f0 = focal(from_cam), fx0 = f0 / from_cam.aspect;
  double f1 = focal(to_cam), fx1 = f1 / to_cam.aspect;
  Mat4d to_view = viewRotation(to_cam);
  Vec3d m[3];  // columns of M = to_view * from_cam's camera-to-world rotation
  for (int i = 0; i < 3; ++i) {
    Vec3d axis{i == 0 ? 1.0 : 0.0, i == 1 ? 1.0 : 0.0, i == 2 ? 1.0 : 0.0};
    m[i] = to_view.transformVector(rotate(from_cam.rotation, axis));
  }
  Vec3d shift = to_view.transformVector(from_cam.eye - to_cam.eye);
  const Rect& fr = from.region();
  for (int ty = 0; ty < from.height(level); ++ty) {
    // The block's centre, clipped to the region (partial blocks at the end).
    double v = (fr.y + std::min(side * (ty + 0.5), fr.h - 0.5)) * 2.0 / height - 1;
    Vec3d row = m[1] * (v / f0) - m[2];
    for (int tx = 0; tx < from.width(level); ++tx) {
      double u = (fr.x + std::min(side * (tx + 0.5), fr.w - 0.5)) * 2.0 / width - 1;
      Vec3d e = m[0] * (u / fx0) + row;  // the direction in the new eye space
      float depth = from.texel(level, tx, ty);
      if (depth > 0) e = e * (from_cam.near / double(depth)) + shift;
      double dist = -e.z;
      // A direction needs only to be ahead; a point must be beyond the near plane.
      if (!(depth > 0 ? dist > to_cam.near : dist > 0)) continue;
      double px = (fx1 * e.x / dist + 1) * 0.5 * width - to_region.x;
      double py = (f1 * e.y / dist + 1) * 0.5 * height - to_region.y;
      if (!(px >= 0 && py >= 0 && px < to_region.w && py < to_region.h)) continue;
      float& z = t[size_t(int(py) >> level) * size_t(w) + size_t(int(px) >> level)];
      z = std::max(z, depth > 0 ? float(to_cam.near / dist) : 0.0f);
    }
  }
  std::vector<float> prev;
  for (int pass = 0; pass < 2; ++pass) {
    prev = t;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        if (prev[size_t(y) * size_t(w) + size_t(x)] != kUnset) continue;
        float far = INFINITY;
        for (int ny = std::max(0, y - 1); ny <= std::min(h - 1, y + 1); ++ny)
          for (int nx = std::max(0, x - 1); nx <= std::min(w - 1, x + 1); ++nx) {
            float z = prev[size_t(ny) * size_t(w) + size_t(nx)];
            if (z != kUnset) far = std::min(far, z);
          }
        if (far != INFINITY) t[size_t(y) * size_t(w) + size_t(x)] = far;
      }
  }
  for (float& z : t)
    if (z == kUnset) z = 0;
}

double shownFraction(const PredictedDepth& p, const ScreenBound& b, int max_samples) {
  if (b.reaches_near) return 1;
  const Rect& r = p.region;
  // The rectangle within the region, in texels.
  int x0 = std::max(b.x0, r.x) - r.x, x1 = std::min(b.x1, r.x1() - 1) - r.x;
  int y0 = std::max(b.y0, r.y) - r.y, y1 = std::min(b.y1, r.y1() - 1) - r.y;
  if (b.empty() || x1 < x0 || y1 < y0) return 0;
  const int l = p.level, side = 1 << l;
  x0 >>= l, x1 >>= l, y0 >>= l, y1 >>= l;
  int grid = int(std::sqrt(double(std::max(1, max_samples))));
  int sx = std::max(1, (x1 - x0 + grid) / grid), sy = std::max(1, (y1 - y0 + grid) / grid);
  int samples = 0, shown = 0;
  for (int y = y0; y <= y1; y += sy)
    for (int x = x0; x <= x1; x += sx) {
      ++samples;
      int px = r.x + side * x, py = r.y + side * y;
      if (!(double(p.texel(x, y)) > b.bound(px, py, px + side - 1, py + side - 1))) ++shown;
    }
  return double(shown) / samples;
}

}  // namespace dmmr
