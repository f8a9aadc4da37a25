// How a long-running renderer asks malloc to keep the memory it frees, and
// to back its heap with transparent huge pages.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

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

// Whether malloc is glibc's own: glibc, and no sanitizer's allocator in its
// place.
bool glibcMalloc();

// Huge pages. Memory a process touches for the first time still faults a
// page at a time: a client's heap grows with every object new to it. On a
// virtual machine such a fault costs about 11 us per 4 KiB page, while a
// 2 MiB transparent huge page maps 512 of them in one fault
// (docs/benchmarks.md, "Huge pages"). glibc backs its heap with huge pages
// only when asked before it starts (the tunable glibc.malloc.hugetlb=1 in
// GLIBC_TUNABLES), and then only its main heap, not the other threads'
// arenas. So a tool that wants them calls restartWithHugePages() first thing,
// then, once restarted, useOneHeap() before it starts threads
// (applyMemoryPolicy does both).

// The GLIBC_TUNABLES value that adds glibc.malloc.hugetlb=1 to `current`
// (null or empty: none set); empty when `current` already sets
// glibc.malloc.hugetlb, whatever to: a choice made outside stands.
std::string tunablesWithHugePages(const char* current);

// Whether `current` (a GLIBC_TUNABLES value, may be null) asks glibc for
// huge pages: glibc.malloc.hugetlb set to anything but 0.
bool tunablesAskHugePages(const char* current);

// Whether the kernel gives transparent huge pages to memory that asks for
// them, from the text of /sys/kernel/mm/transparent_hugepage/enabled (the
// selected mode in brackets): true for "always" and "madvise".
bool hugePagesAllowed(const std::string& enabled_file_text);

// Re-executes this program (the file /proc/self/exe names, the same `argv`)
// once, with glibc.malloc.hugetlb=1 added to GLIBC_TUNABLES, when malloc is
// glibc's (no sanitizer), the kernel allows huge pages and GLIBC_TUNABLES
// does not set that tunable yet. Returns in every other case, and when the
// exec fails (the program then runs on without them). Call it before any
// thread, MPI or GL context starts, and before any output that must not
// repeat. The restart costs a second start of the dynamic linker (about
// 0.1 s of CPU here).
void restartWithHugePages(char** argv);

// Puts every thread on glibc's main heap (M_ARENA_MAX 1): what one thread
// frees or pre-touches, another reuses. Returns false where malloc is not
// glibc's. Call it before threads are made.
bool useOneHeap();

// Pre-touching. The caches of a client grow with every object new to it,
// and each page they grow into is touched for the first time in the frame
// that needs it: a page fault, and on a virtual machine the host backing the
// page (docs/benchmarks.md, "Pre-touching the heap"). preTouchHeap(bytes)
// allocates `bytes` from the heap in blocks below the mmap threshold, writes
// a byte per 4 KiB page and frees them: the heap keeps them at its top, so
// the caches later grow into pages already mapped, and the cost moves to
// start-up (as a JVM's AlwaysPreTouch). Of use only once freed memory is kept
// (keepFreedMemory: the trim threshold is above kMaxPreTouch) and every
// thread allocates from the one heap (useOneHeap); otherwise, or where malloc
// is not glibc's, it does nothing. Returns the bytes touched.
size_t preTouchHeap(size_t bytes);
// The most preTouchHeap is asked for: below keepFreedMemory's 256 MiB trim
// threshold, so that the heap keeps it.
inline constexpr size_t kMaxPreTouch = size_t(192) << 20;
// The bytes to pre-touch for --pre-touch `option_mib` (cli_options.h: MiB,
// 0 none) in a scene of `geometry_file_bytes`, at most kMaxPreTouch. Auto
// (-1) is what a renderer's caches will grow into: twice the geometry file
// bytes (the RAM level holds the files, the GPU level about as much again
// decoded) plus 16 MiB of frame buffers.
size_t preTouchBytes(int64_t option_mib, uint64_t geometry_file_bytes);

// The start-up policy of a tool's --keep-freed-memory, --huge-pages and
// --pre-touch (cli_options.h): restartWithHugePages(argv) when `huge_pages`;
// useOneHeap() when `huge_pages` and GLIBC_TUNABLES now asks for them
// (tunablesAskHugePages), or when `pre_touch`; then keepFreedMemory() when
// `keep_freed`. preTouchHeap is called later, once the scene's size is
// known.
void applyMemoryPolicy(bool keep_freed, bool huge_pages, bool pre_touch, char** argv);

}  // namespace dmmr
