// Not a test: the ray tracer's BVH memory and speed (client/raytrace.h).
//
//   raytrace_bench [--triangles N] [--threads T] [--scene DIR]
//
// Builds a generated mesh of about N triangles (a bumpy grid; 1M by
// default), or every geometry of a preprocessed scene directory with its
// objects as instances, once per BVH quality and layout, and prints per
// configuration: BVH bytes per triangle (Embree's, through its memory
// monitor), all bytes held per triangle (BVH plus the copies shading needs),
// build time, the median of 5 frames of primary rays at 512x512 and
// 1024x1024 and of the same with shadows at 1024x1024, and of a one-pixel
// frame ("top ms": the per-frame top level over the objects, nearly alone).
// Unique triangles count for bytes; the camera looks at the middle of the
// scene from outside it.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <string>
#include <vector>

#include "error.h"
#include "raytrace.h"
#include "scene.h"

using namespace dmmr;

namespace {

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

GeometryData bumpyGrid(uint64_t triangles) {
  int n = std::max(1, int(std::ceil(std::sqrt(double(triangles) / 2))));
  GeometryData m;
  m.positions.reserve(size_t(n + 1) * size_t(n + 1) * 3);
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      double x = double(i) / n, y = double(j) / n;
      double z = 0.04 * std::sin(40 * x) * std::cos(37 * y) + 0.1 * std::sin(5 * x + 3 * y);
      m.positions.insert(m.positions.end(), {float(x), float(y), float(z)});
    }
  m.indices.reserve(size_t(n) * size_t(n) * 6);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      uint32_t a = uint32_t(j * (n + 1) + i), b = a + 1, c = a + uint32_t(n + 1), d = c + 1;
      m.indices.insert(m.indices.end(), {a, b, d, a, d, c});
    }
  SubMesh s;
  s.index_count = uint32_t(m.indices.size());
  m.submeshes = {s};
  return m;
}

Quatd lookRotation(Vec3d forward, Vec3d up) {
  Vec3d z = normalize(-forward), x = normalize(cross(up, z)), y = cross(z, x);
  double m[3][3] = {{x.x, y.x, z.x}, {x.y, y.y, z.y}, {x.z, y.z, z.z}};
  double tr = m[0][0] + m[1][1] + m[2][2];
  if (tr > 0) {
    double s = std::sqrt(tr + 1.0) * 2;
    return {(m[2][1] - m[1][2]) / s, (m[0][2] - m[2][0]) / s, (m[1][0] - m[0][1]) / s, 0.25 * s};
  }
  if (m[0][0] > m[1][1] && m[0][0] > m[2][2]) {
    double s = std::sqrt(1.0 + m[0][0] - m[1][1] - m[2][2]) * 2;
    return {0.25 * s, (m[0][1] + m[1][0]) / s, (m[0][2] + m[2][0]) / s, (m[2][1] - m[1][2]) / s};
  }
  if (m[1][1] > m[2][2]) {
    double s = std::sqrt(1.0 + m[1][1] - m[0][0] - m[2][2]) * 2;
    return {(m[0][1] + m[1][0]) / s, 0.25 * s, (m[1][2] + m[2][1]) / s, (m[0][2] - m[2][0]) / s};
  }
  double s = std::sqrt(1.0 + m[2][2] - m[0][0] - m[1][1]) * 2;
  return {(m[0][2] + m[2][0]) / s, (m[1][2] + m[2][1]) / s, 0.25 * s, (m[1][0] - m[0][1]) / s};
}

struct Input {
  std::vector<GeometryData> geometries;
  std::vector<std::pair<uint32_t, Mat4d>> objects;  // geometry, transform
  Box3d bounds;
  double near = 0.01;
};

[[noreturn]] void usage() {
  std::cerr << "usage: raytrace_bench [--triangles N] [--threads T] [--scene DIR]\n";
  std::exit(2);
}

}  // namespace

int main(int argc, char** argv) try {
  uint64_t triangles = 1'000'000;
  int threads = 0;
  std::string scene_dir;
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    if (i + 1 >= argc) usage();
    if (a == "--triangles")
      triangles = std::stoull(argv[++i]);
    else if (a == "--threads")
      threads = std::stoi(argv[++i]);
    else if (a == "--scene")
      scene_dir = argv[++i];
    else
      usage();
  }
  Input in;
  if (scene_dir.empty()) {
    in.geometries.push_back(bumpyGrid(triangles));
    in.objects.push_back({0, Mat4d::identity()});
    in.bounds.expand(Vec3d{0, 0, -0.2});
    in.bounds.expand(Vec3d{1, 1, 0.2});
  } else {
    Scene s = loadScene(scene_dir, false);
    for (uint32_t g = 0; g < s.manifest.geometries; ++g)
      in.geometries.push_back(loadGeometry(s, g));
    for (const ObjectBounds& o : s.objects) in.objects.push_back({o.geometry, o.transform});
    in.bounds = s.manifest.bounds;
    in.near = defaultNear(s);
  }
  uint64_t unique = 0, total = 0;
  for (const GeometryData& g : in.geometries) unique += g.triangleCount();
  for (const auto& o : in.objects) total += in.geometries[o.first].triangleCount();

  RayTracer rt(threads);
  Vec3d c = in.bounds.center(), e = in.bounds.extent();
  double diag = length(e);
  Vec3d eye = c + Vec3d{0.55, -0.75, 0.45} * diag;
  std::printf("%s: %llu unique triangles, %llu instanced, %zu objects\n",
              scene_dir.empty() ? "bumpy grid" : scene_dir.c_str(), (unsigned long long)unique,
              (unsigned long long)total, in.objects.size());
  std::printf("%-8s %-8s %10s %10s %9s %8s %9s %9s %9s\n", "quality", "layout", "BVH B/tri",
              "all B/tri", "build ms", "top ms", "512 ms", "1024 ms", "1024 sh");
  const char* names[] = {"low", "medium", "high"};
  for (BvhQuality q : {BvhQuality::Low, BvhQuality::Medium, BvhQuality::High})
    for (bool compact : {false, true}) {
      std::vector<std::unique_ptr<RtMesh>> meshes;
      uint64_t bvh = 0, bytes = 0;
      auto t0 = Clock::now();
      for (const GeometryData& g : in.geometries) {
        meshes.push_back(rt.build(g, q, compact));
        bvh += meshes.back()->bvhBytes();
        bytes += meshes.back()->bytes();
      }
      double build_ms = msSince(t0);
      std::vector<RtInstance> inst;
      for (const auto& o : in.objects) inst.push_back({meshes[o.first].get(), o.second});
      double ms[4];
      int k = 0;
      // Size 1: one pixel, so nearly all of the time is the top level's build.
      for (auto [size, shadows] :
           {std::pair{1, false}, {512, false}, {1024, false}, {1024, true}}) {
        Camera cam{eye, lookRotation(c - eye, {0, 0, 1}), 45, 1.0, in.near};
        RayOptions o;
        o.shadows = shadows;
        std::vector<uint8_t> rgba;
        std::vector<double> times;
        for (int i = 0; i < 5; ++i) {
          auto t = Clock::now();
          rt.render(cam, size, size, {0, 0, size, size}, inst, {}, o, &rgba);
          times.push_back(msSince(t));
        }
        std::sort(times.begin(), times.end());
        ms[k++] = times[2];
      }
      std::printf("%-8s %-8s %10.1f %10.1f %9.0f %8.1f %9.1f %9.1f %9.1f\n", names[int(q)],
                  compact ? "compact" : "default", double(bvh) / double(unique),
                  double(bytes) / double(unique), build_ms, ms[0], ms[1], ms[2], ms[3]);
      std::fflush(stdout);
    }
  return 0;
} catch (const std::exception& e) {
  std::cerr << "raytrace_bench: " << e.what() << "\n";
  return 1;
}
