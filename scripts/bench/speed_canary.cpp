// A machine-speed probe for benchmarks on shared machines (issue 16).
//
//   speed_canary probe SECONDS   every 100 ms, on each CPU in turn, times a
//                                fixed arithmetic chain and a fixed pointer
//                                chase over 4 MiB by the thread's CPU time;
//                                prints "seconds cpu arith_us chase_us" lines
//   speed_canary touch GIB       writes GIB GiB of fresh memory, one GiB at a
//                                time, and prints the seconds it took: the
//                                cost of first-touch page faults here
//
// A run's stage CPU times can only be compared with another run's when the
// machine ran at one speed for both: the probe shows whether it did.
#include <sched.h>
#include <time.h>
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "cpu_time.h"  // common/: built with -I common (canary_runs.sh)

namespace {

double threadCpuUs() {
  return dmmr::threadCpuMs() * 1e3;
}

double wallS() {
  timespec t{};
  clock_gettime(CLOCK_MONOTONIC, &t);
  return double(t.tv_sec) + double(t.tv_nsec) * 1e-9;
}

int probe(double seconds) {
  int cpus = int(sysconf(_SC_NPROCESSORS_ONLN));
  std::vector<uint32_t> ring(1u << 20);  // 4 MiB: past the L2, as a frame's buffers are
  for (size_t i = 0; i < ring.size(); ++i) ring[i] = uint32_t(i * 2654435761u);
  double t0 = wallS();
  uint64_t sink = 0;
  while (wallS() - t0 < seconds) {
    for (int c = 0; c < cpus; ++c) {
      cpu_set_t set;
      CPU_ZERO(&set);
      CPU_SET(c, &set);
      if (sched_setaffinity(0, sizeof set, &set) != 0) continue;
      double a = threadCpuUs();
      uint64_t x = 1;
      for (int i = 0; i < 300000; ++i) {
        x = x * 6364136223846793005ull + 1442695040888963407ull + (x >> 17);
        asm volatile("" : "+r"(x));  // a dependent chain the compiler keeps
      }
      double b = threadCpuUs();
      uint32_t k = 0;
      for (int i = 0; i < 20000; ++i) {
        k = ring[k & (ring.size() - 1)] ^ uint32_t(i);
        asm volatile("" : "+r"(k));
      }
      double d = threadCpuUs();
      sink += x + k;
      std::printf("%.3f %d %.0f %.0f\n", wallS() - t0, c, b - a, d - b);
    }
    std::fflush(stdout);
    usleep(100000);
  }
  return int(sink & 0);
}

int touch(int gib) {
  double t0 = wallS();
  for (int i = 0; i < gib; ++i) {
    std::unique_ptr<char[]> block(new char[size_t(1) << 30]);
    std::memset(block.get(), 1, size_t(1) << 30);
    asm volatile("" : : "r"(block.get()) : "memory");
  }
  std::printf("touched %d GiB in %.1f s\n", gib, wallS() - t0);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc == 3 && std::string(argv[1]) == "probe" && std::atof(argv[2]) > 0)
    return probe(std::atof(argv[2]));
  if (argc == 3 && std::string(argv[1]) == "touch" && std::atoi(argv[2]) > 0)
    return touch(std::atoi(argv[2]));
  std::fprintf(stderr, "usage: speed_canary probe SECONDS | touch GIB\n");
  return 2;
}
