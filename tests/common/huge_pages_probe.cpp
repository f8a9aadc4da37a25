// Not a test by itself: memory_policy_test runs it in a fresh process.
// `huge_pages_probe on|off|pretouch` applies the memory policy with huge
// pages on or off (applyMemoryPolicy, which may restart it), or with huge
// pages off and 48 MiB pre-touched (preTouchHeap); then a new thread touches
// every 4 KiB page of a fresh 24 MiB block (served by the heap: below
// keepFreedMemory's 32 MiB threshold) and it prints
// "tunables=<GLIBC_TUNABLES> faults=<the thread's minor page faults>".
#include <sys/resource.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>

#include "memory_policy.h"

int main(int argc, char** argv) {
  const std::string mode = argc == 2 ? argv[1] : "";
  if (mode != "on" && mode != "off" && mode != "pretouch") {
    std::fprintf(stderr, "usage: huge_pages_probe on|off|pretouch\n");
    return 2;
  }
  dmmr::applyMemoryPolicy(true, mode == "on", mode == "pretouch", argv);
  if (mode == "pretouch" && dmmr::preTouchHeap(size_t(48) << 20) == 0) return 1;
  long faults = -1;
  std::thread toucher([&faults] {
    const size_t bytes = size_t(24) << 20;
    rusage before{}, after{};
    getrusage(RUSAGE_THREAD, &before);
    auto* block = static_cast<volatile char*>(std::malloc(bytes));
    if (!block) return;
    for (size_t at = 0; at < bytes; at += 4096) block[at] = 1;
    getrusage(RUSAGE_THREAD, &after);
    faults = after.ru_minflt - before.ru_minflt;
    std::free(const_cast<char*>(block));
  });
  toucher.join();
  const char* tunables = std::getenv("GLIBC_TUNABLES");
  std::printf("tunables=%s faults=%ld\n", tunables ? tunables : "", faults);
  return faults < 0 ? 1 : 0;
}
