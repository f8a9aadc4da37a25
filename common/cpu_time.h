// CPU time of the calling thread: a stage's cost that does not depend on who
// else runs on the machine (its wall time includes waiting for a core).
#pragma once

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

}  // namespace dmmr
