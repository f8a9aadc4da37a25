// The depth-pyramid test's pure parts against brute force: the pyramid's
// texels are the minima of their blocks, `hides` equals a per-pixel check of
// the rectangle (and never says hidden where a pixel is not strictly nearer,
// whatever the budget), and a box's screen bound holds every point of the
// box: inside its rectangle, no nearer than its depth. Fixed-seed random
// buffers, regions, boxes and cameras, near-plane boxes and boxes under a
// pixel.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <tuple>
#include <vector>

#include "depth_pyramid.h"
#include "draw.h"

using namespace dmmr;

namespace {

// A depth buffer like an occluder pass leaves: background 0 with a few
// rectangles of random depth, ramps and noise, so that blocks mix levels.
std::vector<float> randomDepth(std::mt19937& rng, int w, int h) {
  std::vector<float> d(size_t(w) * h, 0.f);
  std::uniform_real_distribution<float> depth(0.001f, 1.f);
  std::uniform_int_distribution<int> rx(0, w - 1), ry(0, h - 1);
  int rects = std::uniform_int_distribution<int>(0, 12)(rng);
  for (int r = 0; r < rects; ++r) {
    int x0 = rx(rng), x1 = rx(rng), y0 = ry(rng), y1 = ry(rng);
    if (x0 > x1) std::swap(x0, x1);
    if (y0 > y1) std::swap(y0, y1);
    float base = depth(rng), slope = depth(rng) * 1e-3f;
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x)
        d[size_t(y) * w + x] = std::max(d[size_t(y) * w + x], base + slope * float(x - x0));
  }
  std::bernoulli_distribution hole(0.01);  // single far pixels: the test must find them
  for (float& v : d)
    if (hole(rng)) v = 0.f;
  return d;
}

// Brute force: every pixel of the rectangle inside the region nearer than b.nearest.
bool hiddenByPixels(const std::vector<float>& d, const Rect& region, const ScreenBound& b) {
  if (b.reaches_near) return false;
  for (int y = std::max(b.y0, region.y); y <= std::min(b.y1, region.y1() - 1); ++y)
    for (int x = std::max(b.x0, region.x); x <= std::min(b.x1, region.x1() - 1); ++x)
      if (!(double(d[size_t(y - region.y) * region.w + (x - region.x)]) > b.bound(x, y, x, y)))
        return false;
  return true;
}

ScreenBound randomBound(std::mt19937& rng, int fw, int fh) {
  std::uniform_int_distribution<int> rx(-3, fw + 2), ry(-3, fh + 2);
  ScreenBound b;
  b.x0 = rx(rng);
  b.y0 = ry(rng);
  // Mostly small rectangles, some large, some single pixels.
  int size = std::uniform_int_distribution<int>(0, 3)(rng) == 0
                 ? std::uniform_int_distribution<int>(0, std::max(fw, fh))(rng)
                 : std::uniform_int_distribution<int>(0, 6)(rng);
  b.x1 = b.x0 + std::uniform_int_distribution<int>(0, size)(rng);
  b.y1 = b.y0 + std::uniform_int_distribution<int>(0, size)(rng);
  b.x0 = std::max(b.x0, 0);
  b.y0 = std::max(b.y0, 0);
  b.x1 = std::min(b.x1, fw - 1);
  b.y1 = std::min(b.y1, fh - 1);
  b.nearest = std::uniform_real_distribution<double>(0, 1.05)(rng);
  // Half of them with entry-depth planes: depth sloping across the frame.
  if (std::bernoulli_distribution(0.5)(rng)) {
    b.has_planes = true;
    std::uniform_real_distribution<double> slope(-2.0 / fw, 2.0 / fw), base(-0.5, 1.5);
    for (auto& k : b.planes) k = {slope(rng), slope(rng), base(rng)};
    if (std::bernoulli_distribution(0.3)(rng)) b.planes[2] = {0, 0, kNoDepthBound};
  }
  return b;
}

TEST(DepthPyramid, TexelsAreTheMinimaOfTheirBlocks) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 40; ++trial) {
    int w = std::uniform_int_distribution<int>(1, 70)(rng);
    int h = std::uniform_int_distribution<int>(1, 70)(rng);
    std::vector<float> d = randomDepth(rng, w, h);
    DepthPyramid p;
    p.build(d.data(), Rect{3, 5, w, h});
    ASSERT_EQ(p.width(p.levels() - 1), 1);
    ASSERT_EQ(p.height(p.levels() - 1), 1);
    for (int l = 0; l < p.levels(); ++l)
      for (int y = 0; y < p.height(l); ++y)
        for (int x = 0; x < p.width(l); ++x) {
          float m = INFINITY;
          for (int py = y << l; py < std::min(h, (y + 1) << l); ++py)
            for (int px = x << l; px < std::min(w, (x + 1) << l); ++px)
              m = std::min(m, d[size_t(py) * w + px]);
          ASSERT_EQ(p.texel(l, x, y), m) << "level " << l << " texel " << x << "," << y;
        }
  }
}

TEST(DepthPyramid, HidesEqualsThePerPixelCheck) {
  std::mt19937 rng(11);
  size_t hidden = 0, shown = 0;
  for (int trial = 0; trial < 300; ++trial) {
    int fw = std::uniform_int_distribution<int>(1, 200)(rng);
    int fh = std::uniform_int_distribution<int>(1, 200)(rng);
    Rect region{std::uniform_int_distribution<int>(0, fw - 1)(rng),
                std::uniform_int_distribution<int>(0, fh - 1)(rng), 0, 0};
    region.w = std::uniform_int_distribution<int>(1, fw - region.x)(rng);
    region.h = std::uniform_int_distribution<int>(1, fh - region.y)(rng);
    std::vector<float> d = randomDepth(rng, region.w, region.h);
    DepthPyramid p;
    p.build(d.data(), region);
    for (int k = 0; k < 60; ++k) {
      ScreenBound b = randomBound(rng, fw, fh);
      // Also depths exactly at a pixel's value: a tie is not hidden.
      if (k % 4 == 0 && !d.empty()) b.nearest = d[size_t(k) % d.size()];
      bool expected = hiddenByPixels(d, region, b);
      std::pair<int, int> seen{-1, -1};
      ASSERT_EQ(p.hides(b, 1 << 30, &seen), expected) << b << " region " << region;
      if (!expected && !b.reaches_near) {  // the witness: a pixel of the rectangle not nearer
        auto [x, y] = seen;
        ASSERT_TRUE(x >= std::max(b.x0, region.x) && x <= std::min(b.x1, region.x1() - 1) &&
                    y >= std::max(b.y0, region.y) && y <= std::min(b.y1, region.y1() - 1))
            << x << "," << y << " " << b;
        ASSERT_FALSE(double(d[size_t(y - region.y) * region.w + (x - region.x)]) >
                     b.bound(x, y, x, y));
      }
      // With a tiny budget the answer may turn to "visible", never to "hidden".
      if (p.hides(b, 2)) {
        ASSERT_TRUE(expected) << b;
      }
      (expected ? hidden : shown)++;
    }
  }
  EXPECT_GT(hidden, 1000u);  // the cases exercise both answers
  EXPECT_GT(shown, 1000u);
}

// update() after a change inside a rectangle gives every texel build()
// gives for the changed buffer: odd sizes, regions off the origin, dirty
// rectangles partly outside the region, single pixels.
TEST(DepthPyramid, UpdateEqualsARebuild) {
  std::mt19937 rng(31);
  for (int trial = 0; trial < 300; ++trial) {
    Rect region{std::uniform_int_distribution<int>(0, 40)(rng),
                std::uniform_int_distribution<int>(0, 40)(rng),
                std::uniform_int_distribution<int>(1, 150)(rng),
                std::uniform_int_distribution<int>(1, 150)(rng)};
    std::vector<float> d = randomDepth(rng, region.w, region.h);
    DepthPyramid updated, rebuilt;
    updated.build(d.data(), region);
    for (int change = 0; change < 3; ++change) {
      std::uniform_int_distribution<int> x(region.x - 10, region.x1() + 5),
          y(region.y - 10, region.y1() + 5), size(0, 60);
      Rect dirty{x(rng), y(rng), size(rng), size(rng)};
      std::uniform_real_distribution<float> depth(0.f, 1.f);
      for (int py = std::max(dirty.y, region.y); py < std::min(dirty.y1(), region.y1()); ++py)
        for (int px = std::max(dirty.x, region.x); px < std::min(dirty.x1(), region.x1()); ++px)
          d[size_t(py - region.y) * size_t(region.w) + size_t(px - region.x)] = depth(rng);
      updated.update(d.data(), dirty);
      rebuilt.build(d.data(), region);
      ASSERT_EQ(updated.levels(), rebuilt.levels());
      for (int l = 0; l < rebuilt.levels(); ++l)
        for (int ty = 0; ty < rebuilt.height(l); ++ty)
          for (int tx = 0; tx < rebuilt.width(l); ++tx)
            ASSERT_EQ(updated.texel(l, tx, ty), rebuilt.texel(l, tx, ty))
                << "trial " << trial << " level " << l << " texel " << tx << "," << ty << " dirty "
                << dirty << " region " << region;
    }
  }
}

TEST(DepthPyramid, NearPlaneBoundsAreNeverHidden) {
  std::vector<float> d(16 * 16, 1.f);  // everything at the near plane
  DepthPyramid p;
  p.build(d.data(), Rect{0, 0, 16, 16});
  ScreenBound b;
  b.reaches_near = true;
  EXPECT_FALSE(p.hides(b));
  ScreenBound tiny{false, 3, 3, 3, 3, 0.5};
  EXPECT_TRUE(p.hides(tiny));
  tiny.nearest = 1.0;  // a tie with the buffer
  EXPECT_FALSE(p.hides(tiny));
}

TEST(DepthPyramid, BoundsOutsideTheRegionAreHidden) {
  std::vector<float> d(8 * 8, 0.f);  // nothing drawn
  DepthPyramid p;
  p.build(d.data(), Rect{10, 10, 8, 8});
  EXPECT_TRUE(p.hides(ScreenBound{false, 0, 0, 9, 30, 0.9}));    // left of it
  EXPECT_FALSE(p.hides(ScreenBound{false, 0, 0, 10, 10, 0.9}));  // touches its first pixel
  EXPECT_TRUE(p.hides(ScreenBound{}));                           // empty rectangle
}

Camera randomCamera(std::mt19937& rng, double scale) {
  std::uniform_real_distribution<double> u(-1, 1);
  Camera c;
  c.eye = Vec3d{u(rng), u(rng), u(rng)} * scale;
  Quatd q{u(rng), u(rng), u(rng), u(rng)};
  double n = std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
  c.rotation = Quatd{q.x / n, q.y / n, q.z / n, q.w / n};
  c.fovy_deg = std::uniform_real_distribution<double>(20, 90)(rng);
  c.aspect = std::uniform_real_distribution<double>(0.5, 2)(rng);
  c.near = scale * std::pow(10.0, std::uniform_real_distribution<double>(-6, -2)(rng));
  return c;
}

// Every point of the box (corners, and random points inside) projects into
// the bound's rectangle (when on screen) with depth at most its nearest.
TEST(ScreenBound, HoldsEveryPointOfTheBox) {
  std::mt19937 rng(3);
  size_t bounded = 0, nearPlane = 0, subPixel = 0;
  for (int trial = 0; trial < 4000; ++trial) {
    // Scenes near the origin and far from it, small and large.
    double scale = std::pow(10.0, std::uniform_real_distribution<double>(-1, 4)(rng));
    Vec3d offset = trial % 3 == 0 ? Vec3d{1e6, -3e5, 2e6} : Vec3d{};
    Camera cam = randomCamera(rng, scale);
    cam.eye = cam.eye + offset;
    int w = std::uniform_int_distribution<int>(1, 1024)(rng);
    int h = std::uniform_int_distribution<int>(1, 1024)(rng);
    cam.aspect = double(w) / h;
    // A box somewhere in front of the camera, of random size (sub-pixel too).
    std::uniform_real_distribution<double> u(-1, 1);
    Vec3d dir = rotate(cam.rotation, normalize(Vec3d{u(rng) * 0.8, u(rng) * 0.8, -1}));
    double dist = scale * std::pow(10.0, std::uniform_real_distribution<double>(-5, 1)(rng));
    double size = dist * std::pow(10.0, std::uniform_real_distribution<double>(-6, 0.5)(rng));
    Vec3d c = cam.eye + dir * dist;
    Box3d box{c - Vec3d{size, size * 0.5, size * 0.3}, c + Vec3d{size * 0.7, size, size * 0.2}};
    ScreenBound b = screenBound(box, cam, w, h);
    ScreenBound rect = screenRect(box, cam, w, h), planeless = b;
    planeless.has_planes = false;
    planeless.planes = {};
    ASSERT_EQ(rect, planeless);  // the same bound without its planes
    if (b.reaches_near) {
      ++nearPlane;
      // Some corner really is at or before the near plane.
      Mat4d v = viewRotation(cam);
      bool some = false;
      for (int i = 0; i < 8; ++i) some |= -v.transformVector(box.corner(i) - cam.eye).z <= cam.near;
      ASSERT_TRUE(some) << box;
      continue;
    }
    ++bounded;
    if (b.x1 - b.x0 <= 2 && b.y1 - b.y0 <= 2) ++subPixel;
    Mat4d view = viewRotation(cam), proj = projectionMatrix(cam);
    std::vector<double> xs, ys;
    for (int k = 0; k < 40; ++k) {
      Vec3d t{(u(rng) + 1) / 2, (u(rng) + 1) / 2, (u(rng) + 1) / 2};
      if (k < 8) t = Vec3d{double(k & 1), double((k >> 1) & 1), double((k >> 2) & 1)};
      Vec3d p = box.lo + Vec3d{t.x * (box.hi.x - box.lo.x), t.y * (box.hi.y - box.lo.y),
                               t.z * (box.hi.z - box.lo.z)};
      Vec3d e = view.transformVector(p - cam.eye);
      double cw = -e.z;
      double ndcx = (proj.at(0, 0) * e.x) / cw, ndcy = (proj.at(1, 1) * e.y) / cw;
      double depth = cam.near / cw;
      ASSERT_LE(depth, b.nearest) << box << " " << cam;
      double px = (ndcx + 1) * 0.5 * w, py = (ndcy + 1) * 0.5 * h;
      // The entry-depth planes, at the point's own (continuous) pixel
      // position, bound it too: the ray there enters the box no farther.
      ASSERT_TRUE(b.has_planes);
      double entry = kNoDepthBound;
      for (const auto& k : b.planes)
        entry = std::min(entry, k[0] * (px - 0.5) + k[1] * (py - 0.5) + k[2]);
      ASSERT_LE(depth, entry * (1 + 1e-9) + 1e-12) << box << " " << cam;
      // Every pixel centre between two projected points of the box along
      // x (or y) lies within the span of the corners: inside the rectangle
      // (or off the frame).
      xs.push_back(px);
      ys.push_back(py);
    }
    for (auto [span, lo, hi, n] :
         {std::tuple{&xs, b.x0, b.x1, w}, std::tuple{&ys, b.y0, b.y1, h}}) {
      auto [mn, mx] = std::minmax_element(span->begin(), span->end());
      for (int i = int(std::ceil(*mn - 0.5)); i + 0.5 <= *mx; ++i)
        if (i >= 0 && i < n)
          ASSERT_TRUE(i >= lo && i <= hi) << i << " outside " << b << " for " << box;
        else if (i >= n)
          break;
      // ... and the rectangle is no wider than that span, rounded out.
      // (Checked on boxes wholly in the frame, where no clipping happens.)
      if (*mn >= 0 && *mx <= n && !b.empty()) {
        EXPECT_GE(lo + 0.5, *mn - 1.0 / 32) << b;
        EXPECT_LE(hi + 0.5, *mx + 1.0 / 32) << b;
      }
    }
  }
  EXPECT_GT(bounded, 1500u);
  EXPECT_GT(nearPlane, 20u);
  EXPECT_GT(subPixel, 100u);
}

// A part's bound is its rectangle within the object's, with the object's
// depth bound at every pixel (the depth clamp's guarantee, not the part's):
// so a pyramid that hides every part's bound has, at every pixel of every
// part's rectangle, depth strictly nearer than the object's own bound there.
TEST(PartBound, HidesOnlyWherePixelsAreNearerThanTheObjectsBound) {
  std::mt19937 rng(17);
  size_t culled = 0, kept = 0;
  for (int trial = 0; trial < 300; ++trial) {
    int fw = std::uniform_int_distribution<int>(1, 160)(rng);
    int fh = std::uniform_int_distribution<int>(1, 160)(rng);
    Rect region{0, 0, fw, fh};
    std::vector<float> d = randomDepth(rng, fw, fh);
    DepthPyramid p;
    p.build(d.data(), region);
    for (int k = 0; k < 40; ++k) {
      ScreenBound ob = randomBound(rng, fw, fh);
      std::vector<ScreenBound> parts;
      for (int n = std::uniform_int_distribution<int>(1, 8)(rng); n > 0; --n) {
        ScreenBound pb = randomBound(rng, fw, fh);  // depth ignored: the object's is taken
        pb.nearest = 2;
        pb.has_planes = false;
        parts.push_back(partBound(ob, pb));
        const ScreenBound& b = parts.back();
        ASSERT_EQ(b.nearest, ob.nearest);
        ASSERT_EQ(b.planes, ob.planes);
        if (!b.empty()) {
          ASSERT_TRUE(b.x0 >= ob.x0 && b.x1 <= ob.x1 && b.y0 >= ob.y0 && b.y1 <= ob.y1) << b;
          ASSERT_TRUE(b.x0 >= pb.x0 && b.x1 <= pb.x1 && b.y0 >= pb.y0 && b.y1 <= pb.y1) << b;
        }
      }
      bool all_hidden = std::all_of(parts.begin(), parts.end(),
                                    [&](const ScreenBound& b) { return p.hides(b, 1 << 30); });
      bool expected = std::all_of(parts.begin(), parts.end(), [&](const ScreenBound& b) {
        return hiddenByPixels(d, region, b);
      });
      ASSERT_EQ(all_hidden, expected);
      (all_hidden ? culled : kept)++;
    }
  }
  EXPECT_GT(culled, 500u);
  EXPECT_GT(kept, 500u);
  // Either reaching the near plane: the result does.
  ScreenBound a{false, 1, 2, 3, 4, 0.25}, n;
  n.reaches_near = true;
  EXPECT_TRUE(partBound(a, n).reaches_near);
  EXPECT_TRUE(partBound(n, a).reaches_near);
}

// A part widened by the object's margins: inside the object's query box,
// holding the part widened by at least what that box adds on each side.
TEST(QueryPartBounds, WidensThePartByTheObjectsMargins) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0, 1);
  for (int trial = 0; trial < 1000; ++trial) {
    double scale = std::pow(10.0, std::uniform_real_distribution<double>(-1, 4)(rng));
    Camera cam = randomCamera(rng, scale);
    if (trial % 2) cam.eye = cam.eye + Vec3d{1e6, -2e6, 5e5};
    Vec3d c = cam.eye + Vec3d{u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5} * (4 * scale);
    Box3d box{c, c + Vec3d{u(rng), u(rng), u(rng)} * scale};
    Box3d part;
    for (int a = 0; a < 3; ++a) {
      double x = box.lo[a] + (box.hi[a] - box.lo[a]) * u(rng);
      double y = box.lo[a] + (box.hi[a] - box.lo[a]) * u(rng);
      part.lo[a] = std::min(x, y);
      part.hi[a] = std::max(x, y);
    }
    Box3d q = queryBoxBounds(box, cam, 512), pq = queryPartBounds(part, box, q);
    for (int a = 0; a < 3; ++a) {
      ASSERT_GE(pq.lo[a], q.lo[a] - 1e-9 * scale);
      ASSERT_LE(pq.hi[a], q.hi[a] + 1e-9 * scale);
      double lo_margin = box.lo[a] - q.lo[a], hi_margin = q.hi[a] - box.hi[a];
      ASSERT_GT(lo_margin, 0);
      ASSERT_GT(hi_margin, 0);
      ASSERT_NEAR(part.lo[a] - pq.lo[a], lo_margin, 1e-9 * (scale + std::abs(box.lo[a])));
      ASSERT_NEAR(pq.hi[a] - part.hi[a], hi_margin, 1e-9 * (scale + std::abs(box.hi[a])));
    }
  }
}

// meets() against brute force over the cells: a rectangle meets the
// marked ones exactly when some cell it touches is touched by a marked one.
TEST(CellCoverage, MeetsEqualsTheCellsBruteForce) {
  std::mt19937 rng(23);
  size_t met = 0, missed = 0;
  for (int trial = 0; trial < 300; ++trial) {
    Rect region{std::uniform_int_distribution<int>(0, 50)(rng),
                std::uniform_int_distribution<int>(0, 50)(rng),
                std::uniform_int_distribution<int>(1, 300)(rng),
                std::uniform_int_distribution<int>(1, 300)(rng)};
    int shift = std::uniform_int_distribution<int>(0, 5)(rng);
    auto randomRect = [&] {
      std::uniform_int_distribution<int> x(region.x - 20, region.x1() + 20),
          y(region.y - 20, region.y1() + 20), size(-2, 60);
      return Rect{x(rng), y(rng), size(rng), size(rng)};
    };
    int cw = ((region.w - 1) >> shift) + 1, ch = ((region.h - 1) >> shift) + 1;
    std::vector<char> touched(size_t(cw) * size_t(ch), 0);
    auto forCells = [&](const Rect& r, auto f) {
      for (int py = std::max(r.y, region.y); py < std::min(r.y1(), region.y1()); ++py)
        for (int px = std::max(r.x, region.x); px < std::min(r.x1(), region.x1()); ++px)
          f(size_t((py - region.y) >> shift) * size_t(cw) + size_t((px - region.x) >> shift));
    };
    CellCoverage c(region, shift);
    for (int n = std::uniform_int_distribution<int>(0, 6)(rng); n > 0; --n) {
      Rect r = randomRect();
      c.mark(r);
      forCells(r, [&](size_t i) { touched[i] = 1; });
    }
    c.finish();
    for (int q = 0; q < 30; ++q) {
      Rect r = randomRect();
      bool expected = false;
      forCells(r, [&](size_t i) { expected = expected || touched[i]; });
      ASSERT_EQ(c.meets(r), expected) << r << " region " << region << " shift " << shift;
      (expected ? met : missed)++;
    }
  }
  EXPECT_GT(met, 1000u);
  EXPECT_GT(missed, 1000u);
}

TEST(ScreenBound, UniteCoversBoth) {
  ScreenBound a{false, 1, 2, 3, 4, 0.25}, b{false, 0, 5, 2, 9, 0.5};
  EXPECT_EQ(unite(a, b), (ScreenBound{false, 0, 2, 3, 9, 0.5}));
  ScreenBound n;
  n.reaches_near = true;
  EXPECT_TRUE(unite(a, n).reaches_near);
  EXPECT_EQ(unite(a, ScreenBound{}), (ScreenBound{false, 1, 2, 3, 4, 0.25}));
}

}  // namespace

namespace {

TEST(Rects, IntersectionAndBoundingRect) {
  Rect a{0, 0, 4, 3}, b{2, 1, 5, 5}, far{10, 10, 1, 1};
  EXPECT_EQ(intersection(a, b), (Rect{2, 1, 2, 2}));
  EXPECT_EQ(intersection(a, far), Rect{});
  EXPECT_EQ(boundingRect(a, b), (Rect{0, 0, 7, 6}));
  EXPECT_EQ(boundingRect(Rect{}, b), b);  // an empty rectangle adds nothing
  EXPECT_EQ(boundingRect(a, Rect{5, 5, 0, 3}), a);
}

TEST(CoverRects, CoversEveryPixelWithinTheLimitAndNoOverlap) {
  std::mt19937 rng(5);
  for (int trial = 0; trial < 300; ++trial) {
    std::vector<Rect> in;
    int n = std::uniform_int_distribution<int>(0, 40)(rng);
    for (int i = 0; i < n; ++i) {
      std::uniform_int_distribution<int> pos(0, 99), size(0, 20);
      in.push_back(Rect{pos(rng), pos(rng), size(rng), size(rng)});
    }
    size_t max = std::uniform_int_distribution<size_t>(1, 8)(rng);
    std::vector<Rect> out = coverRects(in, max);
    ASSERT_LE(out.size(), max);
    for (const Rect& r : in)
      for (int y = r.y; y < r.y1(); ++y)
        for (int x = r.x; x < r.x1(); ++x) {
          Rect px{x, y, 1, 1};
          ASSERT_TRUE(
              std::any_of(out.begin(), out.end(), [&](const Rect& o) { return overlaps(o, px); }))
              << "pixel " << x << "," << y << " of " << r << " not covered";
        }
    for (size_t i = 0; i < out.size(); ++i) {
      ASSERT_FALSE(out[i].empty());
      for (size_t j = i + 1; j < out.size(); ++j) ASSERT_FALSE(overlaps(out[i], out[j]));
    }
  }
}

TEST(CoverRects, KeepsDistantRectanglesApart) {
  std::vector<Rect> out = coverRects({Rect{0, 0, 2, 2}, Rect{100, 100, 2, 2}, Rect{}}, 4);
  EXPECT_EQ(out.size(), 2u);
  EXPECT_EQ(coverRects({Rect{0, 0, 2, 2}, Rect{1, 1, 2, 2}}, 4),
            (std::vector<Rect>{Rect{0, 0, 3, 3}}));
}

// reprojectDepth and shownFraction: a guess only, but points must land
// where the new camera sees them, at their depth, whatever the cameras'
// offset from the origin.

// The depth (near / distance) at which the ray through pixel (x, y)'s centre
// meets the plane z = plane_z, 0 if it does not.
float planeDepth(const Camera& c, int w, int h, int x, int y, double plane_z) {
  double f = 1.0 / std::tan(c.fovy_deg * M_PI / 360.0), fx = f / c.aspect;
  double u = (x + 0.5) * 2.0 / w - 1, v = (y + 0.5) * 2.0 / h - 1;
  Vec3d dir = rotate(c.rotation, Vec3d{u / fx, v / f, -1});
  double s = (plane_z - c.eye.z) / dir.z;  // eye distance: dir's eye-space z is -1
  return s > c.near ? float(c.near / s) : 0.f;
}

TEST(ReprojectDepth, TheSameCameraKeepsEachBlocksFarthestDepth) {
  std::mt19937 rng(11);
  const int fw = 64, fh = 48;
  const Rect region{3, 5, 41, 29};  // odd sizes: partial blocks at the ends
  Vec3d eye{1e6, -2e6, 350};
  Camera c{eye, lookAtRotation(eye, eye + Vec3d{3, 5, -10}, {0, 0, 1}), 45, double(fw) / fh, 0.1};
  std::vector<float> d = randomDepth(rng, region.w, region.h);
  DepthPyramid p;
  p.build(d.data(), region);
  for (int level : {1, 2}) {
    PredictedDepth out;
    reprojectDepth(p, level, c, c, fw, fh, region, &out);
    ASSERT_EQ(out.width, p.width(level));
    ASSERT_EQ(out.height, p.height(level));
    for (int y = 0; y < out.height; ++y)
      for (int x = 0; x < out.width; ++x) {
        float want = p.texel(level, x, y);
        ASSERT_NEAR(out.texel(x, y), want, 1e-5 * want)
            << "level " << level << " " << x << "," << y;
      }
  }
}

TEST(ReprojectDepth, APlaneSeenFromAnotherCameraLandsAtItsDepth) {
  const int fw = 96, fh = 80;
  const Vec3d base{-3e6, 4e5, 1200};  // far from the origin
  const double plane_z = base.z, dist = 10;
  // The new camera looks straight down at the plane, so that every pixel of
  // it sees the plane at `dist`; the old one stood aside and higher, tilted.
  Camera to{base + Vec3d{0, 0, dist}, Quatd{}, 45, double(fw) / fh, 0.1};
  Vec3d from_eye = base + Vec3d{1.5, -0.7, dist + 2};
  Camera from{from_eye, lookAtRotation(from_eye, base, {0, 1, 0}), 45, double(fw) / fh, 0.1};
  const Rect full{0, 0, fw, fh};
  std::vector<float> d(size_t(fw) * fh);
  for (int y = 0; y < fh; ++y)
    for (int x = 0; x < fw; ++x) d[size_t(y) * fw + x] = planeDepth(from, fw, fh, x, y, plane_z);
  DepthPyramid p;
  p.build(d.data(), full);
  const float want = float(to.near / dist);
  PredictedDepth out;
  reprojectDepth(p, 1, from, to, fw, fh, full, &out);
  int centre = 0, reached = 0;
  for (int y = 0; y < out.height; ++y)
    for (int x = 0; x < out.width; ++x) {
      float z = out.texel(x, y);
      // A block's farthest depth stands at its centre: off by the plane's
      // slope over a pixel, under 1% here.
      if (z != 0) {
        ASSERT_NEAR(z, want, 1e-2 * want) << x << "," << y;
      }
      if (std::abs(2 * x - fw / 2) < fw / 4 && std::abs(2 * y - fh / 2) < fh / 4) {
        ++centre;
        reached += z != 0;
      }
    }
  EXPECT_EQ(reached, centre) << "the old camera saw the middle: all of it is reached";
  // Moved past the plane, every point is behind the new camera: nothing.
  Camera below = to;
  below.eye.z = plane_z - 1;
  reprojectDepth(p, 1, from, below, fw, fh, full, &out);
  EXPECT_TRUE(std::all_of(out.texels.begin(), out.texels.end(), [](float z) { return z == 0; }));
}

TEST(ReprojectDepth, WhatWasNeverSeenIsLeftFarAndBackgroundMovesWithTheRotation) {
  const int fw = 64, fh = 64;
  const Rect full{0, 0, fw, fh};
  Camera from{{5, 5, 5}, Quatd{}, 45, 1, 0.1};
  // Turned 10 degrees about the vertical (of a 45-degree view): a strip at
  // one side was never seen.
  Camera to = from;
  to.rotation = Quatd{0, std::sin(M_PI / 36), 0, std::cos(M_PI / 36)};
  std::vector<float> wall(size_t(fw) * fh, 0.5f), sky(size_t(fw) * fh, 0.f);
  DepthPyramid p;
  p.build(wall.data(), full);
  PredictedDepth out;
  reprojectDepth(p, 1, from, to, fw, fh, full, &out);
  size_t unseen = size_t(std::count(out.texels.begin(), out.texels.end(), 0.f));
  EXPECT_GT(unseen, out.texels.size() / 8);
  EXPECT_LT(unseen, out.texels.size() / 3);
  // Background (nothing drawn) is a direction: turning moves it, moving
  // does not, and it stays 0 (nothing hides behind it).
  p.build(sky.data(), full);
  to.eye = from.eye + Vec3d{100, 0, 0};
  reprojectDepth(p, 1, from, to, fw, fh, full, &out);
  EXPECT_TRUE(std::all_of(out.texels.begin(), out.texels.end(), [](float z) { return z == 0; }));
}

TEST(ShownFraction, CountsTheTexelsWhereTheBoundIsNotStrictlyBehind) {
  PredictedDepth p;
  p.region = Rect{10, 20, 64, 32};
  p.level = 1;
  p.width = 32;
  p.height = 16;
  // Left half near (0.8), right half nothing drawn.
  p.texels.assign(size_t(p.width) * p.height, 0.f);
  for (int y = 0; y < p.height; ++y)
    for (int x = 0; x < p.width / 2; ++x) p.texels[size_t(y) * p.width + x] = 0.8f;
  auto box = [](int x0, int y0, int x1, int y1, double nearest) {
    ScreenBound b;
    b.x0 = x0, b.y0 = y0, b.x1 = x1, b.y1 = y1, b.nearest = nearest;
    return b;
  };
  EXPECT_EQ(shownFraction(p, box(10, 20, 41, 51, 0.5)), 0.0) << "behind the near half";
  EXPECT_EQ(shownFraction(p, box(10, 20, 41, 51, double(0.8f))), 1.0) << "a tie is not behind";
  EXPECT_EQ(shownFraction(p, box(42, 20, 73, 51, 0.1)), 1.0) << "nothing drawn there";
  EXPECT_NEAR(shownFraction(p, box(10, 20, 73, 51, 0.5)), 0.5, 0.07) << "half and half";
  EXPECT_EQ(shownFraction(p, box(0, 0, 9, 19, 0.5)), 0.0) << "outside the region";
  EXPECT_EQ(shownFraction(p, box(-5, 20, 20, 30, 0.5)), 0.0) << "clipped to the region";
  ScreenBound near_plane;
  near_plane.reaches_near = true;
  EXPECT_EQ(shownFraction(p, near_plane), 1.0);
}

}  // namespace
