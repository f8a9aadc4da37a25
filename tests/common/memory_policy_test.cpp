#include "memory_policy.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

#include "test_support.h"
#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace dmmr {
namespace {

// glibc's malloc, not a sanitizer's, which ignores mallopt.
const bool kGlibcMalloc = glibcMalloc();

// Without the policy a fresh process serves 8 MiB with mmap (threshold
// 128 KiB), so each frame's buffers would be new pages; with it they come
// from the heap, while blocks above 32 MiB still get their own mapping.
TEST(MemoryPolicy, BlocksUpTo32MiBComeFromTheHeapAndLargerOnesAreMapped) {
  if (!kGlibcMalloc) {
    keepFreedMemory();  // harmless there
    GTEST_SKIP() << "malloc is not glibc's";
  }
#if defined(__GLIBC__)
  ASSERT_TRUE(keepFreedMemory());
  const size_t mapped0 = mallinfo2().hblks;
  void* medium = std::malloc(size_t(8) << 20);
  ASSERT_NE(medium, nullptr);
  EXPECT_EQ(mallinfo2().hblks, mapped0);
  void* large = std::malloc(size_t(48) << 20);
  ASSERT_NE(large, nullptr);
  EXPECT_EQ(mallinfo2().hblks, mapped0 + 1);
  std::free(large);
  std::free(medium);
  // A freed block's pages stay: the same request is served again without
  // growing the mapped count.
  void* again = std::malloc(size_t(8) << 20);
  EXPECT_EQ(mallinfo2().hblks, mapped0);
  std::free(again);
#endif
}

TEST(MemoryPolicy, HugePagesAreAddedToTheTunablesUnlessTheyAreSetThere) {
  EXPECT_EQ(tunablesWithHugePages(nullptr), "glibc.malloc.hugetlb=1");
  EXPECT_EQ(tunablesWithHugePages(""), "glibc.malloc.hugetlb=1");
  EXPECT_EQ(tunablesWithHugePages("glibc.malloc.arena_max=2"),
            "glibc.malloc.arena_max=2:glibc.malloc.hugetlb=1");
  // Set outside, to anything: that choice stands.
  EXPECT_EQ(tunablesWithHugePages("glibc.malloc.hugetlb=0"), "");
  EXPECT_EQ(tunablesWithHugePages("glibc.malloc.tcache_count=0:glibc.malloc.hugetlb=2"), "");
  // Another tunable whose name begins the same is not this one.
  EXPECT_EQ(tunablesWithHugePages("glibc.malloc.hugetlbx=1"),
            "glibc.malloc.hugetlbx=1:glibc.malloc.hugetlb=1");
}

TEST(MemoryPolicy, TunablesAskHugePagesUnlessUnsetOrZero) {
  EXPECT_FALSE(tunablesAskHugePages(nullptr));
  EXPECT_FALSE(tunablesAskHugePages(""));
  EXPECT_FALSE(tunablesAskHugePages("glibc.malloc.hugetlb=0"));
  EXPECT_FALSE(tunablesAskHugePages("glibc.malloc.hugetlb="));
  EXPECT_FALSE(tunablesAskHugePages("glibc.malloc.hugetlbx=1"));
  EXPECT_TRUE(tunablesAskHugePages("glibc.malloc.hugetlb=1"));
  EXPECT_TRUE(tunablesAskHugePages("glibc.malloc.arena_max=1:glibc.malloc.hugetlb=2"));
}

TEST(MemoryPolicy, TheKernelGivesHugePagesOnRequestInItsAlwaysAndMadviseModes) {
  EXPECT_TRUE(hugePagesAllowed("always [madvise] never\n"));
  EXPECT_TRUE(hugePagesAllowed("[always] madvise never\n"));
  EXPECT_FALSE(hugePagesAllowed("always madvise [never]\n"));
  EXPECT_FALSE(hugePagesAllowed(""));  // no such file: a kernel without them
}

// The whole path in a fresh process: the restart, the one heap and the
// kernel's huge pages. 24 MiB touched page by page from a new thread takes a
// fault per 4 KiB (6,144) without huge pages and one per 2 MiB (12, a few
// more where one is not to be had) with them.
TEST(MemoryPolicy, AThreadsFreshMemoryFaultsHugePagesAtATimeWithThePolicy) {
  if (!kGlibcMalloc) GTEST_SKIP() << "malloc is not glibc's";
  std::ifstream file("/sys/kernel/mm/transparent_hugepage/enabled");
  std::stringstream mode;
  mode << file.rdbuf();
  auto probe = [](const char* setting, int* status) {
    return test::runCapture("env -u GLIBC_TUNABLES -u DMMR_HUGE_PAGES_RESTARTED " +
                                test::tool("huge_pages_probe") + " " + setting,
                            status);
  };
  auto faultsOf = [](const std::string& out) {
    size_t at = out.find("faults=");
    return at == std::string::npos ? -1L : std::atol(out.c_str() + at + 7);
  };
  int status = -1;
  const std::string on = probe("on", &status);
  ASSERT_EQ(status, 0) << on;
  if (!hugePagesAllowed(mode.str())) {
    EXPECT_NE(on.find("tunables= "), std::string::npos) << "no restart without huge pages: " << on;
    GTEST_SKIP() << "this kernel gives no huge pages: " << mode.str();
  }
  EXPECT_NE(on.find("tunables=glibc.malloc.hugetlb=1 "), std::string::npos) << on;
  EXPECT_LT(faultsOf(on), 6144 / 4) << on;
  const std::string off = probe("off", &status);
  ASSERT_EQ(status, 0) << off;
  EXPECT_NE(off.find("tunables= "), std::string::npos) << off;
  // In "always" mode every heap gets huge pages, asked or not.
  if (mode.str().find("[madvise]") != std::string::npos) {
    EXPECT_GE(faultsOf(off), 6144 * 3 / 4) << off;
  }
}

// Pre-touching, without huge pages: 48 MiB touched and freed at start-up,
// then 24 MiB touched from a new thread reuse those pages (the one heap)
// instead of faulting 6,144 of their own.
TEST(MemoryPolicy, AThreadGrowsIntoPreTouchedHeapWithoutFaulting) {
  if (!kGlibcMalloc) GTEST_SKIP() << "malloc is not glibc's";
  int status = -1;
  const std::string out = test::runCapture("env -u GLIBC_TUNABLES -u DMMR_HUGE_PAGES_RESTARTED " +
                                               test::tool("huge_pages_probe") + " pretouch",
                                           &status);
  ASSERT_EQ(status, 0) << out;
  EXPECT_NE(out.find("tunables= "), std::string::npos) << "huge pages stay off: " << out;
  const size_t at = out.find("faults=");
  ASSERT_NE(at, std::string::npos) << out;
  EXPECT_LT(std::atol(out.c_str() + at + 7), 6144 / 8) << out;
}

TEST(MemoryPolicy, AutoPreTouchIsTwiceTheGeometryAndFramesAtMost192MiB) {
  EXPECT_EQ(preTouchBytes(-1, 0), size_t(16) << 20);
  EXPECT_EQ(preTouchBytes(-1, uint64_t(10) << 20), size_t(36) << 20);
  EXPECT_EQ(preTouchBytes(-1, uint64_t(1) << 40), kMaxPreTouch);
  // A size given in MiB stands, whatever the scene.
  EXPECT_EQ(preTouchBytes(40, uint64_t(1) << 40), size_t(40) << 20);
  EXPECT_EQ(preTouchBytes(0, uint64_t(1) << 40), 0u);
  EXPECT_LT(kMaxPreTouch, size_t(256) << 20);  // below keepFreedMemory's trim threshold
}

}  // namespace
}  // namespace dmmr
