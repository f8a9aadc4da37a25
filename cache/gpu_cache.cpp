#include "gpu_cache.h"

#include <algorithm>

#include "error.h"

namespace dmmr {

GpuCache::GpuCache(const Scene& scene, HostCache& host, MeshBackend& backend, uint64_t budget,
                   Eviction eviction)
    : host_(host), backend_(backend), meshes_(scene.manifest.geometries) {
  for (uint32_t t = 0; t < scene.manifest.textures; ++t) {
    TextureData tex = loadTexture(scene, t);
    texture_bytes_ += gpuBytes(tex);
    textures_.push_back(backend_.uploadTexture(tex));
  }
  if (budget != LruBudget::kUnlimited && texture_bytes_ > budget)
    throw Error("GPU budget of " + std::to_string(budget) + " bytes is smaller than the scene's " +
                std::to_string(texture_bytes_) + " bytes of textures, which stay resident");
  lru_ = LruBudget(budget == LruBudget::kUnlimited ? budget : budget - texture_bytes_, eviction);
}

GpuCache::~GpuCache() {
  releaseTransient();
  for (uint32_t g : lru_.order()) backend_.release(meshes_[g]);
  for (GLuint t : textures_) backend_.releaseTexture(t);
}

void GpuCache::releaseTransient() {
  if (!has_transient_) return;
  backend_.release(transient_);
  has_transient_ = false;
}

const GpuMesh* GpuCache::acquire(uint32_t geometry) {
  DMMR_CHECK(geometry < meshes_.size());
  releaseTransient();
  if (lru_.touch(geometry)) {
    ++stats_.hits;
    return &meshes_[geometry];
  }
  ++stats_.misses;
  std::optional<GeometryData> data = host_.get(geometry);
  if (!data) return nullptr;
  uint64_t bytes = gpuBytes(*data);
  if (!lru_.admits(bytes)) {
    ++stats_.uncached;
    transient_ = backend_.upload(*data);
    has_transient_ = true;
    return &transient_;
  }
  std::vector<uint32_t> evicted;
  lru_.insert(geometry, bytes, &evicted);
  for (uint32_t e : evicted) backend_.release(meshes_[e]);
  meshes_[geometry] = backend_.upload(*data);
  DMMR_CHECK(meshes_[geometry].bytes == bytes);
  return &meshes_[geometry];
}

GpuCacheStats GpuCache::stats() const {
  GpuCacheStats s = stats_;
  s.resident = lru_.used() + texture_bytes_;
  return s;
}

}  // namespace dmmr
