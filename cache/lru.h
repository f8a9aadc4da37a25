// Least-recently-used bookkeeping under a byte budget: which entries one
// level of the geometry cache keeps and which it gives up. Plain data, no
// I/O, GL or threads; the levels (host_cache.h, gpu_cache.h) hold the bytes.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace dmmr {

// Which entry insert() gives up when the budget is full.
enum class Eviction : uint8_t {
  // The least recently used.
  Lru,
  // The least recently used, unless it was used in the current frame too:
  // then the frame's working set exceeds the budget, and LRU would evict,
  // in a walkthrough that draws in the same order every frame, exactly what
  // the next frame needs first (every access a miss). Evicting the most
  // recently used instead keeps the rest of the working set for the next
  // frame. The default.
  FrameLru,
};

class LruBudget {
 public:
  static constexpr uint64_t kUnlimited = UINT64_MAX;

  explicit LruBudget(uint64_t budget = kUnlimited, Eviction eviction = Eviction::FrameLru)
      : budget_(budget), eviction_(eviction) {}

  // Starts a new frame: entries used before it are the first to go.
  void nextFrame() { ++frame_; }

  uint64_t budget() const { return budget_; }
  uint64_t used() const { return used_; }  // never above budget()
  size_t size() const { return size_; }
  bool contains(uint32_t key) const { return key < entries_.size() && entries_[key].held; }

  // Whether an entry of `bytes` can be held at all. One that cannot is used
  // uncached by the level (and counted there), never squeezed in.
  bool admits(uint64_t bytes) const { return bytes <= budget_; }

  // Makes `key` the most recently used. Returns false, changing nothing,
  // when it is absent.
  bool touch(uint32_t key);

  // Adds absent `key` of `bytes` (admits(bytes) must hold) as the most
  // recently used, first evicting least recently used entries until it fits.
  // Appends the evicted keys to *evicted, in eviction order.
  void insert(uint32_t key, uint64_t bytes, std::vector<uint32_t>* evicted);

  // Adds absent `key` only when it fits in the free space, evicting nothing
  // (for prefetches, which must not push out what a frame is using).
  bool insertIfFree(uint32_t key, uint64_t bytes);

  // Removes `key`; returns its bytes, or 0 when absent.
  uint64_t erase(uint32_t key);

  // Keys from least to most recently used.
  std::vector<uint32_t> order() const;

 private:
  static constexpr uint32_t kNone = UINT32_MAX;
  // Keys are geometry indices, dense from 0: entries are indexed by key and
  // linked in use order through indices (an access is an index, no hash or
  // allocation: docs/benchmarks.md, "Issue 14: hot paths (A/B)").
  struct Entry {
    uint32_t prev = kNone, next = kNone;  // towards least / most recently used
    bool held = false;
    uint64_t bytes = 0;
    uint64_t frame = 0;  // when last used
  };
  void add(uint32_t key, uint64_t bytes);
  void link(uint32_t key);  // as the most recently used
  void unlink(uint32_t key);
  uint32_t victim() const;

  uint64_t budget_;
  Eviction eviction_;
  uint64_t frame_ = 0;
  uint64_t used_ = 0;
  size_t size_ = 0;
  uint32_t first_ = kNone, last_ = kNone;  // least, most recently used
  std::vector<Entry> entries_;             // by key; grows to the largest key added
};

}  // namespace dmmr
