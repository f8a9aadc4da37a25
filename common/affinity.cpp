#include "affinity.h"

#include <pthread.h>
#include <sched.h>

#include <cerrno>
#include <cstring>
#include <thread>

namespace dmmr {

int allowedCpuCount() {
  // A dynamically sized set: the kernel refuses (EINVAL) a mask smaller than
  // its own, which a fixed cpu_set_t (1024 CPUs) can be on large machines.
  for (int cpus = CPU_SETSIZE; cpus <= (1 << 20); cpus *= 2) {
    cpu_set_t* set = CPU_ALLOC(cpus);
    if (!set) break;
    size_t size = CPU_ALLOC_SIZE(cpus);
    CPU_ZERO_S(size, set);
    int rc = ::sched_getaffinity(0, size, set);
    int count = rc == 0 ? CPU_COUNT_S(size, set) : 0;
    int err = errno;
    CPU_FREE(set);
    if (rc == 0 && count > 0) return count;
    if (rc != 0 && err == EINVAL) continue;
    break;
  }
  unsigned hw = std::thread::hardware_concurrency();
  return hw > 0 ? static_cast<int>(hw) : 1;
}

std::string placementWarning(int rank, int allowed_cpus, int wanted_cpus) {
  if (allowed_cpus >= wanted_cpus) return "";
  return "dmmr-render: client rank " + std::to_string(rank) + " may use " +
         std::to_string(allowed_cpus) + (allowed_cpus == 1 ? " CPU" : " CPUs") +
         " but its GL stages want " + std::to_string(wanted_cpus) +
         "; the stages will share a core (mpirun binds ranks to a core by default: use "
         "--bind-to none on one machine, or --map-by ppr:1:node:PE=N on a cluster)";
}

void nameThisThread(const char* name) {
  char buf[16] = {};
  std::strncpy(buf, name, sizeof buf - 1);
  ::pthread_setname_np(::pthread_self(), buf);  // a diagnostic: failure changes nothing
}

}  // namespace dmmr
