// The visibility stage's query mechanism at the GL level, on OSMesa: occluders
// drawn into depth with Renderer::beginDepthFrame and draw(), then boxes
// tested with beginQueries / queryBox / endQueries, exactly as the client's
// visibility stage does.
//
// The camera sits at the origin looking down -Z with a 90 degree field of
// view on a 64 x 64 frame, so at distance D the frame spans x, y in [-D, D]
// and one pixel is 2D/64 wide.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <memory>
#include <random>
#include <vector>

#include "cluster.h"
#include "depth_pyramid.h"
#include "draw.h"
#include "formats.h"
#include "gl_context.h"
#include "visibility.h"

using namespace dmmr;

namespace {

constexpr int kSize = 64;

Box3d box(Vec3d lo, Vec3d hi) {
  Box3d b;
  b.lo = lo;
  b.hi = hi;
  return b;
}

// An axis-aligned quad facing the camera: x in [x0, x1], y in [y0, y1], at z,
// grey or the given red.
GeometryData quad(double x0, double x1, double y0, double y1, double z, float red = 0.8f) {
  GeometryData g;
  g.positions = {float(x0), float(y0), float(z), float(x1), float(y0), float(z),
                 float(x1), float(y1), float(z), float(x0), float(y1), float(z)};
  g.indices = {0, 1, 2, 0, 2, 3};
  SubMesh s;
  s.first_index = 0;
  s.index_count = 6;
  s.diffuse[0] = red;
  g.submeshes = {s};
  return g;
}

// The box of a mesh's positions (its bounds when drawn untransformed).
Box3d positionBox(const GeometryData& g) {
  Box3d b;
  for (size_t i = 0; i + 2 < g.positions.size(); i += 3)
    b.expand(Vec3d{g.positions[i], g.positions[i + 1], g.positions[i + 2]});
  return b;
}

// Appends `b` to `a` as more triangles of the same submesh.
GeometryData join(GeometryData a, const GeometryData& b) {
  uint32_t base = uint32_t(a.vertexCount());
  a.positions.insert(a.positions.end(), b.positions.begin(), b.positions.end());
  for (uint32_t i : b.indices) a.indices.push_back(base + i);
  a.submeshes[0].index_count = uint32_t(a.indices.size());
  return a;
}

// One triangle, one submesh.
GeometryData triangle(Vec3d a, Vec3d b, Vec3d c) {
  GeometryData g;
  g.positions = {float(a.x), float(a.y), float(a.z), float(b.x), float(b.y),
                 float(b.z), float(c.x), float(c.y), float(c.z)};
  g.indices = {0, 1, 2};
  SubMesh s;
  s.index_count = 3;
  g.submeshes = {s};
  return g;
}

class OcclusionQuery : public testing::Test {
 protected:
  void SetUp() override {
    ctx_ = createContext({Backend::OSMesa, -1});
    renderer_ = std::make_unique<Renderer>(ctx_->gl(), kSize, kSize);
    camera_.eye = {0, 0, 0};
    camera_.rotation = Quatd{};  // looks down -Z
    camera_.fovy_deg = 90;
    camera_.aspect = 1;
    camera_.near = 0.1;
  }
  void TearDown() override {
    for (GpuMesh& m : meshes_) renderer_->release(m);
    renderer_.reset();
    ctx_.reset();
  }

  // Draws `occluders` into depth within `region`, then queries `b`; returns
  // the query's result (0 or 1 for ANY_SAMPLES_PASSED, a count otherwise).
  GLuint query(const std::vector<GeometryData>& occluders, const Box3d& b,
               GLenum target = GL_ANY_SAMPLES_PASSED, Rect region = {0, 0, kSize, kSize}) {
    Renderer& r = *renderer_;
    r.beginDepthFrame(camera_, region);
    for (const GeometryData& g : occluders) {
      meshes_.push_back(r.upload(g));
      r.draw(meshes_.back(), Mat4d::identity(), positionBox(g), {});
    }
    // A fresh query object each time: a query's target is fixed by its first use.
    const GlApi& gl = ctx_->gl();
    GLuint q = 0;
    gl.GenQueries(1, &q);
    r.beginQueries();
    r.queryBox(b, q, target);
    r.endQueries();
    GLuint result = 12345;
    gl.GetQueryObjectuiv(q, GL_QUERY_RESULT, &result);
    gl.DeleteQueries(1, &q);
    gl.check("occlusion query test");
    return result;
  }

  // Renders `objects` in colour over the whole frame; RGBA, bottom row first.
  std::vector<uint8_t> render(const std::vector<GeometryData>& objects) {
    Renderer& r = *renderer_;
    r.beginFrame(camera_, {0, 0, kSize, kSize});
    for (const GeometryData& g : objects) {
      meshes_.push_back(r.upload(g));
      r.draw(meshes_.back(), Mat4d::identity(), positionBox(g), {});
    }
    std::vector<uint8_t> px;
    r.readPixels({0, 0, kSize, kSize}, &px);
    return px;
  }

  std::unique_ptr<GlContext> ctx_;
  std::unique_ptr<Renderer> renderer_;
  std::vector<GpuMesh> meshes_;
  Camera camera_;
};

}  // namespace

TEST_F(OcclusionQuery, NothingDrawnEveryBoxInViewPasses) {
  EXPECT_EQ(query({}, box({-1, -1, -12}, {1, 1, -10})), 1u);
  // A box behind the camera is not in view.
  EXPECT_EQ(query({}, box({-1, -1, 10}, {1, 1, 12})), 0u);
}

TEST_F(OcclusionQuery, WallHidesABoxBehindIt) {
  // A 4 x 4 wall at distance 5 covers |x/z|, |y/z| <= 0.4 of the view.
  GeometryData wall = quad(-2, 2, -2, 2, -5);
  EXPECT_EQ(query({wall}, box({-1, -1, -12}, {1, 1, -10})), 0u);        // behind
  EXPECT_EQ(query({wall}, box({-0.5, -0.5, -4}, {0.5, 0.5, -3})), 1u);  // in front
  EXPECT_EQ(query({wall}, box({7, -1, -11}, {9, 1, -9})), 1u);          // beside, as far
  // A box that straddles the wall's plane pokes out in front of it.
  EXPECT_EQ(query({wall}, box({-1, -1, -6}, {1, 1, -4.5})), 1u);
  // Behind but larger than the wall's silhouette: its edges show.
  EXPECT_EQ(query({wall}, box({-5, -5, -12}, {5, 5, -10})), 1u);
}

TEST_F(OcclusionQuery, BoxCoplanarWithTheWallsFrontFacePasses) {
  GeometryData wall = quad(-2, 2, -2, 2, -5);
  // The box's front face lies in the wall's plane: a depth tie is visible.
  EXPECT_EQ(query({wall}, box({-1, -1, -6}, {1, 1, -5})), 1u);
  // A flat box in the wall's plane.
  EXPECT_EQ(query({wall}, box({-1, -1, -5}, {1, 1, -5})), 1u);
  // Versus a box 5 cm behind the wall: hidden, so the widening of query
  // boxes does not make everything near a wall pass. (The widening includes
  // an eighth of a pixel at the box's far side, about 1 cm in this 64-pixel
  // frame: see queryBoxBounds.)
  EXPECT_EQ(query({wall}, box({-1, -1, -6}, {1, 1, -5.05})), 0u);
}

TEST_F(OcclusionQuery, BoxSeenThroughAOnePixelGapPasses) {
  // At distance 5 a pixel is 10/64 wide; column 32 spans x in [0, pw] with
  // its centre at pw/2. The left wall ends at pw/4 and the right one starts
  // at 3pw/4, so exactly column 32 shows what is behind, over all 64 rows.
  const double pw = 10.0 / kSize;
  GeometryData left = quad(-100, 0.25 * pw, -100, 100, -5);
  GeometryData right = quad(0.75 * pw, 100, -100, 100, -5);
  Box3d behind = box({-3, -100, -12}, {3, 100, -10});
  EXPECT_EQ(query({left, right}, behind), 1u);
  // With the eye outside, queries draw only the box's front faces: one
  // sample for each of the column's 64 pixels.
  EXPECT_EQ(query({left, right}, behind, GL_SAMPLES_PASSED), GLuint(kSize)) << "one column";
  // A box behind the walls but off the gap stays hidden.
  EXPECT_EQ(query({left, right}, box({2, -1, -12}, {3, 1, -10})), 0u);
  // Closing the gap hides it.
  GeometryData closed = quad(0.25 * pw, 100, -100, 100, -5);
  EXPECT_EQ(query({left, closed}, behind), 0u);
}

TEST_F(OcclusionQuery, ScissorRegionLimitsTheQuery) {
  // A wall over the left half of the view; a box behind it that reaches into
  // the right half, where nothing hides it.
  GeometryData wall = quad(-100, 0, -100, 100, -5);
  Box3d behind = box({-3, -1, -12}, {3, 1, -10});
  const Rect left_half{0, 0, kSize / 2, kSize};
  EXPECT_EQ(query({wall}, behind), 1u) << "visible in the full frame";
  EXPECT_EQ(query({wall}, behind, GL_ANY_SAMPLES_PASSED, left_half), 0u)
      << "the visible part is outside the region";
  // An unhidden box entirely in the right half does not pass for the left.
  Box3d right = box({2, -1, -12}, {4, 1, -10});
  EXPECT_EQ(query({}, right, GL_ANY_SAMPLES_PASSED, left_half), 0u);
  EXPECT_EQ(query({}, right, GL_ANY_SAMPLES_PASSED, {kSize / 2, 0, kSize / 2, kSize}), 1u);
}

TEST_F(OcclusionQuery, BoxesNotTakenAtTheNearPlaneGiveAnHonestQuery) {
  // The stage queries every box that boxReachesNearPlane rejects, and queryBox
  // widens the box by 0.1% of its size. Here an object's box ends 5 cm in
  // front of the eye (well beyond the near plane, 1 cm) but is 200 m deep,
  // so the widened box swallows the eye: near-plane clipping then removes its
  // front and the query sees only the far faces, behind the occluder. The
  // object's near quad covers the whole view, so it must not be dropped.
  camera_.near = 0.01;
  GeometryData object =
      join(quad(-100, 100, -100, 100, -0.05, 0.1f), quad(-100, 100, -100, 100, -200, 0.1f));
  Box3d object_box = box({-100, -100, -200}, {100, 100, -0.05});
  GeometryData occluder = quad(-1000, 1000, -1000, 1000, -50);
  // The object changes the picture (its near quad covers everything).
  std::vector<uint8_t> without = render({occluder}), with = render({occluder, object});
  ASSERT_NE(without, with);
  bool taken = boxReachesNearPlane(object_box, camera_, kSize);
  EXPECT_TRUE(taken || query({occluder}, object_box) != 0)
      << "a visible object would be culled: not taken at the near plane, and its query fails";
}

// Counts the pixels where a drawing of `g` (alone, into depth) lies in front
// of the front faces of its query box: what would let the visibility stage
// cull an object the reference shows. `bounded`: with the object's box as
// the fragments' depth bound, as every renderer draws; otherwise unbounded.
int pixelsInFrontOfQueryBox(Renderer& r, const GlApi& gl, const Camera& cam, const GeometryData& g,
                            bool bounded) {
  GpuMesh m = r.upload(g);
  Box3d b = positionBox(g);
  r.beginDepthFrame(cam, {0, 0, kSize, kSize});
  r.drawDepth(m, Mat4d::identity(), bounded ? b : Box3d{}, false);
  std::vector<float> depth(size_t(kSize) * kSize);
  gl.ReadPixels(0, 0, kSize, kSize, GL_DEPTH_COMPONENT, GL_FLOAT, depth.data());
  r.release(m);
  EntryDepthPlanes q = entryDepthPlanes(queryBoxBounds(b, cam, kSize), cam);
  int bad = 0;
  for (int y = 0; y < kSize; ++y)
    for (int x = 0; x < kSize; ++x) {
      float d = depth[size_t(y) * kSize + size_t(x)];
      double bound = entryDepth(q, (x + 0.5) * 2 / kSize - 1, (y + 0.5) * 2 / kSize - 1);
      if (d > 0 && d > bound) ++bad;
    }
  return bad;
}

TEST_F(OcclusionQuery, SliverTrianglesSeenEdgeOnStayBehindTheirQueryBox) {
  // Rasterisers interpolate depth with plane equations; for a triangle seen
  // almost edge-on (a sliver a fraction of a pixel wide) the equation is
  // ill-conditioned and a covered pixel centre can get a depth far in front
  // of every vertex: on llvmpipe a plant's pipe at 200 m wrote 185.6 m and
  // won a pixel over an object that hid its box. Slivers: A and B a few
  // pixels apart across the view, C near their midpoint's line of sight at
  // another distance, so the triangle's plane nearly holds the eye.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> ndc(-0.8, 0.8), dist(20, 200), unit(-1, 1),
      depth_step(0.01, 0.1), sliver(1e-6, 1e-3), len(0.5, 20);
  int unbounded = 0, bounded = 0, slivers = 2000;
  for (int i = 0; i < slivers; ++i) {
    double D = dist(rng), pixel = 2 * D / kSize;
    Vec3d m{ndc(rng) * D, ndc(rng) * D, -D};
    Vec3d across = normalize(Vec3d{unit(rng), unit(rng), 0.0 * unit(rng)});
    Vec3d a = m + across * (len(rng) * pixel), b = m - across * (len(rng) * pixel);
    Vec3d side = normalize(cross(m, across));
    double step = (unit(rng) < 0 ? -1 : 1) * depth_step(rng);
    Vec3d c = m * (1 + step) + side * (sliver(rng) * pixel);
    GeometryData g = triangle(a, b, c);
    unbounded += pixelsInFrontOfQueryBox(*renderer_, ctx_->gl(), camera_, g, false);
    bounded += pixelsInFrontOfQueryBox(*renderer_, ctx_->gl(), camera_, g, true);
  }
  EXPECT_EQ(bounded, 0) << "pixels of slivers drawn in front of their query box";
  // Not an assertion on the rasteriser, a record of what the bound guards
  // against on this one.
  std::cout << "slivers: " << slivers
            << ", pixels in front of their query box unbounded: " << unbounded
            << ", bounded: " << bounded << "\n";
}

// The bound drops a fragment nearer than its object's box rather than
// clamping its depth (which would draw it at the box's entry depth and cost
// llvmpipe its depth test before the shader): a quad at 5 m drawn with a
// box 8 to 10 m away leaves colour and depth as cleared, in the shading
// pass (draw) and the depth pass (drawDepth) alike; with its own box it
// covers the frame's middle.
TEST_F(OcclusionQuery, FragmentsInFrontOfTheirDepthBoundAreDroppedNotClamped) {
  Renderer& r = *renderer_;
  const GlApi& gl = ctx_->gl();
  GeometryData wall = quad(-2, 2, -2, 2, -5);
  meshes_.push_back(r.upload(wall));
  const GpuMesh& m = meshes_.back();
  const Box3d behind = box({-2, -2, -10}, {2, 2, -8}), own = positionBox(wall);
  const Rect frame{0, 0, kSize, kSize};
  auto written = [&](const std::vector<float>& depth) {
    return std::count_if(depth.begin(), depth.end(), [](float d) { return d != 0.f; });
  };
  std::vector<uint8_t> cleared, px;
  std::vector<float> depth;
  r.beginFrame(camera_, frame);
  r.readPixels(frame, &cleared);
  r.draw(m, Mat4d::identity(), behind, {});
  r.readPixels(frame, &px);
  r.readDepth(frame, &depth);
  EXPECT_TRUE(px == cleared) << "a fragment in front of its bound was drawn";
  EXPECT_EQ(written(depth), 0);
  r.beginDepthFrame(camera_, frame);
  r.drawDepth(m, Mat4d::identity(), behind, false);
  r.readDepth(frame, &depth);
  EXPECT_EQ(written(depth), 0) << "the depth pass wrote a fragment in front of its bound";
  // The wall spans |x|, |y| <= 0.4 of the view: 26 x 26 pixel centres.
  r.beginFrame(camera_, frame);
  r.draw(m, Mat4d::identity(), own, {});
  r.readDepth(frame, &depth);
  EXPECT_EQ(written(depth), 26 * 26);
  r.beginDepthFrame(camera_, frame);
  r.drawDepth(m, Mat4d::identity(), own, false);
  r.readDepth(frame, &depth);
  EXPECT_EQ(written(depth), 26 * 26);
  gl.check("depth bound test");
}

// The shading program reads each draw's colour and depth bound from a ring
// of Renderer::kDrawSlots slots; a frame with more draws than that waits
// for the draws in flight before it reuses a slot. Without the wait, the
// first draws would be rasterised with what later ones wrote over their
// slots. 64 spots, each its own colour and box, then the filler drawn past
// the ring's end; the frame must equal one that waits every 1000 draws.
TEST_F(OcclusionQuery, MoreDrawsThanDrawSlotsKeepEachDrawsColourAndBound) {
  Renderer& r = *renderer_;
  std::vector<Box3d> boxes;
  for (int k = 0; k < 64; ++k) {  // 2-pixel squares on an 8x8 grid, lower half
    double x = -1 + (k % 8) * 0.25, y = -1 + (k / 8) * 0.125;
    GeometryData g = quad(x, x + 0.0625, y, y + 0.0625, -1, float(k + 1) / 65.f);
    meshes_.push_back(r.upload(g));
    boxes.push_back(positionBox(g));
  }
  GeometryData filler = quad(-1, 1, 0.25, 0.75, -1, 0.5f);
  meshes_.push_back(r.upload(filler));
  boxes.push_back(positionBox(filler));
  const Rect frame{0, 0, kSize, kSize};
  auto render = [&](size_t wait_every) {
    r.beginFrame(camera_, frame);
    size_t draws = 0;
    auto drawOne = [&](size_t i) {
      r.draw(meshes_[i], Mat4d::identity(), boxes[i], {});
      if (wait_every && ++draws % wait_every == 0) r.finish();
    };
    for (size_t i = 0; i < 64; ++i) drawOne(i);
    for (size_t i = 0; i < Renderer::kDrawSlots; ++i) drawOne(64);
    std::vector<uint8_t> px;
    r.readPixels(frame, &px);
    return px;
  };
  std::vector<uint8_t> waiting = render(1000), ring = render(0);
  // The spots' pixels (one inside each) are of many reds (the headlight's
  // falloff makes a few of the 64 coincide): a spot that read the filler's
  // slot would show the filler's.
  std::vector<uint8_t> reds;
  for (int k = 0; k < 64; ++k) {
    int px = (k % 8) * 8 + 1, py = (k / 8) * 4 + 1;
    reds.push_back(waiting[size_t(py * kSize + px) * 4]);
  }
  std::sort(reds.begin(), reds.end());
  EXPECT_GE(std::unique(reds.begin(), reds.end()) - reds.begin(), 48);
  EXPECT_TRUE(ring == waiting) << "a draw read another draw's slot";
  ctx_->gl().check("draw slots test");
}

// The depth-pyramid test's contract on the real rasteriser: every pixel an
// object writes lies in its query box's screen bound and no nearer than the
// bound's depth there (depth_pyramid.h). Random triangles inside random
// boxes, and edge-on slivers as above.
TEST_F(OcclusionQuery, EveryFragmentLiesWithinItsScreenBound) {
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> ndc(-1.1, 1.1), dist(0.3, 300), unit(-1, 1),
      depth_step(0.01, 0.1), sliver(1e-6, 1e-3), len(0.5, 20), size(1e-4, 0.5);
  Renderer& r = *renderer_;
  std::vector<float> depth;
  int pixels = 0, outside = 0, nearer = 0;
  for (int i = 0; i < 3000; ++i) {
    double D = dist(rng), pixel = 2 * D / kSize;
    Vec3d m{ndc(rng) * D, ndc(rng) * D, -D};
    Vec3d a, b, c;
    if (i % 2 == 0) {  // a sliver seen almost edge-on
      Vec3d across = normalize(Vec3d{unit(rng), unit(rng), 0.0});
      a = m + across * (len(rng) * pixel);
      b = m - across * (len(rng) * pixel);
      Vec3d side = normalize(cross(m, across));
      c = m * (1 + (unit(rng) < 0 ? -1 : 1) * depth_step(rng)) + side * (sliver(rng) * pixel);
    } else {  // any triangle in a box of up to half the distance
      double s = size(rng) * D;
      auto corner = [&] { return m + Vec3d{unit(rng), unit(rng), unit(rng)} * s; };
      a = corner(), b = corner(), c = corner();
    }
    GeometryData g = triangle(a, b, c);
    Box3d bounds = positionBox(g);
    r.beginDepthFrame(camera_, {0, 0, kSize, kSize});
    meshes_.push_back(r.upload(g));
    r.draw(meshes_.back(), Mat4d::identity(), bounds, {});
    r.readDepth({0, 0, kSize, kSize}, &depth);
    r.release(meshes_.back());
    meshes_.pop_back();
    ScreenBound sb = screenBound(queryBoxBounds(bounds, camera_, kSize), camera_, kSize, kSize);
    if (sb.reaches_near) continue;
    for (int y = 0; y < kSize; ++y)
      for (int x = 0; x < kSize; ++x) {
        float d = depth[size_t(y) * kSize + x];
        if (d <= 0) continue;
        ++pixels;
        if (x < sb.x0 || x > sb.x1 || y < sb.y0 || y > sb.y1)
          ++outside;
        else if (double(d) > sb.bound(x, y, x, y))
          ++nearer;
      }
  }
  EXPECT_GT(pixels, 5000);
  EXPECT_EQ(outside, 0) << "pixels outside their screen bound";
  EXPECT_EQ(nearer, 0) << "pixels nearer than their screen bound allows";
}

// The part boxes' contract on the real rasteriser (client.cpp partsHide):
// every pixel an object writes lies in the bound of one of its parts
// (partBox, moved by the object's transform, widened by the object's
// margins, its rectangle with the object's depth bound) and no nearer than
// that bound. Random meshes of small and thin triangles along a bent path,
// quantised parts as the preprocessor stores them, transforms with rotation
// and non-uniform scale.
TEST_F(OcclusionQuery, EveryFragmentLiesWithinAPartsBound) {
  std::mt19937 rng(29);
  std::uniform_real_distribution<double> unit(-1, 1), dist(2, 200), thin(1e-5, 1e-2);
  Renderer& r = *renderer_;
  std::vector<float> depth;
  int pixels = 0, outside = 0, nearer = 0;
  int64_t object_area = 0, part_area = 0;
  for (int i = 0; i < 400; ++i) {
    // Triangles along two legs of an L in the unit square (local frame).
    GeometryData g;
    int n = std::uniform_int_distribution<int>(4, 24)(rng);
    for (int t = 0; t < n; ++t) {
      double f = (unit(rng) + 1) / 2, w = t % 3 == 0 ? thin(rng) : 0.25;
      Vec3d c = t % 2 ? Vec3d{f, 0, 0} : Vec3d{0, f, 0};
      auto corner = [&] { return c + Vec3d{unit(rng), unit(rng), unit(rng)} * w; };
      g = g.submeshes.empty() ? triangle(corner(), corner(), corner())
                              : join(g, triangle(corner(), corner(), corner()));
    }
    Box3d local = positionBox(g);
    std::vector<Box3d> raw = partBoxes(g.positions.data(), g.vertexCount(), g.indices.data(),
                                       g.indices.size(), kMaxParts);
    GeometryParts parts = quantizeParts(local, raw);
    double D = dist(rng);
    Quatd q{unit(rng), unit(rng), unit(rng), unit(rng)};
    double qn = std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
    q = Quatd{q.x / qn, q.y / qn, q.z / qn, q.w / qn};
    Vec3d scale{D * (0.1 + (unit(rng) + 1) * 0.3), D * (0.1 + (unit(rng) + 1) * 0.3),
                D * (0.05 + (unit(rng) + 1) * 0.1)};
    Mat4d T = Mat4d::translate(Vec3d{unit(rng) * D * 0.6, unit(rng) * D * 0.6, -D}) *
              Mat4d::rotation(q) * Mat4d::scale(scale);
    Box3d box = transformBox(T, local);
    Box3d qbox = queryBoxBounds(box, camera_, kSize);
    ScreenBound ob = screenBound(qbox, camera_, kSize, kSize);
    if (ob.reaches_near) continue;
    std::vector<ScreenBound> bounds;
    for (size_t k = 0; k < parts.parts.size(); ++k) {
      Box3d part = transformBox(T, partBox(parts, k));
      bounds.push_back(
          partBound(ob, screenRect(queryPartBounds(part, box, qbox), camera_, kSize, kSize)));
    }
    r.beginDepthFrame(camera_, {0, 0, kSize, kSize});
    meshes_.push_back(r.upload(g));
    r.draw(meshes_.back(), T, box, {});
    r.readDepth({0, 0, kSize, kSize}, &depth);
    r.release(meshes_.back());
    meshes_.pop_back();
    for (int y = 0; y < kSize; ++y)
      for (int x = 0; x < kSize; ++x) {
        bool in_object = !ob.empty() && x >= ob.x0 && x <= ob.x1 && y >= ob.y0 && y <= ob.y1;
        auto holds = [&](const ScreenBound& b) {
          return !b.empty() && x >= b.x0 && x <= b.x1 && y >= b.y0 && y <= b.y1;
        };
        bool in_part = std::any_of(bounds.begin(), bounds.end(), holds);
        object_area += in_object;
        part_area += in_part;
        float d = depth[size_t(y) * kSize + x];
        if (d <= 0) continue;
        ++pixels;
        if (!in_part)
          ++outside;
        else if (double(d) > ob.bound(x, y, x, y))
          ++nearer;
      }
  }
  EXPECT_GT(pixels, 5000);
  EXPECT_EQ(outside, 0) << "pixels outside every part's bound";
  EXPECT_EQ(nearer, 0) << "pixels nearer than the object's bound allows";
  // The parts leave out much of what the box covers (the L's empty corner).
  EXPECT_LT(double(part_area), 0.8 * double(object_area));
}

// The batched queries (one buffer, a base vertex per box, no state change
// between queries) answer as the one-box-at-a-time queries do.
TEST_F(OcclusionQuery, BatchedQueriesAnswerAsSingleOnes) {
  Renderer& r = *renderer_;
  const GlApi& gl = ctx_->gl();
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> xy(-12, 12), z(-16, -6), half(0.05, 2);
  std::vector<Box3d> boxes;
  for (int i = 0; i < 300; ++i) {
    Vec3d c{xy(rng), xy(rng), z(rng)}, h{half(rng), half(rng), half(rng)};
    boxes.push_back(box(c - h, c + h));
  }
  std::vector<GLuint> single(boxes.size()), batched(boxes.size());
  gl.GenQueries(GLsizei(single.size()), single.data());
  gl.GenQueries(GLsizei(batched.size()), batched.data());
  r.beginDepthFrame(camera_, {0, 0, kSize, kSize});
  GeometryData wall = quad(-4, 6, -5, 3, -10);  // hides some boxes, not others
  meshes_.push_back(r.upload(wall));
  r.draw(meshes_.back(), Mat4d::identity(), positionBox(wall), {});
  r.beginQueries();
  for (size_t i = 0; i < boxes.size(); ++i) r.queryBox(boxes[i], single[i], GL_SAMPLES_PASSED);
  r.queryBoxes(boxes, batched.data(), GL_SAMPLES_PASSED);
  r.endQueries();
  int hidden = 0;
  for (size_t i = 0; i < boxes.size(); ++i) {
    GLuint a = 0, b = 0;
    gl.GetQueryObjectuiv(single[i], GL_QUERY_RESULT, &a);
    gl.GetQueryObjectuiv(batched[i], GL_QUERY_RESULT, &b);
    EXPECT_EQ(a != 0, b != 0) << boxes[i] << ": " << a << " samples alone, " << b << " batched";
    EXPECT_NEAR(double(a), double(b), 2 + 0.02 * a) << boxes[i];
    hidden += b == 0;
  }
  EXPECT_GT(hidden, 10);
  EXPECT_LT(hidden, 290);
  gl.DeleteQueries(GLsizei(single.size()), single.data());
  gl.DeleteQueries(GLsizei(batched.size()), batched.data());
  gl.check("batched queries");
}

// The fused stages' colour pass over the new objects' own depth
// (beginEqualColorPass): where they changed the depth one fragment each
// passes, so the count equals the changed pixels, and the frame equals
// drawing everything in order; a tie, with what was drawn before or among
// the new objects, adds fragments, so the count tells it.
TEST_F(OcclusionQuery, EqualColorPassCountsOneFragmentPerPixelItChangedUnlessTied) {
  Renderer& r = *renderer_;
  const GlApi& gl = ctx_->gl();
  GLuint q = 0;
  gl.GenQueries(1, &q);
  const Rect all{0, 0, kSize, kSize};
  auto mesh = [&](const GeometryData& g) {
    meshes_.push_back(r.upload(g));
    return meshes_.size() - 1;
  };
  // Step 1 draws `first` in colour; the new ones go into depth, then into
  // colour where EQUAL. Returns the fragments counted minus the pixels whose
  // depth the new ones changed, and the frame.
  auto fused = [&](const std::vector<GeometryData>& first, const std::vector<GeometryData>& fresh,
                   std::vector<uint8_t>* rgba) {
    r.beginFrame(camera_, all);
    for (const GeometryData& g : first)
      r.draw(meshes_[mesh(g)], Mat4d::identity(), positionBox(g), {});
    std::vector<float> before, after;
    r.readDepth(all, &before);
    std::vector<size_t> ids;
    for (const GeometryData& g : fresh) ids.push_back(mesh(g));
    r.maskColor(true);
    for (size_t i = 0; i < fresh.size(); ++i)
      r.drawDepth(meshes_[ids[i]], Mat4d::identity(), positionBox(fresh[i]), false);
    r.maskColor(false);
    r.readDepth(all, &after);
    int64_t changed = 0;
    for (size_t i = 0; i < after.size(); ++i) changed += after[i] != before[i];
    r.beginEqualColorPass(q);
    for (size_t i = 0; i < fresh.size(); ++i)
      r.draw(meshes_[ids[i]], Mat4d::identity(), positionBox(fresh[i]), {});
    r.endEqualColorPass();
    GLuint fragments = 0;
    gl.GetQueryObjectuiv(q, GL_QUERY_RESULT, &fragments);
    r.readPixels(all, rgba);
    EXPECT_GT(changed + int64_t(fragments), 0) << "the case draws nothing";
    return int64_t(fragments) - changed;
  };
  auto inOrder = [&](const std::vector<GeometryData>& objects) {
    r.beginFrame(camera_, all);
    for (const GeometryData& g : objects)
      r.draw(meshes_[mesh(g)], Mat4d::identity(), positionBox(g), {});
    std::vector<uint8_t> rgba;
    r.readPixels(all, &rgba);
    return rgba;
  };
  GeometryData wall = quad(-4, 4, -4, 4, -10, 0.8f);
  // Nearer than the wall over part of it, and beside it; a sliver seen
  // obliquely too.
  GeometryData front = quad(-2, 6, -1, 2, -9, 0.3f);
  GeometryData slanted =
      join(quad(-3, -1, -3, 3, -9.5, 0.5f), triangle({-3, -3, -8}, {3, -2.9, -12}, {2, -3.1, -9}));
  std::vector<uint8_t> got;
  EXPECT_EQ(fused({wall}, {front, slanted}, &got), 0);
  EXPECT_TRUE(got == inOrder({wall, front, slanted})) << "the frame differs from drawing in order";
  // A tie with step 1's depth (the wall again, another colour), and one
  // between two new objects: more fragments than changed pixels.
  EXPECT_GT(fused({wall}, {quad(-4, 4, -4, 4, -10, 0.1f)}, &got), 0);
  EXPECT_GT(fused({wall}, {front, quad(-2, 6, -1, 2, -9, 0.6f)}, &got), 0);
  gl.DeleteQueries(1, &q);
  gl.check("equal colour pass");
}

// Flushing while drawing (Renderer::setFlushEvery) lets llvmpipe rasterise
// one batch while the next is binned; GL keeps the order, so depth ties
// still resolve to the first drawn. The schedule starts again with each
// frame (the second render of the same objects flushes as often). Coplanar quads of different
// colours tie everywhere they overlap, and slanted triangles cross them.
TEST_F(OcclusionQuery, FlushingWhileDrawingChangesNoPixel) {
  EXPECT_EQ(renderer_->flushEvery(), 0u) << "a Renderer starts without flushing";
  EXPECT_EQ(defaultFlushTriangles(ctx_->gl()), kFlushTrianglesCpu) << "OSMesa is llvmpipe here";
  std::vector<GeometryData> objects;
  for (int i = 0; i < 24; ++i) {
    double x = -4 + 0.3 * i;
    objects.push_back(quad(x, x + 3, -3, 3, -10, float(i % 7) / 7.f));  // ties with the others
    objects.push_back(triangle({x, -3, -8}, {x + 2, 3, -12}, {x + 1, -2, -9.5}));
  }
  std::vector<uint8_t> plain = render(objects);
  for (uint64_t every : {1u, 2u, 5u}) {
    renderer_->setFlushEvery(every);
    uint64_t before = renderer_->flushes();
    std::vector<uint8_t> flushed = render(objects);
    // A flush after the draw call that reaches `every` triangles, then twice
    // as many, then every four times as many.
    uint64_t due = 0, next = every, expected = 0;
    for (const GeometryData& g : objects)
      if ((due += g.indices.size() / 3) >= next)
        ++expected, due = 0, next = std::min(2 * next, 4 * every);
    EXPECT_EQ(renderer_->flushes() - before, expected) << "every " << every;
    EXPECT_TRUE(render(objects) == plain);
    EXPECT_EQ(renderer_->flushes() - before, 2 * expected) << "every " << every << ", again";
    EXPECT_TRUE(flushed == plain) << "flushing every " << every << " triangles changed the frame";
  }
}

// The fused stages' tie check: a fragment at exactly the depth already in
// the buffer counts, one nearer or farther does not.
TEST_F(OcclusionQuery, DepthEqualQueryFindsExactTiesOnly) {
  Renderer& r = *renderer_;
  const GlApi& gl = ctx_->gl();
  GLuint q = 0;
  gl.GenQueries(1, &q);
  auto ties = [&](const GeometryData& drawn, const GeometryData& probe) {
    r.beginFrame(camera_, {0, 0, kSize, kSize});
    meshes_.push_back(r.upload(drawn));
    r.draw(meshes_.back(), Mat4d::identity(), positionBox(drawn), {});
    meshes_.push_back(r.upload(probe));
    r.beginDepthEqualQuery(q);
    r.drawDepth(meshes_.back(), Mat4d::identity(), positionBox(probe), false);
    r.endDepthEqualQuery();
    GLuint any = 7;
    gl.GetQueryObjectuiv(q, GL_QUERY_RESULT, &any);
    return any != 0;
  };
  GeometryData wall = quad(-4, 4, -4, 4, -10);
  EXPECT_TRUE(ties(wall, wall));
  EXPECT_FALSE(ties(wall, quad(-4, 4, -4, 4, -9.99)));
  EXPECT_FALSE(ties(wall, quad(-4, 4, -4, 4, -10.01)));
  EXPECT_FALSE(ties(quad(-4, 0, -4, 4, -10), quad(1, 4, -4, 4, -10)));  // side by side
  gl.DeleteQueries(1, &q);
}
