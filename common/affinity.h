// Where a rank may run: its CPU affinity, and a warning when mpirun's
// placement leaves a client fewer CPUs than its GL stages' threads.
#pragma once

#include <string>

namespace dmmr {

// The number of CPUs in the calling thread's affinity mask (sched_getaffinity;
// called before any thread is started, the process's). Falls back to
// std::thread::hardware_concurrency when the mask cannot be read. At least 1.
int allowedCpuCount();

// "" when allowed_cpus >= wanted_cpus; otherwise one line (no newline) naming
// client `rank`, both counts and the mpirun options that give it more CPUs.
std::string placementWarning(int rank, int allowed_cpus, int wanted_cpus);

// Names the calling thread (at most 15 characters are kept: Linux's limit), so
// that top -H, perf --comm and gdb tell a rank's stage threads apart.
void nameThisThread(const char* name);

}  // namespace dmmr
