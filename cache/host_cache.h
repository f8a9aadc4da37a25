// The host levels of the geometry cache (DMMR paper, section 3.8): geometry
// files held in RAM (or in a RAM-disk directory) under a byte budget, LRU,
// over the scene directory on disk; and a loader thread that brings
// geometry in ahead of the frame that draws it.
//
// The RAM level keeps files as they are on disk (compact encodings stay
// compact); decoding happens in get(), on the way to the GPU.
#pragma once

#include <condition_variable>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "formats.h"
#include "lru.h"
#include "scene.h"

namespace dmmr {

struct HostCacheOptions {
  uint64_t budget = LruBudget::kUnlimited;  // bytes of geometry files held
  // When set, entries are files in a fresh directory under this one (a RAM
  // disk such as /dev/shm, as in the paper) instead of process memory.
  std::string dir;
  Eviction eviction = Eviction::FrameLru;
};

struct HostCacheStats {
  uint64_t hits = 0;        // get() found the geometry in RAM
  uint64_t misses = 0;      // get() had to read it from disk
  uint64_t disk_bytes = 0;  // read from the scene directory, prefetches included
  uint64_t prefetched = 0;  // geometries the loader thread brought in
  uint64_t uncached = 0;    // larger than the whole budget: read, used, not kept
  uint64_t skipped = 0;     // unreadable or malformed files, never drawn
  uint64_t lost = 0;        // RAM-disk entries found missing or short (a failed write)
  uint64_t resident = 0;    // bytes held now (never above the budget)
  friend bool operator==(const HostCacheStats&, const HostCacheStats&) = default;
};

// Thread-safe: both GL stages of a client share one.
class HostCache {
 public:
  // Starts the loader thread. Throws Error naming the directory when
  // options.dir cannot be used.
  HostCache(const Scene& scene, HostCacheOptions options);
  ~HostCache();  // stops the loader; removes the RAM-disk directory
  HostCache(const HostCache&) = delete;
  HostCache& operator=(const HostCache&) = delete;

  // The decoded geometry, from RAM or else from disk (waiting for a prefetch
  // of it already under way). Empty when the file is unreadable or
  // malformed: that is warned about once on stderr, naming the file and the
  // problem, counted as skipped, and the file is never read again.
  std::optional<GeometryData> get(uint32_t geometry);

  // Asks the loader thread to bring these geometries into RAM. Urgent
  // requests (objects that passed a query: the next frame draws them) may
  // evict by LRU; the others (objects entering the region) only fill free
  // space. Returns at once.
  void prefetch(const std::vector<uint32_t>& geometries, bool urgent);

  // A new frame for the eviction policy (lru.h): the render stage calls it.
  void nextFrame();

  // Blocks until the loader has no request left (tests and benchmarks).
  void drain();

  HostCacheStats stats() const;

 private:
  using Bytes = std::shared_ptr<const std::vector<uint8_t>>;
  class Store;
  class MemoryStore;
  class DirectoryStore;

  // All with mu_ held (`lock`), which they release while reading or writing.
  // The file's bytes from disk, or null after marking it bad.
  Bytes readDisk(std::unique_lock<std::mutex>& lock, uint32_t geometry);
  // Keeps `bytes` as the entry of `geometry` (urgent: may evict).
  void admit(std::unique_lock<std::mutex>& lock, uint32_t geometry, const Bytes& bytes,
             bool urgent);
  // Removes the entry of `geometry`, if held.
  void drop(std::unique_lock<std::mutex>& lock, uint32_t geometry);
  // Ends this thread's claim on `geometry` (busy_), first erasing its stored
  // entry when that went stale meanwhile.
  void release(std::unique_lock<std::mutex>& lock, uint32_t geometry);
  void markBad(uint32_t geometry, const std::string& why);
  void loaderLoop();

  const Scene& scene_;
  std::unique_ptr<Store> store_;
  mutable std::mutex mu_;
  std::condition_variable changed_;  // requests queued or all served, stop
  // Disk reads (in_flight_) and claims (busy_) ended. Apart from changed_, so
  // that a claim's end, once per RAM hit, does not wake the loader.
  std::condition_variable idle_;
  LruBudget lru_;
  HostCacheStats stats_;                           // counters; stats() adds resident from lru_
  std::vector<uint8_t> bad_, in_flight_, queued_;  // per geometry
  // The store is read and written without mu_ (with --ram-dir these are file
  // reads and writes), one operation per geometry at a time: a thread claims
  // the geometry (busy_) for it, and others wait for the claim to end. An
  // entry evicted or dropped while claimed is marked stale_ and erased from
  // the store by the claim's holder, so no file goes while being read.
  std::vector<uint8_t> busy_, stale_;
  // Per geometry, from the manifest once: its lookup by file name costs 12 %
  // of a RAM hit (docs/benchmarks.md, "Issue 14: hot paths (A/B)").
  std::vector<uint64_t> file_bytes_;
  std::deque<std::pair<uint32_t, bool>> requests_;  // geometry, urgent
  bool loader_busy_ = false;
  bool stop_ = false;
  std::thread loader_;
};

}  // namespace dmmr
