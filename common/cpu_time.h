// CPU time of the calling thread: a stage's cost that does not depend on who
// else runs on the machine (its wall time includes waiting for a core).
#pragma once

#include <sys/resource.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <ctime>

namespace dmmr {

// Milliseconds of CPU the calling thread has used (CLOCK_THREAD_CPUTIME_ID).
// Differences of two calls on one thread are that thread's CPU time between
// them; llvmpipe's rasteriser threads are not the caller's (run with
// LP_NUM_THREADS=0 so that a GL stage rasterises on its own thread).
inline double threadCpuMs() {
  timespec ts{};
  ::clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return double(ts.tv_sec) * 1e3 + double(ts.tv_nsec) * 1e-6;
}

// The calling thread's kernel time and minor page faults so far
// (getrusage(RUSAGE_THREAD)). Differences of two calls on one thread split a
// stage's CPU time (threadCpuMs) into user and kernel parts: on a virtual
// machine the kernel's cost of a page fault (mostly zeroing a fresh page)
// depends on the host's load and moved by up to 10x between runs of one
// command (docs/benchmarks.md, "Kernel time"), so a cost judged by CPU time
// is shown beside its kernel part. Linux splits a thread's exact run time by
// its sampled user and kernel ticks: the kernel part of a short interval is
// approximate, the sum over a run is not.
struct ThreadUsage {
  double sys_ms = 0;
  uint64_t minor_faults = 0;
};
inline ThreadUsage threadUsage() {
  rusage ru{};
  if (::getrusage(RUSAGE_THREAD, &ru) != 0) return {};
  return {double(ru.ru_stime.tv_sec) * 1e3 + double(ru.ru_stime.tv_usec) * 1e-3,
          uint64_t(ru.ru_minflt)};
}

// Whether llvmpipe rasterises on the calling GL thread (LP_NUM_THREADS=0,
// which mpirun -x gives every rank alike): then a GL thread's CPU time is its
// whole cost, and costs judged by it hold however many processes share the
// machine's cores.
inline bool rasterisesOnCallingThread() {
  const char* lp = std::getenv("LP_NUM_THREADS");
  return lp && std::strcmp(lp, "0") == 0;
}

}  // namespace dmmr
