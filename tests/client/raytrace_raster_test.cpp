// The ray tracer with every effect off against the raster path (Renderer on
// OSMesa, what dmmr-reference draws): a hand-made scene of coloured boxes at
// several depths, vertex colours, a textured quad (repeat and clamp), a mesh
// without normals, a rotated and non-uniformly scaled instance, a mesh shared
// by two instances, and the same scene 10^6 from the origin.
//
// Both renderers sample each pixel at its centre, so they can only disagree
// where the rasteriser's coverage rules (vertices snapped to its sub-pixel
// grid) put an edge on the other side of a pixel centre than the exact ray
// does, and by rounding elsewhere. The test finds the edge pixels on the
// reference from an object-id frame (a pixel whose 3x3 neighbourhood holds
// another object or the background) and asserts:
//   - every pixel that differs by more than kTolerance in a channel is an
//     edge pixel;
//   - the PSNR is at least the bound that follows: a non-edge pixel is off by
//     at most kTolerance per channel; an edge pixel shows one of the surfaces
//     seen in its neighbourhood, so it is off by at most the largest
//     difference between its reference colour and its neighbours' plus
//     kTolerance. The bound is that error everywhere, as a PSNR.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <random>

#include "compare.h"
#include "draw.h"
#include "gl_context.h"
#include "image.h"
#include "raytrace.h"
#include "raytrace_scenes.h"

using namespace dmmr;
using namespace dmmr::rtscenes;

namespace {

constexpr int kW = 256, kH = 192;
// Rounding: GL's interpolation and 8-bit texture filtering against the ray
// tracer's float shading (1), and the conversion to 8 bits (1).
constexpr int kTolerance = 2;

struct Object {
  int mesh;  // into Scene::meshes
  Mat4d transform;
};

struct Scene {
  std::vector<GeometryData> meshes;
  std::vector<TextureData> textures;
  std::vector<Object> objects;
};

TextureData makeTexture() {
  TextureData t;
  t.width = 8;
  t.height = 8;
  t.repeat_s = true;
  t.repeat_t = false;
  std::mt19937 rng(7);
  for (uint32_t i = 0; i < t.width * t.height; ++i)
    for (int c = 0; c < 4; ++c) t.rgba.push_back(c == 3 ? 255 : uint8_t(60 + rng() % 196));
  return t;
}

Mat4d rotationAbout(Vec3d axis, double degrees) {
  Vec3d a = normalize(axis) * std::sin(degrees * M_PI / 360);
  return Mat4d::rotation(Quatd{a.x, a.y, a.z, std::cos(degrees * M_PI / 360)});
}

Scene makeScene() {
  Scene s;
  s.textures = {makeTexture()};
  s.meshes = {
      quad(-30, 30, -4, 60, 0.55f, 0.55f, 0.5f),                            // 0 ground
      box({-3, -1, 0}, {-2.2, 0, 1.2}, 0.9f, 0.5f, 0.2f),                   // 1 near box
      box({1.5, 2, 0}, {2.7, 3, 2}, 1, 1, 1, true, true),                   // 2 vertex colours
      box({-0.5, 4, 0}, {0.5, 5, 1}, 0.4f, 0.8f, 0.4f, false),              // 3 no normals
      box({-0.5, -0.5, -0.5}, {0.5, 0.5, 0.5}, 0.3f, 0.5f, 0.95f),          // 4 instanced
      quad(-1, 1, -1, 1, 1, 1, 1, 0, -0.25f, 1.25f, -0.1f, 1.1f),           // 5 textured
      box({-0.3, -0.3, 0}, {0.3, 0.3, 3}, 0.8f, 0.8f, 0.85f, false, true),  // 6 far pillar
  };
  Mat4d id = Mat4d::identity();
  s.objects = {
      {0, Mat4d::translate({0, 0, -0.01})},
      {1, id},
      {2, id},
      {3, id},
      {4, Mat4d::translate({0.5, -3, 1}) * rotationAbout({1, 2, 0.5}, 35) *
              Mat4d::scale({1.5, 0.5, 0.8})},
      // Standing up, facing the camera (its +Z turned to -Y).
      {5, Mat4d::translate({3.3, -1, 1.6}) * rotationAbout({1, 0, 0}, 90)},
      {6, Mat4d::translate({-4, 7, 0})},
      {2, Mat4d::translate({-5.5, 3, 0}) * rotationAbout({0, 0, 1}, 30)},  // mesh 2 again
      {6, Mat4d::translate({1, 8.5, 0}) * Mat4d::scale({2, 2, 0.5})},
  };
  return s;
}

Box3d meshBox(const GeometryData& g) {
  Box3d b;
  for (size_t i = 0; i + 2 < g.positions.size(); i += 3)
    b.expand(Vec3d{g.positions[i], g.positions[i + 1], g.positions[i + 2]});
  return b;
}

struct Frames {
  std::vector<uint8_t> raster, ids, traced;  // RGBA, bottom row first
};

Frames renderBoth(GlContext& ctx, RayTracer& rt, const Scene& s, const Camera& cam, Vec3d offset) {
  Frames f;
  Renderer r(ctx.gl(), kW, kH);
  std::vector<GpuMesh> gpu;
  for (const GeometryData& g : s.meshes) gpu.push_back(r.upload(g));
  std::vector<GLuint> tex;
  for (const TextureData& t : s.textures) tex.push_back(r.uploadTexture(t));
  std::vector<Mat4d> transforms;
  std::vector<Box3d> bounds;
  for (const Object& o : s.objects) {
    transforms.push_back(Mat4d::translate(offset) * o.transform);
    bounds.push_back(transformBox(transforms.back(), meshBox(s.meshes[size_t(o.mesh)])));
  }
  const Rect all{0, 0, kW, kH};
  r.beginFrame(cam, all);
  for (size_t i = 0; i < s.objects.size(); ++i)
    r.draw(gpu[size_t(s.objects[i].mesh)], transforms[i], bounds[i], tex);
  r.readPixels(all, &f.raster);
  r.beginIdFrame(cam, all);
  for (size_t i = 0; i < s.objects.size(); ++i)
    r.drawId(gpu[size_t(s.objects[i].mesh)], transforms[i], bounds[i], uint32_t(i));
  r.readPixels(all, &f.ids);
  for (GpuMesh& m : gpu) r.release(m);
  for (GLuint t : tex) r.releaseTexture(t);

  std::vector<std::unique_ptr<RtMesh>> meshes;
  for (const GeometryData& g : s.meshes) meshes.push_back(rt.build(g));
  std::vector<RtInstance> inst;
  for (size_t i = 0; i < s.objects.size(); ++i)
    inst.push_back({meshes[size_t(s.objects[i].mesh)].get(), transforms[i], SurfaceEffect::None});
  std::vector<const TextureData*> textures;
  for (const TextureData& t : s.textures) textures.push_back(&t);
  rt.render(cam, kW, kH, all, inst, textures, RayOptions{}, &f.traced);
  return f;
}

struct Verdict {
  ImageDiff diff;
  double bound_psnr = 0;
  int64_t edge_pixels = 0, covered = 0;
  int64_t nonedge_differing = 0;  // beyond kTolerance
  int64_t edge_differing = 0;
  int64_t over_edge_bound = 0;  // edge pixels off by more than their neighbourhood allows
};

Verdict judge(const Frames& f) {
  Verdict v;
  Image a{kW, kH, f.traced}, b{kW, kH, f.raster};
  v.diff = compareImages(a, b);
  auto id = [&](int x, int y) {
    const uint8_t* p = &f.ids[(size_t(y) * kW + size_t(x)) * 4];
    return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16;
  };
  double bound_sq = 0;
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      bool edge = false;
      int spread[3] = {0, 0, 0};
      const uint8_t* ref = b.pixel(x, y);
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          int nx = std::clamp(x + dx, 0, kW - 1), ny = std::clamp(y + dy, 0, kH - 1);
          edge |= id(nx, ny) != id(x, y);
          for (int c = 0; c < 3; ++c)
            spread[c] = std::max(spread[c], std::abs(b.pixel(nx, ny)[c] - ref[c]));
        }
      v.covered += id(x, y) != 0;
      v.edge_pixels += edge;
      int worst = 0;
      bool over = false;
      for (int c = 0; c < 3; ++c) {
        int d = std::abs(a.pixel(x, y)[c] - ref[c]);
        worst = std::max(worst, d);
        int allowed = (edge ? spread[c] : 0) + kTolerance;
        over |= d > allowed;
        bound_sq += double(allowed) * allowed;
      }
      if (worst > kTolerance) (edge ? v.edge_differing : v.nonedge_differing)++;
      v.over_edge_bound += edge && over;
    }
  v.bound_psnr = psnrFromMse(bound_sq / (3.0 * kW * kH));
  return v;
}

}  // namespace

TEST(RayTraceVsRaster, EffectsOffMatchesTheRasterFrameBarEdges) {
  auto ctx = createContext({Backend::OSMesa, -1});
  RayTracer rt(2);
  Scene s = makeScene();
  Camera cam = lookAt({0.4, -10, 3.6}, {0, 0.5, 0.6}, kW, kH);
  std::vector<uint8_t> traced_at_origin;
  for (Vec3d offset : {Vec3d{0, 0, 0}, Vec3d{1e6, -1e6, 1e6}}) {
    Camera c = cam;
    c.eye = cam.eye + offset;
    Frames f = renderBoth(*ctx, rt, s, c, offset);
    Verdict v = judge(f);
    std::cout << "offset " << offset << ": ray traced vs raster " << v.diff << "; PSNR "
              << v.diff.psnr << " dB, bound " << v.bound_psnr << " dB; " << v.edge_pixels
              << " edge pixels of " << kW * kH << " (" << v.covered << " covered); differing by > "
              << kTolerance << ": " << v.edge_differing << " edge, " << v.nonedge_differing
              << " other; edge pixels beyond their neighbourhood's spread: " << v.over_edge_bound
              << "\n";
    EXPECT_GT(v.covered, kW * kH / 2) << "the scene must fill most of the frame";
    EXPECT_GT(v.edge_pixels, 500) << "and have edges";
    EXPECT_EQ(v.nonedge_differing, 0) << "offset " << offset;
    EXPECT_GE(v.diff.psnr, v.bound_psnr) << "offset " << offset;
    EXPECT_LE(v.over_edge_bound, v.edge_pixels / 100) << "offset " << offset;
    for (size_t i = 3; i < f.traced.size(); i += 4) ASSERT_EQ(f.traced[i], f.raster[i]) << i;
    // Far from the origin, the camera-relative transforms give the same
    // pixels as at the origin.
    if (offset.x == 0)
      traced_at_origin = f.traced;
    else
      EXPECT_LE(
          compareImages(Image{kW, kH, f.traced}, Image{kW, kH, traced_at_origin}).differing_pixels,
          kW * kH / 1000);
  }
}
