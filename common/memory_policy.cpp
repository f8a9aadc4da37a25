#include "memory_policy.h"

#include <algorithm>
#include <cstdlib>  // defines __GLIBC__ on glibc, which the #if below needs
#include <cstring>
#include <fstream>
#include <sstream>
#include <vector>

#if defined(__GLIBC__)
#include <malloc.h>
#include <unistd.h>
#endif

namespace dmmr {

namespace {

// A sanitizer's allocator replaces glibc's: GCC says so with
// __SANITIZE_*__, clang with __has_feature.
#if defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || \
    __has_feature(memory_sanitizer)
#define DMMR_SANITIZER_MALLOC 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define DMMR_SANITIZER_MALLOC 1
#endif

#if defined(__GLIBC__) && !defined(DMMR_SANITIZER_MALLOC)
constexpr bool kGlibcMalloc = true;
#else
constexpr bool kGlibcMalloc = false;  // or a sanitizer's allocator
#endif

constexpr const char* kHugeTlb = "glibc.malloc.hugetlb";
// What preTouchHeap needs of the policy applied so far.
bool kept_freed = false, one_heap = false;
// Set across the exec, so that a glibc that dropped GLIBC_TUNABLES (a
// set-uid program) cannot make the restart loop.
constexpr const char* kRestarted = "DMMR_HUGE_PAGES_RESTARTED";

// The value `current` gives glibc.malloc.hugetlb (tunables are
// "name=value" separated by ':'), or null when it sets none.
const char* hugeTlbValue(const char* current, size_t* length) {
  if (!current) return nullptr;
  const size_t name = std::strlen(kHugeTlb);
  for (const char* at = current; *at;) {
    const char* end = std::strchr(at, ':');
    if (!end) end = at + std::strlen(at);
    if (size_t(end - at) > name && std::strncmp(at, kHugeTlb, name) == 0 && at[name] == '=') {
      *length = size_t(end - at) - name - 1;
      return at + name + 1;
    }
    at = *end ? end + 1 : end;
  }
  return nullptr;
}

}  // namespace

bool glibcMalloc() {
  return kGlibcMalloc;
}

bool keepFreedMemory() {
#if defined(__GLIBC__)
  // Setting either threshold also ends glibc's dynamic adjustment of both.
  kept_freed =
      mallopt(M_MMAP_THRESHOLD, 32 << 20) == 1 && mallopt(M_TRIM_THRESHOLD, 256 << 20) == 1;
  return kept_freed;
#else
  return false;
#endif
}

std::string tunablesWithHugePages(const char* current) {
  size_t length = 0;
  if (hugeTlbValue(current, &length)) return {};
  std::string out = current ? current : "";
  if (!out.empty()) out += ':';
  return out + kHugeTlb + "=1";
}

bool tunablesAskHugePages(const char* current) {
  size_t length = 0;
  const char* value = hugeTlbValue(current, &length);
  return value && length > 0 && !(length == 1 && value[0] == '0');
}

bool hugePagesAllowed(const std::string& enabled_file_text) {
  return enabled_file_text.find("[always]") != std::string::npos ||
         enabled_file_text.find("[madvise]") != std::string::npos;
}

void restartWithHugePages(char** argv) {
  if (!kGlibcMalloc || !argv || std::getenv(kRestarted)) return;
  const char* current = std::getenv("GLIBC_TUNABLES");
  std::string tunables = tunablesWithHugePages(current);
  if (tunables.empty()) return;
  std::ifstream mode("/sys/kernel/mm/transparent_hugepage/enabled");
  std::stringstream text;
  text << mode.rdbuf();
  if (!hugePagesAllowed(text.str())) return;
#if defined(__GLIBC__)
  if (setenv("GLIBC_TUNABLES", tunables.c_str(), 1) != 0 || setenv(kRestarted, "1", 1) != 0) return;
  // The program's own path, not /proc/self/exe: the process is named after
  // the file it runs (ps, pgrep, perf would show "exe").
  char self[4096];
  ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
  if (n > 0) {
    self[n] = '\0';
    execv(self, argv);
  }
  // The exec failed: run on as started.
  if (current)
    setenv("GLIBC_TUNABLES", current, 1);
  else
    unsetenv("GLIBC_TUNABLES");
#endif
}

bool useOneHeap() {
  if (!kGlibcMalloc) return false;
#if defined(__GLIBC__)
  if (mallopt(M_ARENA_MAX, 1) != 1) return false;
  one_heap = true;
  return true;
#else
  return false;
#endif
}

size_t preTouchHeap(size_t bytes) {
  if (!kGlibcMalloc || !kept_freed || !one_heap) return 0;
  bytes = std::min(bytes, kMaxPreTouch);
  // 16 MiB blocks: below the 32 MiB mmap threshold, so they come from the
  // heap, and freed together they merge into its top.
  constexpr size_t kBlock = size_t(16) << 20;
  // Reserved first: the list's own growth must not land between the blocks,
  // or freed they would not merge into the heap's top (one free region that
  // any later request can be cut from).
  std::vector<void*> blocks;
  blocks.reserve(bytes / kBlock + 1);
  size_t touched = 0;
  for (; touched < bytes; touched += kBlock) {
    auto* block = static_cast<volatile char*>(std::malloc(kBlock));
    if (!block) break;
    for (size_t at = 0; at < kBlock; at += 4096) block[at] = 0;
    blocks.push_back(const_cast<char*>(block));
  }
  for (auto it = blocks.rbegin(); it != blocks.rend(); ++it) std::free(*it);
  return touched;
}

size_t preTouchBytes(int64_t option_mib, uint64_t geometry_file_bytes) {
  const uint64_t want =
      option_mib >= 0 ? uint64_t(option_mib) << 20 : 2 * geometry_file_bytes + (uint64_t(16) << 20);
  return size_t(std::min<uint64_t>(want, kMaxPreTouch));
}

void applyMemoryPolicy(bool keep_freed, bool huge_pages, bool pre_touch, char** argv) {
  if (huge_pages) restartWithHugePages(argv);  // returns unless it restarts
  if ((huge_pages && tunablesAskHugePages(std::getenv("GLIBC_TUNABLES"))) || pre_touch)
    useOneHeap();
  if (keep_freed) keepFreedMemory();
}

}  // namespace dmmr
