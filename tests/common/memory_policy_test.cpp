#include "memory_policy.h"

#include <gtest/gtest.h>

#include <cstdlib>
#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace dmmr {
namespace {

#if defined(__GLIBC__) && !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__)
constexpr bool kGlibcMalloc = true;
#else
constexpr bool kGlibcMalloc = false;  // or a sanitizer's allocator, which ignores mallopt
#endif

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

}  // namespace
}  // namespace dmmr
