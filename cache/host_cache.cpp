#include "host_cache.h"

#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "atomic_file.h"
#include "error.h"
#include "guarded.h"

namespace dmmr {

// Called without the cache's lock, never twice at once for one key (the
// cache claims the key for each call), concurrently for different keys.
class HostCache::Store {
 public:
  virtual ~Store() = default;
  virtual void put(uint32_t key, const Bytes& bytes) = 0;
  virtual Bytes read(uint32_t key) = 0;  // null when it cannot
  virtual void erase(uint32_t key) = 0;
};

// One slot per geometry: calls for different keys touch different slots.
class HostCache::MemoryStore : public Store {
 public:
  explicit MemoryStore(size_t geometries) : slots_(geometries) {}
  void put(uint32_t key, const Bytes& bytes) override { slots_[key] = bytes; }
  Bytes read(uint32_t key) override { return slots_[key]; }
  void erase(uint32_t key) override { slots_[key].reset(); }

 private:
  std::vector<Bytes> slots_;
};

// One file per entry in a directory of its own, so runs sharing a RAM disk
// do not meet.
class HostCache::DirectoryStore : public Store {
 public:
  explicit DirectoryStore(const std::string& parent) {
    static std::atomic<int> counter{0};
    dir_ = parent + "/dmmr-cache-" + std::to_string(::getpid()) + "-" + std::to_string(counter++);
    std::error_code ec;
    std::filesystem::create_directories(dir_, ec);
    if (ec) throw Error(fileError(dir_, "cannot create the RAM cache directory: " + ec.message()));
  }
  ~DirectoryStore() override {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  void put(uint32_t key, const Bytes& bytes) override {
    // No fsync: the directory is scratch. A failed write (a full RAM disk)
    // leaves the entry unreadable and read() sends get() back to the scene.
    std::ofstream out(path(key), std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(bytes->data()), std::streamsize(bytes->size()));
    out.close();
    if (!out) erase(key);
  }
  Bytes read(uint32_t key) override {
    try {
      return std::make_shared<const std::vector<uint8_t>>(readFileBytes(path(key)));
    } catch (const std::exception&) {
      return nullptr;
    }
  }
  void erase(uint32_t key) override {
    std::error_code ec;
    std::filesystem::remove(path(key), ec);
  }

 private:
  std::string path(uint32_t key) const { return dir_ + "/" + std::to_string(key) + ".bin"; }
  std::string dir_;
};

HostCache::HostCache(const Scene& scene, HostCacheOptions options)
    : scene_(scene),
      lru_(options.budget, options.eviction),
      bad_(scene.manifest.geometries, 0),
      in_flight_(scene.manifest.geometries, 0),
      queued_(scene.manifest.geometries, 0),
      busy_(scene.manifest.geometries, 0),
      stale_(scene.manifest.geometries, 0) {
  file_bytes_.reserve(scene.manifest.geometries);
  for (uint32_t g = 0; g < scene.manifest.geometries; ++g)
    file_bytes_.push_back(geometryFileBytes(scene, g));
  if (options.dir.empty())
    store_ = std::make_unique<MemoryStore>(scene.manifest.geometries);
  else
    store_ = std::make_unique<DirectoryStore>(options.dir);
  // Prefetching is an optimisation: should anything escape the loader (an
  // allocation failing), gets still read for themselves; the thread must not
  // end in std::terminate, and drain() must not wait for it.
  loader_ = std::thread([this] {
    runGuarded([&] { loaderLoop(); },
               [&](const std::string& what) {
                 std::fprintf(stderr, "dmmr: warning: geometry prefetching stopped: %s\n",
                              what.c_str());
                 std::lock_guard<std::mutex> lock(mu_);
                 requests_.clear();
                 loader_busy_ = false;
                 stop_ = true;  // prefetch() still queues; nothing waits on the queue
                 changed_.notify_all();
               });
  });
}

HostCache::~HostCache() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_ = true;
  }
  changed_.notify_all();
  loader_.join();
}

std::optional<GeometryData> HostCache::get(uint32_t geometry) {
  DMMR_CHECK(geometry < bad_.size());
  std::unique_lock<std::mutex> lock(mu_);
  // Not while it is read from disk or its entry is written or erased.
  idle_.wait(lock, [&] { return !in_flight_[geometry] && !busy_[geometry]; });
  if (bad_[geometry]) return std::nullopt;
  Bytes bytes;
  if (lru_.touch(geometry)) {
    busy_[geometry] = 1;
    lock.unlock();
    bytes = store_->read(geometry);
    lock.lock();
    if (bytes && bytes->size() != file_bytes_[geometry]) bytes = nullptr;
    if (!bytes && lru_.contains(geometry)) {  // the RAM disk lost it: drop the entry
      ++stats_.lost;
      lru_.erase(geometry);
      stale_[geometry] = 1;
    }
    release(lock, geometry);
  }
  if (bytes) {
    ++stats_.hits;
  } else {
    ++stats_.misses;
    bytes = readDisk(lock, geometry);
    if (!bytes) return std::nullopt;
    admit(lock, geometry, bytes, /*urgent=*/true);
  }
  lock.unlock();
  try {
    return decodeGeometryFile(scene_, geometry, *bytes);
  } catch (const std::exception& e) {
    lock.lock();
    markBad(geometry, e.what());
    drop(lock, geometry);
    return std::nullopt;
  }
}

HostCache::Bytes HostCache::readDisk(std::unique_lock<std::mutex>& lock, uint32_t geometry) {
  in_flight_[geometry] = 1;
  lock.unlock();
  Bytes bytes;
  std::string problem;
  try {
    bytes = std::make_shared<const std::vector<uint8_t>>(readGeometryFile(scene_, geometry));
  } catch (const std::exception& e) {
    problem = e.what();
  }
  lock.lock();
  in_flight_[geometry] = 0;
  idle_.notify_all();
  if (!bytes) {
    markBad(geometry, problem);
    return nullptr;
  }
  stats_.disk_bytes += bytes->size();
  return bytes;
}

void HostCache::admit(std::unique_lock<std::mutex>& lock, uint32_t geometry, const Bytes& bytes,
                      bool urgent) {
  idle_.wait(lock, [&] { return !busy_[geometry]; });  // its stale entry is still going
  if (lru_.contains(geometry) || bad_[geometry]) return;
  if (!lru_.admits(bytes->size())) {
    ++stats_.uncached;
    return;
  }
  std::vector<uint32_t> evicted;
  if (urgent)
    lru_.insert(geometry, bytes->size(), &evicted);
  else if (!lru_.insertIfFree(geometry, bytes->size()))
    return;
  busy_[geometry] = 1;
  // Evicted entries being read or written go when that ends; this thread
  // erases the others.
  std::vector<uint32_t> erasing;
  for (uint32_t e : evicted) {
    if (busy_[e]) {
      stale_[e] = 1;
    } else {
      busy_[e] = 1;
      erasing.push_back(e);
    }
  }
  lock.unlock();
  for (uint32_t e : erasing) store_->erase(e);
  store_->put(geometry, bytes);
  lock.lock();
  for (uint32_t e : erasing) busy_[e] = 0;
  release(lock, geometry);
}

void HostCache::drop(std::unique_lock<std::mutex>& lock, uint32_t geometry) {
  if (!lru_.contains(geometry)) return;  // nothing stored, or a stale entry already going
  lru_.erase(geometry);
  stale_[geometry] = 1;
  if (busy_[geometry]) return;  // the holder erases it
  busy_[geometry] = 1;
  release(lock, geometry);
}

void HostCache::release(std::unique_lock<std::mutex>& lock, uint32_t geometry) {
  if (stale_[geometry]) {
    stale_[geometry] = 0;
    lock.unlock();
    store_->erase(geometry);
    lock.lock();
  }
  busy_[geometry] = 0;
  idle_.notify_all();
}

void HostCache::markBad(uint32_t geometry, const std::string& why) {
  if (bad_[geometry]) return;
  bad_[geometry] = 1;
  ++stats_.skipped;
  std::fprintf(stderr, "dmmr: warning: skipping geometry %u, whose objects are not drawn: %s\n",
               geometry, why.c_str());
}

void HostCache::prefetch(const std::vector<uint32_t>& geometries, bool urgent) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    for (uint32_t g : geometries) {
      DMMR_CHECK(g < queued_.size());
      if (queued_[g] || bad_[g]) continue;
      if (lru_.contains(g)) {
        if (urgent) lru_.touch(g);  // drawn soon: keep it
        continue;
      }
      queued_[g] = 1;
      requests_.push_back({g, urgent});
    }
  }
  changed_.notify_all();
}

void HostCache::nextFrame() {
  std::lock_guard<std::mutex> lock(mu_);
  lru_.nextFrame();
}

void HostCache::drain() {
  std::unique_lock<std::mutex> lock(mu_);
  changed_.wait(lock, [&] { return stop_ || (requests_.empty() && !loader_busy_); });
}

HostCacheStats HostCache::stats() const {
  std::lock_guard<std::mutex> lock(mu_);
  HostCacheStats s = stats_;
  s.resident = lru_.used();
  return s;
}

void HostCache::loaderLoop() {
  std::unique_lock<std::mutex> lock(mu_);
  for (;;) {
    changed_.wait(lock, [&] { return stop_ || !requests_.empty(); });
    if (stop_) return;
    auto [g, urgent] = requests_.front();
    requests_.pop_front();
    queued_[g] = 0;
    uint64_t size = file_bytes_[g];
    bool wanted = !bad_[g] && !in_flight_[g] && !lru_.contains(g) && lru_.admits(size) &&
                  (urgent || lru_.budget() - lru_.used() >= size);
    if (wanted) {
      loader_busy_ = true;
      Bytes bytes = readDisk(lock, g);
      if (bytes) {
        ++stats_.prefetched;
        admit(lock, g, bytes, urgent);
      }
      loader_busy_ = false;
    }
    if (requests_.empty()) changed_.notify_all();  // wakes drain()
  }
}

}  // namespace dmmr
