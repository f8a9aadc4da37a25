// Least-recently-used bookkeeping under a byte budget: which entries one
// level of the geometry cache keeps and which it gives up. Plain data, no
// I/O, GL or threads; the levels (host_cache.h, gpu_cache.h) hold the bytes.
#pragma once

#include <cstddef>
#include <cstdint>
#include <list>
#include <unordered_map>
#include <vector>

namespace dmmr {

class LruBudget {
 public:
  static constexpr uint64_t kUnlimited = UINT64_MAX;

  explicit LruBudget(uint64_t budget = kUnlimited) : budget_(budget) {}

  uint64_t budget() const { return budget_; }
  uint64_t used() const { return used_; }  // never above budget()
  size_t size() const { return entries_.size(); }
  bool contains(uint32_t key) const { return entries_.count(key) != 0; }

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
  std::vector<uint32_t> order() const { return {order_.begin(), order_.end()}; }

 private:
  struct Entry {
    std::list<uint32_t>::iterator pos;
    uint64_t bytes;
  };
  uint64_t budget_;
  uint64_t used_ = 0;
  std::list<uint32_t> order_;  // front: least recently used
  std::unordered_map<uint32_t, Entry> entries_;
};

}  // namespace dmmr
