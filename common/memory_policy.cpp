#include "memory_policy.h"

#include <cstdlib>  // defines __GLIBC__ on glibc, which the #if below needs

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace dmmr {

bool keepFreedMemory() {
#if defined(__GLIBC__)
  // Setting either threshold also ends glibc's dynamic adjustment of both.
  return mallopt(M_MMAP_THRESHOLD, 32 << 20) == 1 && mallopt(M_TRIM_THRESHOLD, 256 << 20) == 1;
#else
  return false;
#endif
}

}  // namespace dmmr
