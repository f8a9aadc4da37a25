// Where the renderers get GPU meshes from. This is the seam the multi-level
// cache takes over: today's provider loads a geometry on first use and keeps
// it for the rest of the run.
#pragma once

#include <vector>

#include "draw.h"
#include "scene.h"

namespace dmmr {

class MeshProvider {
 public:
  virtual ~MeshProvider() = default;
  // The mesh of `geometry`, loading it if needed. Throws Error naming the
  // geometry file when it cannot be read.
  virtual const GpuMesh& acquire(uint32_t geometry) = 0;
  // GL texture names by texture index, for Renderer::draw.
  virtual const std::vector<GLuint>& textures() const = 0;
};

class KeepAllMeshProvider : public MeshProvider {
 public:
  // Uploads the scene's textures now (they are few and small).
  KeepAllMeshProvider(const Scene& scene, Renderer& renderer);
  ~KeepAllMeshProvider() override;
  const GpuMesh& acquire(uint32_t geometry) override;
  const std::vector<GLuint>& textures() const override { return textures_; }
  uint64_t loads() const { return loads_; }

 private:
  const Scene& scene_;
  Renderer& renderer_;
  std::vector<GpuMesh> meshes_;
  std::vector<uint8_t> loaded_;
  std::vector<GLuint> textures_;
  uint64_t loads_ = 0;
};

}  // namespace dmmr
