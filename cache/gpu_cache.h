// The GPU level of the geometry cache: one per GL context, LRU under a byte
// budget over the host levels. The GL work sits behind MeshBackend, so the
// level's policy is tested without a context.
#pragma once

#include <vector>

#include "draw.h"
#include "host_cache.h"
#include "lru.h"

namespace dmmr {

// Uploads and releases GPU buffers. upload's GpuMesh::bytes must equal
// gpuBytes(g): the cache makes room for that much before uploading.
class MeshBackend {
 public:
  virtual ~MeshBackend() = default;
  virtual GpuMesh upload(const GeometryData& g) = 0;
  virtual void release(GpuMesh& mesh) = 0;
  virtual GLuint uploadTexture(const TextureData& t) = 0;
  virtual void releaseTexture(GLuint id) = 0;
};

// The backend of a real context.
class RendererBackend : public MeshBackend {
 public:
  explicit RendererBackend(Renderer& r) : r_(r) {}
  GpuMesh upload(const GeometryData& g) override { return r_.upload(g); }
  void release(GpuMesh& mesh) override { r_.release(mesh); }
  GLuint uploadTexture(const TextureData& t) override { return r_.uploadTexture(t); }
  void releaseTexture(GLuint id) override { r_.releaseTexture(id); }

 private:
  Renderer& r_;
};

struct GpuCacheStats {
  uint64_t hits = 0, misses = 0;
  uint64_t uncached = 0;  // larger than the budget: uploaded for one draw, then released
  uint64_t resident = 0;  // bytes held now, textures included (never above the budget)
  friend bool operator==(const GpuCacheStats&, const GpuCacheStats&) = default;
};

class GpuCache {
 public:
  // Uploads the scene's textures now (few and small): they stay resident and
  // count against `budget`; geometry gets what is left (possibly nothing,
  // in which case every mesh is drawn uncached).
  GpuCache(const Scene& scene, HostCache& host, MeshBackend& backend,
           uint64_t budget = LruBudget::kUnlimited, Eviction eviction = Eviction::FrameLru);
  ~GpuCache();
  GpuCache(const GpuCache&) = delete;
  GpuCache& operator=(const GpuCache&) = delete;

  // The mesh of `geometry`, loading it if needed. Valid until the next
  // acquire, which may evict it: draw it before asking for another (GL keeps
  // a released buffer alive for the draws already issued). Null when the
  // geometry's file is unreadable or malformed: its objects are skipped
  // (HostCacheStats::skipped counts them).
  const GpuMesh* acquire(uint32_t geometry);

  // A new frame for the eviction policy (lru.h): the stage calls it first.
  void nextFrame() { lru_.nextFrame(); }

  // GL texture names by texture index, for Renderer::draw.
  const std::vector<GLuint>& textures() const { return textures_; }

  GpuCacheStats stats() const;

 private:
  void releaseTransient();

  HostCache& host_;
  MeshBackend& backend_;
  LruBudget lru_;
  uint64_t texture_bytes_ = 0;
  std::vector<GpuMesh> meshes_;  // by geometry; resident when lru_ holds it
  GpuMesh transient_;            // an uncached mesh, released at the next acquire
  bool has_transient_ = false;
  std::vector<GLuint> textures_;
  GpuCacheStats stats_;
};

}  // namespace dmmr
