// Benchmark (not a test): the triangle cull's two loops (coverage.h) on a
// dense mesh seen whole: a sphere tessellated as a latitude-longitude grid
// of N x N quads (2 N^2 triangles, indices in grid order, as a mesh's
// triangles lie after a spatial sort), 190 pixels across in a 512x512
// frame, so that most triangles are under a pixel.
//
//   coverage_bench [N] [RUNS]     defaults: 1024, 9
//
// Prints the median over RUNS of projectVertices' nanoseconds a vertex and
// keepCoveringTriangles' a triangle, their portable loops' and (where the
// CPU has AVX2) their AVX2 paths', timed alternately, and the triangles
// kept; exits 1 if the paths disagree.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "camera.h"
#include "coverage.h"

using namespace dmmr;

int main(int argc, char** argv) {
  const int n = argc > 1 ? std::atoi(argv[1]) : 1024;
  const int runs = argc > 2 ? std::atoi(argv[2]) : 9;
  if (n < 2 || runs < 1) {
    std::fprintf(stderr, "usage: coverage_bench [N >= 2] [RUNS >= 1]\n");
    return 2;
  }
  // The grid's (n + 1)^2 vertices on a unit sphere, a little off the origin.
  std::vector<float> positions;
  for (int i = 0; i <= n; ++i)
    for (int j = 0; j <= n; ++j) {
      double lat = M_PI * (double(i) / n - 0.5), lon = 2 * M_PI * double(j) / n;
      positions.push_back(float(std::cos(lat) * std::cos(lon) + 100));
      positions.push_back(float(std::cos(lat) * std::sin(lon) - 50));
      positions.push_back(float(std::sin(lat) + 20));
    }
  std::vector<uint32_t> indices;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      uint32_t a = uint32_t(i * (n + 1) + j), b = a + 1, c = a + uint32_t(n + 1), d = c + 1;
      indices.insert(indices.end(), {a, b, d, a, d, c});
    }
  // The eye 7 radii from the centre, looking at it: about 190 pixels
  // across at 45 degrees in 512x512.
  Camera cam;
  cam.eye = {100, -50, 27};
  cam.fovy_deg = 45;
  cam.aspect = 1;
  cam.near = 0.1;
  cam.rotation = Quatd{};  // identity: looking down -Z at the sphere
  Mat4d rel = Mat4d::identity();
  for (int k = 0; k < 3; ++k) rel.at(k, 3) = -cam.eye[k];
  WindowTransform t{viewRotation(cam) * rel, projectionMatrix(cam), 512, 512, 8};
  WindowVertices v;
  std::vector<uint32_t> out(indices.size());
  std::vector<double> project_ns, project_avx2_ns, scalar_ns, avx2_ns;
  size_t kept = 0, kept_avx2 = 0;
  const double tris = double(indices.size() / 3);
  auto ns = [](auto a, auto b) { return std::chrono::duration<double, std::nano>(b - a).count(); };
  for (int r = 0; r < runs; ++r) {
    auto t0 = std::chrono::steady_clock::now();
    detail::projectVerticesScalar(positions.data(), positions.size() / 3, t, &v);
    auto t1 = std::chrono::steady_clock::now();
    kept = detail::keepCoveringTrianglesScalar(indices.data(), indices.size(), v, {0, 0, 512, 512},
                                               out.data());
    auto t2 = std::chrono::steady_clock::now();
    project_ns.push_back(ns(t0, t1) / double(positions.size() / 3));
    scalar_ns.push_back(ns(t1, t2) / tris);
    if (detail::haveAvx2()) {
      WindowVertices v2;
      auto t4 = std::chrono::steady_clock::now();
      detail::projectVerticesAvx2(positions.data(), positions.size() / 3, t, &v2);
      project_avx2_ns.push_back(ns(t4, std::chrono::steady_clock::now()) /
                                double(positions.size() / 3));
      if (std::memcmp(v.data(), v2.data(), v.size() * sizeof(WindowVertex)) != 0) {
        std::fprintf(stderr, "coverage_bench: the AVX2 projection differs\n");
        return 1;
      }
      auto t3 = std::chrono::steady_clock::now();
      kept_avx2 = detail::keepCoveringTrianglesAvx2(indices.data(), indices.size(), v,
                                                    {0, 0, 512, 512}, out.data());
      avx2_ns.push_back(ns(t3, std::chrono::steady_clock::now()) / tris);
    }
  }
  auto median = [](std::vector<double> x) {
    std::sort(x.begin(), x.end());
    return x.empty() ? 0.0 : x[x.size() / 2];
  };
  std::printf("portable: project %.2f ns/vertex, keep %.2f ns/triangle", median(project_ns),
              median(scalar_ns));
  if (detail::haveAvx2())
    std::printf("; AVX2: project %.2f, keep %.2f (the same vertices; kept %s)",
                median(project_avx2_ns), median(avx2_ns),
                kept_avx2 == kept ? "the same" : "OTHERS");
  std::printf(", kept %zu of %zu triangles\n", kept / 3, indices.size() / 3);
  return kept_avx2 == kept || !detail::haveAvx2() ? 0 : 1;
}
