// The ray tracer's device level of the geometry cache: each geometry's BVH
// (RtMesh) under the --gpu-budget byte budget, LRU over the host levels
// (host_cache.h), as GpuCache is for the raster path. A BVH's size is known
// only once built, so a miss builds first and then makes room. A frame
// needs all its meshes at once (rays go anywhere), so acquire() hands out a
// shared pointer: a mesh evicted while its frame is still being gathered
// lives until that frame is drawn, and is then freed; the level itself
// never holds more than its budget. (The ray-tracing stage pins the meshes
// of its top level until that changes, docs/raytrace.md.)
#pragma once

#include <functional>
#include <memory>
#include <vector>

#include "host_cache.h"
#include "lru.h"
#include "raytrace.h"

namespace dmmr {

struct RtCacheStats {
  uint64_t hits = 0, misses = 0;
  uint64_t uncached = 0;     // larger than the budget: built for one frame, then freed
  uint64_t resident = 0;     // bytes held now, textures included (never above the budget)
  uint64_t built_bytes = 0;  // BVH and attribute bytes of every mesh built so far
  friend bool operator==(const RtCacheStats&, const RtCacheStats&) = default;
};

class RtCache {
 public:
  // Builds a geometry's mesh (RayTracer::build in a client; a fake in tests).
  using Build = std::function<std::unique_ptr<RtMesh>(const GeometryData&)>;

  // Loads the scene's textures now (few and small; they stay resident and
  // count against `budget`). Throws Error when they alone exceed it.
  RtCache(const Scene& scene, HostCache& host, Build build, uint64_t budget = LruBudget::kUnlimited,
          Eviction eviction = Eviction::FrameLru);

  // A new frame for the eviction policy: the stage calls it first.
  void nextFrame() { lru_.nextFrame(); }

  // The mesh of `geometry`, built if needed; null when its file is
  // unreadable or malformed (its objects are skipped, as the raster path
  // does). Keep the pointer until the frame is drawn.
  std::shared_ptr<const RtMesh> acquire(uint32_t geometry);

  // Whether the level holds `geometry`'s mesh now (no load, no recency).
  bool holds(uint32_t geometry) const {
    return geometry < meshes_.size() && meshes_[geometry] != nullptr;
  }

  // Texture files by index, for RayTracer::render.
  const std::vector<const TextureData*>& textures() const { return texture_ptrs_; }

  RtCacheStats stats() const;

 private:
  HostCache& host_;
  Build build_;
  LruBudget lru_;
  uint64_t texture_bytes_ = 0;
  std::vector<std::shared_ptr<const RtMesh>> meshes_;  // by geometry; held when lru_ holds it
  std::vector<TextureData> textures_;
  std::vector<const TextureData*> texture_ptrs_;
  RtCacheStats stats_;
};

}  // namespace dmmr
