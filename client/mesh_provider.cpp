#include "mesh_provider.h"

namespace dmmr {

KeepAllMeshProvider::KeepAllMeshProvider(const Scene& scene, Renderer& renderer)
    : scene_(scene),
      renderer_(renderer),
      meshes_(scene.manifest.geometries),
      loaded_(scene.manifest.geometries, 0) {
  for (uint32_t t = 0; t < scene.manifest.textures; ++t)
    textures_.push_back(renderer_.uploadTexture(loadTexture(scene_, t)));
}

KeepAllMeshProvider::~KeepAllMeshProvider() {
  for (size_t g = 0; g < meshes_.size(); ++g)
    if (loaded_[g]) renderer_.release(meshes_[g]);
  for (GLuint t : textures_) renderer_.releaseTexture(t);
}

const GpuMesh& KeepAllMeshProvider::acquire(uint32_t geometry) {
  if (!loaded_[geometry]) {
    meshes_[geometry] = renderer_.upload(loadGeometry(scene_, geometry));
    loaded_[geometry] = 1;
    ++loads_;
  }
  return meshes_[geometry];
}

}  // namespace dmmr
