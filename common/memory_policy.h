// How a long-running renderer asks malloc to keep the memory it frees.
#pragma once

namespace dmmr {

// glibc's malloc by default serves blocks above a threshold (128 KiB, raised
// to the size of the largest such block freed so far, at most 32 MiB) with
// mmap and returns them to the kernel on free, and gives back free memory at
// the top of a heap above twice that. A renderer frees and allocates blocks
// of megabytes every frame (read-back pixels, index streams, llvmpipe's
// buffers) whose sizes change with the region, so each frame starts on fresh
// pages and pays a page fault per 4 KiB (docs/benchmarks.md, "Page faults
// from malloc"). keepFreedMemory() fixes the thresholds instead: blocks up
// to 32 MiB come from the heaps and the heaps keep up to 256 MiB of free
// memory at their tops, so a frame reuses the pages the last one freed. The
// price is resident memory that stays at its peak. Call it once at start-up,
// before threads are made. Returns false where malloc is not glibc's (it then
// does nothing).
bool keepFreedMemory();

}  // namespace dmmr
