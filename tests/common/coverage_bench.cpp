// Benchmark (not a test): the triangle cull's two loops (coverage.h) on a
// dense mesh seen whole: a sphere tessellated as a latitude-longitude grid
// of N x N quads (2 N^2 triangles, indices in grid order, as a mesh's
// triangles lie after a spatial sort), 190 pixels across in a 512x512
// frame, so that most triangles are under a pixel.
//
//   coverage_bench [N] [RUNS]     defaults: 1024, 9
//
// Prints the median over RUNS of projectVertices' nanoseconds a vertex and
// keepCoveringTriangles' a triangle, and the triangles kept.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
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
  std::vector<double> project_ns, keep_ns;
  size_t kept = 0;
  for (int r = 0; r < runs; ++r) {
    auto t0 = std::chrono::steady_clock::now();
    projectVertices(positions.data(), positions.size() / 3, t, &v);
    auto t1 = std::chrono::steady_clock::now();
    kept = keepCoveringTriangles(indices.data(), indices.size(), v, {0, 0, 512, 512}, out.data());
    auto t2 = std::chrono::steady_clock::now();
    project_ns.push_back(std::chrono::duration<double, std::nano>(t1 - t0).count() /
                         double(positions.size() / 3));
    keep_ns.push_back(std::chrono::duration<double, std::nano>(t2 - t1).count() /
                      double(indices.size() / 3));
  }
  std::sort(project_ns.begin(), project_ns.end());
  std::sort(keep_ns.begin(), keep_ns.end());
  std::printf("project %.2f ns/vertex, keep %.2f ns/triangle, kept %zu of %zu triangles\n",
              project_ns[project_ns.size() / 2], keep_ns[keep_ns.size() / 2], kept / 3,
              indices.size() / 3);
  return 0;
}
