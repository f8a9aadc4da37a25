// Benchmark (not a test): the cache's per-object and per-miss costs, for the
// A/Bs of docs/benchmarks.md ("Issue 14: hot paths (A/B)", "Cache").
//
//   cache_bench lru [RUNS]               LruBudget alone: CPU ns per access
//   cache_bench miss SCENE_DIR [RUNS]    per GPU miss: the manifest lookup
//                                        (geometryFileBytes) against decoding
//   cache_bench ramdir SCENE_DIR DIR [THREADS] [RUNS]
//                                        HostCache::get over a RAM-disk level
//                                        from THREADS threads: wall and CPU
//                                        ns per get
//
// Each prints the median over RUNS (default 7) passes.
#include <time.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "atomic_file.h"
#include "error.h"
#include "host_cache.h"
#include "lru.h"
#include "scene.h"

using namespace dmmr;

namespace {

double cpuSeconds() {
  timespec t;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return double(t.tv_sec) + double(t.tv_nsec) * 1e-9;
}

double wallSeconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

// A walkthrough's pattern: 20000 geometries; each frame touches a window of
// 4000 in ascending order, sliding by 40 a frame, with 30 % of the window
// skipped at random (culled). `fraction`: the budget against the window's
// bytes (below 1: misses every frame).
void benchLru(int runs) {
  const uint32_t keys = 20000, window = 4000, frames = 300;
  std::mt19937 rng(7);
  std::vector<uint64_t> bytes(keys);
  for (auto& b : bytes) b = 1000 + rng() % 100'000;
  std::vector<std::vector<uint32_t>> lists(frames);
  for (uint32_t f = 0; f < frames; ++f)
    for (uint32_t k = f * 40; k < f * 40 + window; ++k)
      if (rng() % 10 >= 3) lists[f].push_back(k % keys);
  uint64_t window_bytes = 0;
  for (uint32_t k : lists[0]) window_bytes += bytes[k];
  for (double fraction : {2.0, 0.5}) {
    std::vector<double> ns;
    uint64_t hits = 0, accesses = 0;
    for (int run = 0; run < runs; ++run) {
      LruBudget lru(uint64_t(double(window_bytes) * fraction), Eviction::FrameLru);
      std::vector<uint32_t> evicted;
      hits = accesses = 0;
      double t0 = cpuSeconds();
      for (uint32_t f = 0; f < frames; ++f) {
        lru.nextFrame();
        for (uint32_t k : lists[f]) {
          ++accesses;
          if (lru.touch(k)) {
            ++hits;
          } else {
            evicted.clear();
            lru.insert(k, bytes[k], &evicted);
          }
        }
      }
      ns.push_back((cpuSeconds() - t0) * 1e9 / double(accesses));
    }
    std::printf("lru budget %.1fx window: %.1f CPU ns per access (hit rate %.3f, %llu accesses)\n",
                fraction, median(ns), double(hits) / double(accesses),
                (unsigned long long)accesses);
  }
}

// What a GPU miss costs on the host side once the file is in RAM: the
// manifest lookup (geometryFileBytes: snprintf and a map<string> find), the
// file's path as decodeGeometryFile builds it for its errors, decoding the
// file (decodeGeometryFile), and the whole HostCache::get (a RAM hit: lock,
// LRU, size check, decode).
void benchMiss(const std::string& dir, int runs) {
  Scene s = loadScene(dir, false);
  uint32_t n = s.manifest.geometries;
  std::vector<std::vector<uint8_t>> files;
  for (uint32_t g = 0; g < n; ++g) files.push_back(readGeometryFile(s, g));
  std::vector<double> lookup, path, decode, get;
  uint64_t sink = 0;
  HostCache cache(s, {});
  for (uint32_t g = 0; g < n; ++g) cache.get(g);  // all in RAM
  for (int run = 0; run < runs; ++run) {
    double t0 = cpuSeconds();
    for (int rep = 0; rep < 20; ++rep)
      for (uint32_t g = 0; g < n; ++g) sink += geometryFileBytes(s, g);
    lookup.push_back((cpuSeconds() - t0) * 1e9 / (20.0 * n));
    t0 = cpuSeconds();
    for (int rep = 0; rep < 20; ++rep)
      for (uint32_t g = 0; g < n; ++g) sink += (s.dir + "/" + geometryFileName(g)).size();
    path.push_back((cpuSeconds() - t0) * 1e9 / (20.0 * n));
    t0 = cpuSeconds();
    for (uint32_t g = 0; g < n; ++g) sink += decodeGeometryFile(s, g, files[g]).triangleCount();
    decode.push_back((cpuSeconds() - t0) * 1e9 / n);
    t0 = cpuSeconds();
    for (uint32_t g = 0; g < n; ++g) sink += cache.get(g)->triangleCount();
    get.push_back((cpuSeconds() - t0) * 1e9 / n);
  }
  std::printf(
      "miss: %u geometries; CPU ns per geometry: lookup %.0f, path %.0f, decode %.0f, "
      "get %.0f (lookup %.1f %%, path %.1f %% of get) [%llu]\n",
      n, median(lookup), median(path), median(decode), median(get),
      100 * median(lookup) / median(get), 100 * median(path) / median(get),
      (unsigned long long)(sink & 1));
}

// get() from THREADS threads over a RAM-disk level holding every geometry
// (hits: file read, size check, decode), and over one holding a fifth
// (misses too: disk reads, RAM-disk writes and deletes).
void benchRamDir(const std::string& dir, const std::string& ramdir, int threads, int runs) {
  Scene s = loadScene(dir, false);
  uint32_t n = s.manifest.geometries;
  for (uint64_t budget : {LruBudget::kUnlimited, s.manifest.geometry_bytes / 5}) {
    std::vector<double> wall, cpu;
    for (int run = 0; run < runs; ++run) {
      HostCache cache(s, {budget, ramdir});
      for (uint32_t g = 0; g < n; ++g) cache.get(g);  // warm
      const int per_thread = int(4 * n);
      double w0 = wallSeconds(), c0 = cpuSeconds();
      std::vector<std::thread> pool;
      for (int t = 0; t < threads; ++t)
        pool.emplace_back([&, t] {
          std::mt19937 rng(unsigned(t + 1));
          for (int i = 0; i < per_thread; ++i) cache.get(uint32_t(rng() % n));
        });
      for (auto& t : pool) t.join();
      double gets = double(per_thread) * threads;
      wall.push_back((wallSeconds() - w0) * 1e9 / gets);
      cpu.push_back((cpuSeconds() - c0) * 1e9 / gets);
    }
    std::printf("ramdir %s, %d threads: %.0f wall ns, %.0f CPU ns per get\n",
                budget == LruBudget::kUnlimited ? "unlimited" : "budget 1/5", threads, median(wall),
                median(cpu));
  }
}

}  // namespace

int main(int argc, char** argv) {
  std::string mode = argc > 1 ? argv[1] : "";
  auto runsAt = [&](int i) { return argc > i ? std::max(1, std::atoi(argv[i])) : 7; };
  try {
    if (mode == "lru" && argc <= 3) {
      benchLru(runsAt(2));
    } else if (mode == "miss" && (argc == 3 || argc == 4)) {
      benchMiss(argv[2], runsAt(3));
    } else if (mode == "ramdir" && argc >= 4 && argc <= 6) {
      benchRamDir(argv[2], argv[3], argc > 4 ? std::max(1, std::atoi(argv[4])) : 2, runsAt(5));
    } else {
      std::fprintf(stderr,
                   "usage: cache_bench lru [RUNS] | miss SCENE_DIR [RUNS] | "
                   "ramdir SCENE_DIR RAM_DIR [THREADS] [RUNS]\n");
      return 2;
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cache_bench: %s\n", e.what());
    return 1;
  }
  return 0;
}
