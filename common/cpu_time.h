// CPU time of the calling thread: a stage's cost that does not depend on who
// else runs on the machine (its wall time includes waiting for a core).
#pragma once

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

// Whether llvmpipe rasterises on the calling GL thread (LP_NUM_THREADS=0,
// which mpirun -x gives every rank alike): then a GL thread's CPU time is its
// whole cost, and costs judged by it hold however many processes share the
// machine's cores.
inline bool rasterisesOnCallingThread() {
  const char* lp = std::getenv("LP_NUM_THREADS");
  return lp && std::strcmp(lp, "0") == 0;
}

}  // namespace dmmr
