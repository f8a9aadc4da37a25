// Ray-traced rendering on the clients (the Sensors 2022 paper's renderer):
// Embree over the same scene, objects and camera as the raster path, no GL.
// One BVH per unique geometry (RtMesh), built when the geometry is loaded and
// shared by every instance; a top level over the frame's objects, kept from
// frame to frame and changed only where the objects did, with transforms
// made relative to an anchor near the camera in double first (as the raster
// path makes them camera-relative), so that scenes far from the origin keep
// precision.
//
// Shading with every effect off is the raster shader's (common/draw.cpp):
// two-sided headlight, base = diffuse * vertex colour * texture, colour =
// base * (0.3 + 0.7 |n . v|), facet normal where a mesh has none, the same
// background. Pixels differ from the raster frame only where sampling does:
// a pixel's one primary ray through its centre against the rasteriser's
// coverage rules at edges, and textures sampled bilinearly from the full
// image where GL uses mipmaps (docs/raytrace.md).
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "camera.h"
#include "draw.h"
#include "formats.h"

namespace dmmr {

// Embree's BVH build quality and layout (docs/benchmarks.md compares their
// bytes per triangle and speed).
enum class BvhQuality { Low, Medium, High };

struct RayOptions {
  // Hard shadows from a directional light (`light`, the direction towards
  // it, world space): lit surfaces get 0.3 + 0.7 max(n . l, 0), shadowed
  // ones 0.3 (ambient). Off: the headlight shading above.
  bool shadows = false;
  Vec3d light = {0.3, 0.4, 0.866};
  // Mirror reflection and refraction for objects whose effect says so
  // (RtInstance::effect), each bounce bounded by max_depth.
  bool reflections = false;
  int max_depth = 4;
  BvhQuality quality = BvhQuality::Medium;
  // Embree's compact BVH layout: 40% less BVH memory at the same tracing
  // speed on this project's scenes (docs/raytrace.md), so the default.
  bool compact = true;
  // One primary ray per stride x stride pixels, the rest interpolated
  // bilinearly (1: every pixel, exact). For moving frames in the
  // interactive mode; the error is measured in docs/benchmarks.md.
  int stride = 1;
  // The top level's transforms are relative to anchorFor(eye, anchor_grid)
  // and kept while that does not change (docs/raytrace.md): 0 makes them
  // eye-relative and sets them all every time the eye moves.
  double anchor_grid = 0;
};

inline constexpr int kMaxRayStride = 8;

// The samples of a strided frame: sample (i, j), 0 <= i < w, 0 <= j < h, is
// traced through pixel (x + i stride, y + j stride), where x and y are
// multiples of the stride (the grid is the frame's, whatever the region),
// and every pixel of `region` lies in a cell of four samples. Stride 1: the
// region's pixels. Pure.
struct RayGrid {
  int x = 0, y = 0, w = 0, h = 0, stride = 1;
  friend bool operator==(const RayGrid&, const RayGrid&) = default;
};
RayGrid rayStrideGrid(const Rect& region, int stride);
// Fills `region`'s RGBA8 pixels (bottom row first) by bilinear interpolation
// between the grid's samples (w x h RGBA8), rounding to nearest.
void upsampleStrided(const RayGrid& grid, const uint8_t* samples, const Rect& region,
                     uint8_t* rgba);

enum class SurfaceEffect : uint8_t { None = 0, Mirror = 1, Glass = 2 };

// One unique geometry, ready for rays: its BVH and what shading needs
// (normals, colours, texture coordinates, submesh materials).
class RtMesh {
 public:
  virtual ~RtMesh() = default;
  // Bytes held: the BVH (Embree's reported size) plus the vertex and index
  // copies; what the cache's device level counts.
  virtual uint64_t bytes() const = 0;
  virtual uint64_t bvhBytes() const = 0;
  virtual uint64_t triangles() const = 0;
};

struct RtInstance {
  static constexpr uint32_t kNoObject = UINT32_MAX;
  const RtMesh* mesh = nullptr;
  Mat4d object_to_world;
  SurfaceEffect effect = SurfaceEffect::None;
  // Which object this is, so that the top level can keep it from one
  // render to the next (kNoObject: the instance's index in the list).
  uint32_t object = kNoObject;
};

// What one RayTracer::render did to the top level.
struct RtRenderStats {
  uint32_t updated = 0;     // instances bound, moved or removed
  bool rebuilt = false;     // the top level's BVH was built again
  bool reanchored = false;  // a new anchor: every transform set again
  double top_ms = 0;        // wall time of the top level's update
};

// The top level's anchor for an eye: the eye rounded to the nearest point
// of a grid of spacing `grid` (0: the eye itself). A function of the eye
// alone, so that every client of a run (whatever it traced before) uses the
// same anchor for a frame and distributed frames equal one client's.
Vec3d anchorFor(Vec3d eye, double grid);

class RayTracer {
 public:
  // `threads`: the threads Embree and the tracer may use (0: every CPU this
  // process may run on, see affinity.h).
  explicit RayTracer(int threads = 0);
  ~RayTracer();
  RayTracer(const RayTracer&) = delete;
  RayTracer& operator=(const RayTracer&) = delete;

  // Builds `g`'s BVH. Throws Error when Embree fails (out of memory).
  std::unique_ptr<RtMesh> build(const GeometryData& g, BvhQuality quality = BvhQuality::Medium,
                                bool compact = false);

  // Renders `region` of a width x height frame: one primary ray through each
  // pixel's centre, into `rgba` (region-sized, RGBA8, bottom row first, as
  // Renderer::readPixels gives). `textures[i]` is texture file i (null:
  // untextured). The scene is exactly `instances` (an object at most once;
  // null meshes skipped); the top level keeps them for the next call, so
  // a list like the last one is cheap, and the same list costs nothing.
  // A mesh may be destroyed between calls (it leaves the top level then),
  // never during one. `list_version` (0: none) lets a caller that calls
  // with one list many times (the tiles of a frame) skip even the
  // comparison: a nonzero version equal to the last call's promises the
  // same list, and no mesh of it destroyed since.
  RtRenderStats render(const Camera& camera, int width, int height, const Rect& region,
                       const std::vector<RtInstance>& instances,
                       const std::vector<const TextureData*>& textures, const RayOptions& opts,
                       std::vector<uint8_t>* rgba, Rgb background = {}, uint64_t list_version = 0);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace dmmr
