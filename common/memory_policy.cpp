#include "memory_policy.h"

#include <cstdlib>  // defines __GLIBC__ on glibc, which the #if below needs
#include <cstring>
#include <fstream>
#include <sstream>

#if defined(__GLIBC__)
#include <malloc.h>
#include <unistd.h>
#endif

namespace dmmr {

namespace {

#if defined(__GLIBC__) && !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__)
constexpr bool kGlibcMalloc = true;
#else
constexpr bool kGlibcMalloc = false;  // or a sanitizer's allocator
#endif

constexpr const char* kHugeTlb = "glibc.malloc.hugetlb";
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

bool keepFreedMemory() {
#if defined(__GLIBC__)
  // Setting either threshold also ends glibc's dynamic adjustment of both.
  return mallopt(M_MMAP_THRESHOLD, 32 << 20) == 1 && mallopt(M_TRIM_THRESHOLD, 256 << 20) == 1;
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

bool useHugePageHeap() {
  if (!kGlibcMalloc || !tunablesAskHugePages(std::getenv("GLIBC_TUNABLES"))) return false;
#if defined(__GLIBC__)
  return mallopt(M_ARENA_MAX, 1) == 1;
#else
  return false;
#endif
}

void applyMemoryPolicy(bool keep_freed, bool huge_pages, char** argv) {
  if (huge_pages) {
    restartWithHugePages(argv);  // returns unless it restarts
    useHugePageHeap();
  }
  if (keep_freed) keepFreedMemory();
}

}  // namespace dmmr
