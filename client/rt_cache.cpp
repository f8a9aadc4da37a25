#include "rt_cache.h"

#include "error.h"

namespace dmmr {

RtCache::RtCache(const Scene& scene, HostCache& host, Build build, uint64_t budget,
                 Eviction eviction)
    : host_(host), build_(std::move(build)), meshes_(scene.manifest.geometries) {
  for (uint32_t t = 0; t < scene.manifest.textures; ++t) {
    textures_.push_back(loadTexture(scene, t));
    texture_bytes_ += textures_.back().rgba.size();
  }
  for (const TextureData& t : textures_) texture_ptrs_.push_back(&t);
  if (budget != LruBudget::kUnlimited && texture_bytes_ > budget)
    throw Error("--gpu-budget of " + std::to_string(budget) +
                " bytes is smaller than the scene's " + std::to_string(texture_bytes_) +
                " bytes of textures, which stay resident");
  lru_ = LruBudget(budget == LruBudget::kUnlimited ? budget : budget - texture_bytes_, eviction);
}

std::shared_ptr<const RtMesh> RtCache::acquire(uint32_t geometry) {
  DMMR_CHECK(geometry < meshes_.size());
  if (lru_.touch(geometry)) {
    ++stats_.hits;
    return meshes_[geometry];
  }
  ++stats_.misses;
  std::optional<GeometryData> data = host_.get(geometry);
  if (!data) return nullptr;
  std::shared_ptr<const RtMesh> mesh = build_(*data);
  stats_.built_bytes += mesh->bytes();
  if (!lru_.admits(mesh->bytes())) {
    ++stats_.uncached;
    return mesh;  // freed when the frame lets go of it
  }
  std::vector<uint32_t> evicted;
  lru_.insert(geometry, mesh->bytes(), &evicted);
  for (uint32_t e : evicted) meshes_[e].reset();  // frames holding it keep it alive
  meshes_[geometry] = mesh;
  return mesh;
}

RtCacheStats RtCache::stats() const {
  RtCacheStats s = stats_;
  s.resident = lru_.used() + texture_bytes_;
  return s;
}

}  // namespace dmmr
