// Benchmark (not a test): what the threads FramePlanner::footprints spawns
// per frame cost against the projection they share (issue 14). For N random
// boxes in view it times, with footprints()'s projectInSlices: one thread;
// the threads spawned per call as footprints() does (hardware threads, at
// most 8, one per 16384 boxes); and an empty spawn and join alone.
//
//   footprint_bench [N ...]     default N: 16384 32768 65536 131072
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <thread>
#include <vector>

#include "plan.h"

using namespace dmmr;

namespace {

double nowMs() {
  return std::chrono::duration<double, std::milli>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

template <typename F>
double medianMs(int runs, F f) {
  std::vector<double> ms;
  for (int r = 0; r < runs; ++r) {
    double t0 = nowMs();
    f();
    ms.push_back(nowMs() - t0);
  }
  std::sort(ms.begin(), ms.end());
  return ms[ms.size() / 2];
}

// footprints()'s projection, over `threads` slices.
size_t project(const FootprintProjector& p, const std::vector<Box3d>& boxes, size_t threads) {
  return projectInSlices(boxes.size(), threads,
                         [&](size_t k, Footprint* f) { return p(boxes[k], 1000, uint32_t(k), f); })
      .size();
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<size_t> sizes = {16384, 32768, 65536, 131072};
  if (argc > 1) {
    sizes.clear();
    for (int i = 1; i < argc; ++i) sizes.push_back(size_t(std::atol(argv[i])));
  }
  Camera cam;
  cam.eye = {0, 0, 0};
  cam.fovy_deg = 60;
  FootprintProjector projector(cam, 1024, 1024);
  const int runs = 51;
  size_t hw = std::max(1u, std::thread::hardware_concurrency());
  double spawn = medianMs(runs * 4, [] { std::thread([] {}).join(); });
  std::printf("hardware threads %zu; an empty spawn + join: %.1f us (median of %d)\n", hw,
              spawn * 1e3, runs * 4);
  std::printf("%8s %8s %12s %12s %10s\n", "boxes", "threads", "serial_ms", "spawned_ms", "ratio");
  std::mt19937_64 g(7);
  std::uniform_real_distribution<double> u(-1, 1);
  for (size_t n : sizes) {
    std::vector<Box3d> boxes;
    for (size_t i = 0; i < n; ++i) {
      double z = -2 - 50 * (u(g) + 1), x = u(g) * -z * 0.5, y = u(g) * -z * 0.5, s = 0.1;
      Box3d b;
      b.expand(Vec3d{x - s, y - s, z - s});
      b.expand(Vec3d{x + s, y + s, z + s});
      boxes.push_back(b);
    }
    size_t threads = footprintThreads(n);
    size_t sink = 0;
    double one = medianMs(runs, [&] { sink += project(projector, boxes, 1); });
    double many = medianMs(runs, [&] { sink += project(projector, boxes, threads); });
    std::printf("%8zu %8zu %12.3f %12.3f %9.2fx%s\n", n, threads, one, many, one / many,
                sink == 0 ? " " : "");
  }
  return 0;
}
