// The ray tracer without GL (client/raytrace.h): shadows and mirror
// reflections on hand-made scenes, predicted pixel by pixel from the analytic
// rays; BVH memory; regions and thread counts giving the same pixels. The
// comparison with the raster path is raytrace_raster_test.cpp.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <random>

#include "error.h"
#include "raytrace.h"
#include "raytrace_scenes.h"

using namespace dmmr;
using namespace dmmr::rtscenes;

namespace {

constexpr int kW = 160, kH = 120;

const uint8_t* px(const std::vector<uint8_t>& rgba, int x, int y) {
  return &rgba[(size_t(y) * kW + size_t(x)) * 4];
}

std::vector<uint8_t> renderFrame(RayTracer& rt, const Camera& cam,
                                 const std::vector<RtInstance>& inst, const RayOptions& o) {
  std::vector<uint8_t> rgba;
  rt.render(cam, kW, kH, {0, 0, kW, kH}, inst, {}, o, &rgba);
  return rgba;
}

// Where the ray eye + t d meets the floor z = 0 (t, point p), if it does
// within |x|, |y| <= half.
bool floorPoint(Vec3d eye, Vec3d d, double half, double* t, Vec3d* p) {
  if (d.z >= 0) return false;
  *t = -eye.z / d.z;
  *p = eye + d * *t;
  return std::abs(p->x) <= half && std::abs(p->y) <= half;
}

}  // namespace

// A grey floor (z = 0) and a box floating above it, lit from straight above:
// the floor under the box, where the camera sees floor (not the box), is in
// shadow (0.3 base) and the floor away from it is lit (1.0 base, n . l = 1).
// With shadows off, the same pixels have the headlight shading and nothing
// marks the shadow.
TEST(RayTrace, ShadowFallsUnderTheBlockerAndNowhereElse) {
  RayTracer rt(2);
  const float grey = 0.7f;
  auto floor = rt.build(quad(-6, 6, -6, 6, grey, grey, grey));
  const Box3d blocker = makeBox({-0.5, -0.5, 1.0}, {0.5, 0.5, 2.0});
  auto cube = rt.build(box(blocker.lo, blocker.hi, 0.9f, 0.2f, 0.2f));
  std::vector<RtInstance> inst = {{floor.get(), Mat4d::identity(), SurfaceEffect::None},
                                  {cube.get(), Mat4d::identity(), SurfaceEffect::None}};
  Camera cam = lookAt({0.3, -4.5, 4.0}, {0, 0, 0}, kW, kH);
  RayOptions on;
  on.shadows = true;
  on.light = {0, 0, 1};
  RayOptions off = on;
  off.shadows = false;
  std::vector<uint8_t> with = renderFrame(rt, cam, inst, on);
  std::vector<uint8_t> without = renderFrame(rt, cam, inst, off);

  const int lit = unorm8(grey), dark = unorm8(0.3 * grey);
  int shadowed = 0, lit_px = 0, wrong = 0;
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      Vec3d d = pixelRay(cam, kW, kH, x, y), p;
      double t = 0;
      if (!floorPoint(cam.eye, d, 5.9, &t, &p)) continue;
      // Floor pixels only, well clear of the box's outline.
      if (rayBox(cam.eye, d, grow(blocker, 0.05)) < t) continue;
      double r = std::max(std::abs(p.x), std::abs(p.y));
      const uint8_t* a = px(with, x, y);
      const uint8_t* b = px(without, x, y);
      // Headlight shading of the floor: |n . v| with n = +Z.
      int head = unorm8(grey * (0.3 + 0.7 * std::abs(d.z) / length(d)));
      bool headOk = std::abs(b[0] - head) <= 1 && b[0] == b[1] && b[1] == b[2];
      if (r < 0.45) {
        ++shadowed;
        wrong += std::abs(a[0] - dark) > 1 || !headOk;
      } else if (r > 0.55) {
        ++lit_px;
        wrong += std::abs(a[0] - lit) > 1 || !headOk;
      }
    }
  EXPECT_GT(shadowed, 100) << "the scene must show the shadowed floor";
  EXPECT_GT(lit_px, 1000);
  EXPECT_EQ(wrong, 0) << "of " << shadowed << " shadowed and " << lit_px << " lit floor pixels";
}

// A mirror floor under a red box, the camera looking at the floor in front
// of it: where the reflected ray meets the box the floor is red (0.2 floor +
// 0.8 box), elsewhere it is not; with reflections off, nowhere.
TEST(RayTrace, MirrorFloorReflectsTheRedBox) {
  RayTracer rt(2);
  auto floor = rt.build(quad(-8, 8, -8, 8, 0.6f, 0.6f, 0.6f));
  const Box3d red = makeBox({-0.6, -0.6, 0.0}, {0.6, 0.6, 1.2});
  auto cube = rt.build(box(red.lo, red.hi, 0.9f, 0.1f, 0.1f));
  std::vector<RtInstance> inst = {{floor.get(), Mat4d::identity(), SurfaceEffect::Mirror},
                                  {cube.get(), Mat4d::identity(), SurfaceEffect::None}};
  // Low and close, looking down at the floor before the box, so that the box
  // itself is at the top of the frame and its reflection below it.
  Camera cam = lookAt({0, -4, 1.0}, {0, -0.8, 0.05}, kW, kH);
  RayOptions on;
  on.reflections = true;
  RayOptions off;
  std::vector<uint8_t> with = renderFrame(rt, cam, inst, on);
  std::vector<uint8_t> without = renderFrame(rt, cam, inst, off);
  auto reddish = [](const uint8_t* p) { return p[0] > p[1] + 40 && p[0] > p[2] + 40; };

  int mirrored = 0, plain = 0, wrong = 0, wrong_off = 0;
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      Vec3d d = pixelRay(cam, kW, kH, x, y), p;
      double t = 0;
      if (!floorPoint(cam.eye, d, 7.9, &t, &p)) continue;
      if (rayBox(cam.eye, d, grow(red, 0.05)) < t) continue;  // the box itself
      Vec3d r{d.x, d.y, -d.z};                                // reflected off z = 0
      bool hits = rayBox(p, r, grow(red, -0.05)) < 1e30;
      bool misses = rayBox(p, r, grow(red, 0.05)) > 1e30;
      if (hits) {
        ++mirrored;
        wrong += !reddish(px(with, x, y));
      } else if (misses) {
        ++plain;
        wrong += reddish(px(with, x, y));
      }
      wrong_off += (hits || misses) && reddish(px(without, x, y));
    }
  EXPECT_GT(mirrored, 200) << "the reflection must cover part of the frame";
  EXPECT_GT(plain, 200);
  EXPECT_EQ(wrong, 0) << "of " << mirrored << " reflecting and " << plain << " other pixels";
  EXPECT_EQ(wrong_off, 0) << "reflections off";
}

// Depth bounds recursion: a camera between two parallel mirrors sees a
// corridor of reflections; with max_depth 0 the mirrors are shaded locally
// and show no reflection at all.
TEST(RayTrace, MaxDepthZeroShadesMirrorsLocally) {
  RayTracer rt(1);
  auto floor = rt.build(quad(-8, 8, -8, 8, 0.6f, 0.6f, 0.6f));
  auto cube = rt.build(box({-0.6, -0.6, 0}, {0.6, 0.6, 1.2}, 0.9f, 0.1f, 0.1f));
  std::vector<RtInstance> inst = {{floor.get(), Mat4d::identity(), SurfaceEffect::Mirror},
                                  {cube.get(), Mat4d::identity(), SurfaceEffect::None}};
  Camera cam = lookAt({0, -4, 1.0}, {0, -0.8, 0.05}, kW, kH);
  RayOptions o;
  o.reflections = true;
  o.max_depth = 0;
  EXPECT_EQ(renderFrame(rt, cam, inst, o), renderFrame(rt, cam, inst, RayOptions{}));
  o.max_depth = 1;
  EXPECT_NE(renderFrame(rt, cam, inst, o), renderFrame(rt, cam, inst, RayOptions{}));
}

// A white glass slab between the camera and a red floor, seen head-on: at
// normal incidence Schlick's Fresnel term is 0.04 per surface, so the floor
// shows through nearly as bright as beside the slab, and in place (no bend at
// normal incidence); with reflections off the slab is opaque white.
TEST(RayTrace, GlassSlabTransmitsAtNormalIncidence) {
  RayTracer rt(2);
  auto floor = rt.build(quad(-4, 4, -4, 4, 0.9f, 0.1f, 0.1f));
  auto slab = rt.build(box({-1, -1, 2}, {1, 1, 2.1}, 1, 1, 1));
  std::vector<RtInstance> inst = {{floor.get(), Mat4d::identity(), SurfaceEffect::None},
                                  {slab.get(), Mat4d::identity(), SurfaceEffect::Glass}};
  Camera cam = lookAt({0, 0, 5}, {0, 0, 0}, kW, kH, {0, 1, 0});
  RayOptions on;
  on.reflections = true;
  std::vector<uint8_t> with = renderFrame(rt, cam, inst, on);
  std::vector<uint8_t> without = renderFrame(rt, cam, inst, RayOptions{});
  const uint8_t* centre = px(with, kW / 2, kH / 2);
  const uint8_t* opaque = px(without, kW / 2, kH / 2);
  EXPECT_EQ(opaque[0], 255);
  EXPECT_EQ(opaque[1], 255);
  // The floor seen head-on at the centre: 0.9 red (|n . v| = 1 up to half a
  // pixel).
  const double head_on = 0.9 * 255;
  // Through the slab: (1 - 0.04)^2 of it, plus a little reflected background
  // and light bounced inside the slab (at most a few levels).
  EXPECT_GE(centre[0], 0.96 * 0.96 * head_on - 2);
  EXPECT_LE(centre[0], 0.96 * 0.96 * head_on + 8);
  EXPECT_LT(centre[0], head_on - 5) << "Fresnel reflection takes some light";
  EXPECT_LT(centre[1], 40);
  // Beside the slab, the floor as without it.
  Vec3d d = pixelRay(cam, kW, kH, 4, kH / 2);
  EXPECT_NEAR(px(with, 4, kH / 2)[0], unorm8(0.9 * (0.3 + 0.7 * std::abs(d.z) / length(d))), 1);
}

// BVH memory as Embree reports it: more triangles, more bytes; the bytes
// held include the BVH; the compact layout takes no more than the default.
TEST(RayTrace, BvhBytesGrowWithTrianglesAndCompactIsSmaller) {
  RayTracer rt(2);
  GeometryData small = grid(20), big = grid(80);
  for (BvhQuality q : {BvhQuality::Low, BvhQuality::Medium, BvhQuality::High}) {
    auto a = rt.build(small, q), b = rt.build(big, q);
    auto c = rt.build(big, q, true);
    EXPECT_EQ(a->triangles(), small.triangleCount());
    EXPECT_EQ(b->triangles(), big.triangleCount());
    EXPECT_GT(a->bvhBytes(), 0u);
    EXPECT_GE(a->bytes(), a->bvhBytes() + small.positions.size() * 4 + small.indices.size() * 4);
    EXPECT_GT(b->bvhBytes(), a->bvhBytes());
    EXPECT_GT(b->bytes(), a->bytes());
    EXPECT_LE(c->bvhBytes(), b->bvhBytes());
    EXPECT_LE(c->bytes(), b->bytes());
    std::cout << "quality " << int(q) << ": BVH bytes/triangle " << b->bvhBytes() / 12800.0
              << ", compact " << c->bvhBytes() / 12800.0 << "\n";
  }
  // The count is per mesh: the same mesh built twice reports the same bytes
  // (within Embree's allocation slack), whatever was built before.
  auto d = rt.build(big), e = rt.build(big);
  EXPECT_NEAR(double(d->bvhBytes()), double(e->bvhBytes()), 0.1 * double(d->bvhBytes()));
}

// A region renders the same pixels as that part of the full frame, whatever
// the number of threads.
TEST(RayTrace, RegionsAndThreadCountsGiveTheSamePixels) {
  RayTracer one(1), two(2);
  auto m1 = one.build(box({-1, -1, -1}, {1, 1, 1}, 0.3f, 0.6f, 0.9f, false, true));
  auto m2 = two.build(box({-1, -1, -1}, {1, 1, 1}, 0.3f, 0.6f, 0.9f, false, true));
  Mat4d t = Mat4d::translate({0.2, 0.1, 0}) * Mat4d::rotation(lookRotation({1, 2, 0.5}, {0, 0, 1}));
  Camera cam = lookAt({3, -4, 2}, {0, 0, 0}, kW, kH);
  std::vector<uint8_t> full1, full2, part;
  one.render(cam, kW, kH, {0, 0, kW, kH}, {{m1.get(), t, SurfaceEffect::None}}, {}, {}, &full1);
  two.render(cam, kW, kH, {0, 0, kW, kH}, {{m2.get(), t, SurfaceEffect::None}}, {}, {}, &full2);
  EXPECT_EQ(full1, full2);
  const Rect r{37, 21, 61, 45};
  two.render(cam, kW, kH, r, {{m2.get(), t, SurfaceEffect::None}}, {}, {}, &part);
  ASSERT_EQ(part.size(), size_t(r.area()) * 4);
  int covered = 0;
  for (int y = 0; y < r.h; ++y)
    for (int x = 0; x < r.w; ++x) {
      const uint8_t* a = &part[(size_t(y) * r.w + x) * 4];
      const uint8_t* b = px(full2, r.x + x, r.y + y);
      ASSERT_EQ(std::memcmp(a, b, 4), 0) << "pixel " << r.x + x << "," << r.y + y;
      covered += a[0] != 51;  // not the default background's red (0.2)
    }
  EXPECT_GT(covered, r.area() / 4) << "the region must show the box";
}

TEST(RayTrace, BadInputIsAnError) {
  RayTracer rt(1);
  GeometryData g = quad(0, 1, 0, 1, 1, 1, 1);
  g.indices[2] = 99;
  EXPECT_THROW(rt.build(g), Error);
  g = quad(0, 1, 0, 1, 1, 1, 1);
  g.submeshes[0].index_count = 9;
  EXPECT_THROW(rt.build(g), Error);
  g = quad(0, 1, 0, 1, 1, 1, 1);
  g.normals.pop_back();
  EXPECT_THROW(rt.build(g), Error);
  std::vector<uint8_t> rgba;
  Camera cam = lookAt({0, 0, 5}, {0, 0, 0}, kW, kH, {0, 1, 0});
  EXPECT_THROW(rt.render(cam, kW, kH, {100, 0, 100, 10}, {}, {}, {}, &rgba), Error);
  RayTracer other(1);
  auto m = other.build(quad(0, 1, 0, 1, 1, 1, 1));
  EXPECT_THROW(
      rt.render(cam, kW, kH, {0, 0, kW, kH}, {{m.get(), Mat4d::identity()}}, {}, {}, &rgba), Error);
  for (int stride : {0, kMaxRayStride + 1}) {
    RayOptions o;
    o.stride = stride;
    EXPECT_THROW(rt.render(cam, kW, kH, {0, 0, kW, kH}, {}, {}, o, &rgba), Error) << stride;
  }
}

// ---- the top level, kept from call to call ---------------------------------

namespace {

// A row of coloured boxes on a floor, object i at x = 2 i.
struct Row {
  std::unique_ptr<RtMesh> floor, box;
  std::vector<RtInstance> all;
  Row(RayTracer& rt, int n) {
    floor = rt.build(quad(-4, 4 * n, -6, 6, 0.6f, 0.6f, 0.6f));
    box = rt.build(box_(0.3f, 0.5f, 0.9f));
    all.push_back({floor.get(), Mat4d::identity(), SurfaceEffect::None, 0});
    for (int i = 0; i < n; ++i)
      all.push_back(
          {box.get(), Mat4d::translate({2.0 * i, 0, 0}), SurfaceEffect::None, uint32_t(i + 1)});
  }
  static GeometryData box_(float r, float g, float b) {
    return rtscenes::box({-0.5, -0.5, 0}, {0.5, 0.5, 1}, r, g, b);
  }
};

}  // namespace

TEST(RayTraceTopLevel, TheSameObjectsAgainCostNothingAndGiveTheSamePixels) {
  RayTracer rt(2);
  Row row(rt, 8);
  Camera cam = lookAt({4, -12, 6}, {6, 0, 0}, kW, kH);
  std::vector<uint8_t> a, b;
  RtRenderStats first = rt.render(cam, kW, kH, {0, 0, kW, kH}, row.all, {}, {}, &a);
  EXPECT_TRUE(first.rebuilt);
  EXPECT_EQ(first.updated, 2 * row.all.size()) << "each bound and placed once";
  RtRenderStats again = rt.render(cam, kW, kH, {0, 0, kW, kH}, row.all, {}, {}, &b);
  EXPECT_EQ(again.updated, 0u);
  EXPECT_FALSE(again.rebuilt);
  EXPECT_FALSE(again.reanchored);
  EXPECT_EQ(a, b);
  // With a version, the same list is not even compared; a new version is.
  std::vector<RtInstance> fewer(row.all.begin(), row.all.begin() + 3);
  std::vector<uint8_t> c, d;
  rt.render(cam, kW, kH, {0, 0, kW, kH}, fewer, {}, {}, &c, {}, 7);
  RtRenderStats promised = rt.render(cam, kW, kH, {0, 0, kW, kH}, fewer, {}, {}, &d, {}, 7);
  EXPECT_EQ(promised.updated, 0u);
  EXPECT_FALSE(promised.rebuilt);
  EXPECT_EQ(c, d);
  RtRenderStats changed = rt.render(cam, kW, kH, {0, 0, kW, kH}, row.all, {}, {}, &d, {}, 8);
  EXPECT_EQ(changed.updated, 2 * (row.all.size() - fewer.size())) << "bound and placed";
  EXPECT_EQ(d, a);
}

// Whatever came before, a frame shows exactly its own objects: the pixels of
// a kept top level equal a fresh tracer's after objects leave, come back,
// change mesh and move, and after a mesh is destroyed between frames.
TEST(RayTraceTopLevel, AKeptTopLevelRendersExactlyTheGivenObjects) {
  RayTracer kept(2);
  Row row(kept, 8);
  auto red = kept.build(Row::box_(0.9f, 0.1f, 0.1f));
  Camera cam = lookAt({4, -12, 6}, {6, 0, 0}, kW, kH);
  auto fresh = [&](const std::vector<RtInstance>& inst) {
    RayTracer rt(2);  // meshes of another tracer are refused: rebuild them here
    auto floor = rt.build(quad(-4, 32, -6, 6, 0.6f, 0.6f, 0.6f));
    auto blue = rt.build(Row::box_(0.3f, 0.5f, 0.9f)), r = rt.build(Row::box_(0.9f, 0.1f, 0.1f));
    std::vector<RtInstance> mine = inst;
    for (RtInstance& in : mine)
      in.mesh = in.mesh == row.floor.get() ? floor.get()
                : in.mesh == red.get()     ? r.get()
                                           : blue.get();
    std::vector<uint8_t> out;
    rt.render(cam, kW, kH, {0, 0, kW, kH}, mine, {}, {}, &out);
    return out;
  };
  auto check = [&](const std::vector<RtInstance>& inst, const char* what) {
    std::vector<uint8_t> out;
    kept.render(cam, kW, kH, {0, 0, kW, kH}, inst, {}, {}, &out);
    EXPECT_EQ(out, fresh(inst)) << what;
  };
  check(row.all, "all");
  std::vector<RtInstance> some(row.all.begin(), row.all.begin() + 4);
  check(some, "the last five boxes left");
  some.push_back(row.all[7]);
  some[2].mesh = red.get();
  some[1].object_to_world = Mat4d::translate({1, 2, 0});
  check(some, "one back, one red, one moved");
  std::reverse(some.begin(), some.end());
  check(some, "the same objects in another order");
  const RtMesh* gone = red.get();
  some.erase(std::remove_if(some.begin(), some.end(),
                            [&](const RtInstance& in) { return in.mesh == gone; }),
             some.end());
  red.reset();  // destroyed between frames: its slot leaves the top level
  check(some, "after the red mesh was destroyed");
  check(row.all, "all again");
}

TEST(RayTraceTopLevel, TheAnchorIsTheEyesGridPointAndMovesWhenThatDoes) {
  EXPECT_EQ(anchorFor({1.2, -3.7, 100.1}, 0), (Vec3d{1.2, -3.7, 100.1}));
  EXPECT_EQ(anchorFor({1.2, -3.7, 100.1}, 4), (Vec3d{0, -4, 100}));
  EXPECT_EQ(anchorFor({1e9 + 3, 2.5, -2.5}, 2), (Vec3d{1e9 + 4, 2, -2}));  // ties to even
  RayTracer kept(2);
  Row row(kept, 8);
  RayOptions o;
  o.anchor_grid = 8;
  Camera first = lookAt({4.5, -12.5, 6}, {6, 0, 0}, kW, kH);  // grid point (8, -16, 8)
  std::vector<uint8_t> a;
  EXPECT_TRUE(kept.render(first, kW, kH, {0, 0, kW, kH}, row.all, {}, o, &a).reanchored);
  // A step within the grid cell keeps the anchor: nothing to set again.
  Camera step = lookAt({5, -13, 6.5}, {6, 0, 0}, kW, kH);
  RtRenderStats s = kept.render(step, kW, kH, {0, 0, kW, kH}, row.all, {}, o, &a);
  EXPECT_FALSE(s.reanchored);
  EXPECT_EQ(s.updated, 0u);
  // Into another cell: a new anchor, every transform set again.
  Camera far_cam = lookAt({4, -12 - 200, 6}, {6, 0, 0}, kW, kH);
  s = kept.render(far_cam, kW, kH, {0, 0, kW, kH}, row.all, {}, o, &a);
  EXPECT_TRUE(s.reanchored);
  EXPECT_EQ(s.updated, row.all.size());
  // Whatever came before, the pixels are a fresh tracer's for that eye.
  for (const Camera* c : {&step, &far_cam}) {
    std::vector<uint8_t> mine, fresh;
    kept.render(*c, kW, kH, {0, 0, kW, kH}, row.all, {}, o, &mine);
    RayTracer other(2);
    Row row2(other, 8);
    other.render(*c, kW, kH, {0, 0, kW, kH}, row2.all, {}, o, &fresh);
    EXPECT_EQ(mine, fresh) << *c;
  }
}

TEST(RayTraceTopLevel, AnObjectGivenTwiceIsAnError) {
  RayTracer rt(1);
  Row row(rt, 2);
  std::vector<RtInstance> twice = row.all;
  twice.push_back(row.all[1]);
  std::vector<uint8_t> out;
  Camera cam = lookAt({4, -12, 6}, {0, 0, 0}, kW, kH);
  EXPECT_THROW(rt.render(cam, kW, kH, {0, 0, kW, kH}, twice, {}, {}, &out), Error);
  EXPECT_NO_THROW(rt.render(cam, kW, kH, {0, 0, kW, kH}, row.all, {}, {}, &out));
}

// ---- fewer rays: a pixel stride, upsampled -----------------------------------

TEST(RayStride, TheGridIsTheFramesAndEveryPixelLiesBetweenFourSamples) {
  EXPECT_EQ(rayStrideGrid({3, 5, 10, 7}, 1), (RayGrid{3, 5, 10, 7, 1}));
  std::mt19937 rng(5);
  for (int trial = 0; trial < 2000; ++trial) {
    int s = 2 + int(rng() % 7);
    Rect r{int(rng() % 300), int(rng() % 300), 1 + int(rng() % 100), 1 + int(rng() % 100)};
    RayGrid g = rayStrideGrid(r, s);
    ASSERT_EQ(g.stride, s);
    EXPECT_EQ(g.x % s, 0);
    EXPECT_EQ(g.y % s, 0);
    for (int x : {r.x, r.x1() - 1}) {
      int i = (x - g.x) / s;
      EXPECT_GE(x - g.x, 0);
      EXPECT_LT(i + 1, g.w) << r << " stride " << s;
    }
    for (int y : {r.y, r.y1() - 1}) {
      int j = (y - g.y) / s;
      EXPECT_GE(y - g.y, 0);
      EXPECT_LT(j + 1, g.h) << r << " stride " << s;
    }
    // No more samples than the cells need.
    EXPECT_LE(g.w, r.w / s + 3);
    EXPECT_LE(g.h, r.h / s + 3);
  }
}

// Samples taken from a function of the pixel: a linear ramp comes back
// exactly (to rounding), the samples' own pixels exactly, and any region
// gives the pixels the whole frame gives.
TEST(RayStride, UpsamplingIsBilinearAndDoesNotDependOnTheRegion) {
  const int w = 61, h = 37;
  auto value = [](int x, int y, int ch) { return (x * 3 + y * 2 + ch * 17) % 256; };
  auto upsample = [&](const Rect& r, int s) {
    RayGrid g = rayStrideGrid(r, s);
    std::vector<uint8_t> samples(size_t(g.w) * g.h * 4), out(size_t(r.area()) * 4);
    for (int j = 0; j < g.h; ++j)
      for (int i = 0; i < g.w; ++i)
        for (int ch = 0; ch < 4; ++ch)
          samples[(size_t(j) * g.w + i) * 4 + ch] = uint8_t(value(g.x + i * s, g.y + j * s, ch));
    upsampleStrided(g, samples.data(), r, out.data());
    return out;
  };
  for (int s : {2, 3, 4}) {
    std::vector<uint8_t> whole = upsample({0, 0, w, h}, s);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        for (int ch = 0; ch < 3; ++ch) {
          int got = whole[(size_t(y) * w + x) * 4 + ch];
          if (x % s == 0 && y % s == 0) {
            EXPECT_EQ(got, value(x, y, ch)) << x << "," << y;
          }
        }
    // A ramp without wrap-around: exact to rounding everywhere.
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        int got = whole[(size_t(y) * w + x) * 4 + 3];  // channel 3: 3x + 2y + 51, no wrap below 256
        if (3 * (x / s * s + s) + 2 * (y / s * s + s) + 51 < 256) {
          EXPECT_NEAR(got, 3 * x + 2 * y + 51, 0.5 + 1e-9) << x << "," << y << " stride " << s;
        }
      }
    std::mt19937 rng(s);
    for (int trial = 0; trial < 50; ++trial) {
      Rect r{int(rng() % w), int(rng() % h), 0, 0};
      r.w = 1 + int(rng() % (w - r.x));
      r.h = 1 + int(rng() % (h - r.y));
      std::vector<uint8_t> part = upsample(r, s);
      for (int y = 0; y < r.h; ++y)
        for (int x = 0; x < r.w; ++x)
          for (int ch = 0; ch < 4; ++ch)
            ASSERT_EQ(part[(size_t(y) * r.w + x) * 4 + ch],
                      whole[(size_t(y + r.y) * w + x + r.x) * 4 + ch])
                << r << " stride " << s;
    }
  }
}

// Traced: a strided frame's sample pixels are the full frame's, and regions
// of it are the whole strided frame's pixels.
TEST(RayStride, StridedFramesKeepTheSampledPixelsAndDoNotDependOnTheRegion) {
  RayTracer rt(2);
  Row row(rt, 8);
  Camera cam = lookAt({4, -12, 6}, {6, 0, 0}, kW, kH);
  RayOptions full, strided;
  strided.stride = 3;
  std::vector<uint8_t> a, b;
  rt.render(cam, kW, kH, {0, 0, kW, kH}, row.all, {}, full, &a);
  rt.render(cam, kW, kH, {0, 0, kW, kH}, row.all, {}, strided, &b);
  int differing = 0;
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      bool diff = std::memcmp(px(a, x, y), px(b, x, y), 4) != 0;
      if (x % 3 == 0 && y % 3 == 0)
        EXPECT_FALSE(diff) << x << "," << y;
      else
        differing += diff;
    }
  EXPECT_GT(differing, 0) << "the interpolated pixels are not all exact";
  for (Rect r : {Rect{0, 0, 80, 120}, Rect{80, 0, 80, 120}, Rect{17, 23, 61, 41}}) {
    std::vector<uint8_t> part;
    rt.render(cam, kW, kH, r, row.all, {}, strided, &part);
    for (int y = 0; y < r.h; ++y)
      ASSERT_EQ(0, std::memcmp(&part[size_t(y) * r.w * 4], px(b, r.x, r.y + y), size_t(r.w) * 4))
          << r << " row " << y;
  }
}
