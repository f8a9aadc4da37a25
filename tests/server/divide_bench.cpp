// Benchmark (not a test): the median time of divideFrame over 21 runs for N
// random footprints on a 1024x1024 frame and 2, 4 and 8 clients.
//
//   divide_bench [N ...]     default N: 10000 50000 100000 200000
//
// Footprints are 1..64 pixels a side (a few up to 512), uniformly placed,
// with weights 1..100000 and ascending object indices, as planFrame passes
// them (culling yields ascending indices).
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <vector>

#include "divide.h"

using namespace dmmr;

namespace {

std::vector<Footprint> randomFootprints(uint64_t seed, int n, int width, int height) {
  std::mt19937_64 g(seed);
  auto range = [&](int lo, int hi) { return lo + int(g() % uint64_t(hi - lo + 1)); };
  std::vector<Footprint> out;
  out.reserve(size_t(n));
  for (int i = 0; i < n; ++i) {
    bool big = g() % 100 == 0;
    int w = range(1, big ? 512 : 64), h = range(1, big ? 512 : 64);
    int x = range(0, width - w), y = range(0, height - h);
    Footprint f;
    f.object = uint32_t(i);
    f.x0 = x;
    f.x1 = x + w;
    f.y0 = y;
    f.y1 = y + h;
    f.weight = uint64_t(range(1, 100000));
    out.push_back(f);
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<int> sizes = {10000, 50000, 100000, 200000};
  if (argc > 1) {
    sizes.clear();
    for (int i = 1; i < argc; ++i) sizes.push_back(std::atoi(argv[i]));
  }
  const Rect frame{0, 0, 1024, 1024};
  const int runs = 21;
  std::printf("%9s %8s %12s %12s %12s\n", "objects", "clients", "median_ms", "min_ms", "listed");
  for (int n : sizes) {
    std::vector<Footprint> items = randomFootprints(uint64_t(n), n, frame.w, frame.h);
    for (int clients : {2, 4, 8}) {
      std::vector<double> ms;
      size_t listed = 0;
      for (int r = 0; r < runs; ++r) {
        auto t0 = std::chrono::steady_clock::now();
        std::vector<Region> regions = divideFrame(items, frame, clients);
        auto t1 = std::chrono::steady_clock::now();
        ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
        listed = 0;
        for (const Region& reg : regions) listed += reg.objects.size();
      }
      std::sort(ms.begin(), ms.end());
      std::printf("%9d %8d %12.3f %12.3f %12zu\n", n, clients, ms[ms.size() / 2], ms.front(),
                  listed);
    }
  }
  return 0;
}
