// Exact triangle culling in the renderer (Renderer::setTriangleCull): a
// dense mesh far from the origin, scaled and rotated, drawn with culling on
// and off, must give the same colour and depth bit for bit, whole or in
// scissored regions, in colour and depth-only passes, near and far; and
// the culling must actually drop triangles.
#include <gtest/gtest.h>

#include <cmath>

#include "camera.h"
#include "draw.h"
#include "gl_context.h"

using namespace dmmr;

namespace {

// A wavy n x n grid over [0,1]^2 (z up to 0.05), two submeshes (the lower
// and upper halves of the rows, two colours), with normals, and an occluder
// level of detail of every fourth triangle.
GeometryData denseGrid(int n) {
  GeometryData g;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      double u = double(i) / n, v = double(j) / n;
      double z = 0.05 * std::sin(17 * u) * std::cos(13 * v);
      g.positions.insert(g.positions.end(), {float(u), float(v), float(z)});
      g.normals.insert(g.normals.end(), {float(-0.85 * std::cos(17 * u) * std::cos(13 * v)),
                                         float(0.65 * std::sin(17 * u) * std::sin(13 * v)), 1.f});
    }
  auto quad = [&](int i, int j) {
    uint32_t a = uint32_t(j * (n + 1) + i), b = a + 1, c = a + uint32_t(n + 1), d = c + 1;
    g.indices.insert(g.indices.end(), {a, b, d, a, d, c});
  };
  for (int half = 0; half < 2; ++half) {
    SubMesh s;
    s.first_index = uint32_t(g.indices.size());
    for (int j = half * n / 2; j < (half + 1) * n / 2; ++j)
      for (int i = 0; i < n; ++i) quad(i, j);
    s.index_count = uint32_t(g.indices.size()) - s.first_index;
    s.diffuse[0] = half ? 0.9f : 0.3f;
    g.submeshes.push_back(s);
  }
  for (size_t t = 0; t < g.indices.size(); t += 12)
    g.lod_indices.insert(g.lod_indices.end(), g.indices.begin() + long(t),
                         g.indices.begin() + long(t) + 3);
  return g;
}

struct Frame {
  std::vector<uint8_t> rgba;
  std::vector<float> depth;
  uint64_t culled = 0;
};

// Draws the grid at `objects` (world transforms) into each region in turn,
// then reads the whole frame; depth_only: drawDepth (lod: its level of
// detail) into a colour-masked frame.
Frame render(GlContext& ctx, bool cull, const Camera& cam, const std::vector<Mat4d>& objects,
             const std::vector<Rect>& regions, bool depth_only = false, bool lod = false) {
  const int w = 241, h = 173;
  Renderer r(ctx.gl(), w, h);
  r.setTriangleCull(cull);
  GeometryData g = denseGrid(160);
  GpuMesh mesh = r.upload(g);
  for (const Rect& reg : regions) {
    if (depth_only)
      r.beginDepthFrame(cam, reg);
    else
      r.beginFrame(cam, reg);
    for (const Mat4d& m : objects) {
      Box3d box;
      for (int k = 0; k < 8; ++k)
        box.expand(m.transformPoint({double(k & 1), double(k >> 1 & 1), k & 4 ? 0.05 : -0.05}));
      if (depth_only)
        r.drawDepth(mesh, m, box, lod);
      else
        r.draw(mesh, m, box, {});
    }
  }
  Frame f;
  r.readPixels({0, 0, w, h}, &f.rgba);
  r.readDepth({0, 0, w, h}, &f.depth);
  f.culled = r.trianglesCulled();
  r.release(mesh);
  return f;
}

// Far from the origin; the objects scaled, rotated and tilted toward the
// eye at several distances, so triangles range from well under a pixel
// to several pixels.
Camera farCamera() {
  Camera cam;
  cam.eye = {3.0e5, -2.0e5, 1.0e4};
  cam.rotation = Quatd{0.2, -0.1, 0.05, 0.97};
  double l = std::sqrt(0.2 * 0.2 + 0.1 * 0.1 + 0.05 * 0.05 + 0.97 * 0.97);
  cam.rotation = {0.2 / l, -0.1 / l, 0.05 / l, 0.97 / l};
  cam.fovy_deg = 50;
  cam.aspect = 241.0 / 173;
  cam.near = 0.05;
  return cam;
}
std::vector<Mat4d> objectsBefore(const Camera& cam) {
  std::vector<Mat4d> out;
  Mat4d rot = Mat4d::rotation(cam.rotation);
  const double dist[] = {0.9, 4, 12, 40};
  for (int k = 0; k < 4; ++k) {
    Vec3d at = cam.eye + rot.transformVector({(k - 1.5) * 0.2 * dist[k], 0.1 * dist[k], -dist[k]});
    double s = 0.5 + 0.6 * k;
    Quatd q{0.3 * k, 0.5, -0.2, 0.8};
    double l = std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
    q = {q.x / l, q.y / l, q.z / l, q.w / l};
    out.push_back(Mat4d::translate(at) * Mat4d::rotation(q) * Mat4d::scale({s, s * 1.7, s}));
  }
  return out;
}

}  // namespace

TEST(TriangleCull, ColourAndDepthEqualTheUnculledDrawBitForBit) {
  // Both backends: the buffers are read back through a mapping of each.
  for (Backend backend : {Backend::OSMesa, Backend::EGL}) {
    auto ctx = createContext({backend, -1});
    Camera cam = farCamera();
    auto objects = objectsBefore(cam);
    const Rect full{0, 0, 241, 173};
    Frame off = render(*ctx, false, cam, objects, {full});
    Frame on = render(*ctx, true, cam, objects, {full});
    EXPECT_EQ(off.culled, 0u);
    EXPECT_GT(on.culled, 10000u);  // of 4 x 51200 triangles
    EXPECT_TRUE(on.rgba == off.rgba);
    EXPECT_TRUE(on.depth == off.depth);
    // Not trivially equal: the objects cover a good part of the frame.
    size_t covered = 0;
    for (float d : off.depth) covered += d != 0.f;
    EXPECT_GT(covered, off.depth.size() / 10);
  }
}

TEST(TriangleCull, ScissoredRegionsEqualTheUnculledFullFrame) {
  auto ctx = createContext({Backend::OSMesa, -1});
  Camera cam = farCamera();
  auto objects = objectsBefore(cam);
  Frame off = render(*ctx, false, cam, objects, {{0, 0, 241, 173}});
  // Odd splits, a one-pixel-wide column among them.
  std::vector<Rect> pieces = {{0, 0, 97, 80}, {97, 0, 144, 80}, {0, 80, 1, 93}, {1, 80, 240, 93}};
  Frame on = render(*ctx, true, cam, objects, pieces);
  EXPECT_GT(on.culled, 0u);
  EXPECT_TRUE(on.rgba == off.rgba);
  EXPECT_TRUE(on.depth == off.depth);
}

TEST(TriangleCull, DepthPassesEqualTheUnculledOnesWholeAndByLevelOfDetail) {
  auto ctx = createContext({Backend::OSMesa, -1});
  Camera cam = farCamera();
  auto objects = objectsBefore(cam);
  const Rect full{0, 0, 241, 173};
  for (bool lod : {false, true}) {
    Frame off = render(*ctx, false, cam, objects, {full}, true, lod);
    Frame on = render(*ctx, true, cam, objects, {full}, true, lod);
    EXPECT_GT(on.culled, 0u) << lod;
    EXPECT_TRUE(on.depth == off.depth) << lod;
  }
}

TEST(TriangleCull, AnObjectAcrossTheEyePlaneIsDrawnAsItIs) {
  // The box reaches behind the eye: nothing culled, and the same pixels.
  auto ctx = createContext({Backend::OSMesa, -1});
  Camera cam = farCamera();
  Mat4d rot = Mat4d::rotation(cam.rotation);
  Vec3d at = cam.eye + rot.transformVector({-0.5, -0.2, 0.3});
  std::vector<Mat4d> objects = {Mat4d::translate(at) * Mat4d::rotation(cam.rotation) *
                                Mat4d::rotation(Quatd{std::sqrt(0.5), 0, 0, std::sqrt(0.5)}) *
                                Mat4d::scale({3, 3, 3})};
  const Rect full{0, 0, 241, 173};
  Frame off = render(*ctx, false, cam, objects, {full});
  Frame on = render(*ctx, true, cam, objects, {full});
  EXPECT_EQ(on.culled, 0u);
  EXPECT_TRUE(on.rgba == off.rgba);
  EXPECT_TRUE(on.depth == off.depth);
}
