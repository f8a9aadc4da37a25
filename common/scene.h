// Loading and validating a preprocessed scene directory (see formats.h).
#pragma once

#include <string>
#include <vector>

#include "formats.h"

namespace dmmr {

// What the server holds: everything but geometry. Clients add geometry on
// demand with loadGeometry.
struct Scene {
  std::string dir;
  Manifest manifest;
  std::vector<SkeletonNode> skeleton;
  std::vector<ObjectBounds> objects;
  std::vector<uint32_t> occluders;
  // Per geometry (loaded for the clients' culling only; empty when not
  // loaded, or for a scene preprocessed before part boxes).
  std::vector<GeometryParts> parts;
};

// Reads manifest, skeleton, bounds and occluders; checks each file's size and
// CRC against the manifest and the references between them (object and
// geometry indices in range, counts equal to the manifest's). Throws Error
// naming the file and the problem.
// Clients pass with_skeleton = false (they never traverse it) and
// with_parts = true (their occlusion tests use them); parts.bin is read when
// the manifest lists it.
Scene loadScene(const std::string& dir, bool with_skeleton = true, bool with_parts = false);

// Reads one geometry (or texture) file, checked against the manifest and the
// scene's texture count. Throws Error naming the file.
GeometryData loadGeometry(const Scene& scene, uint32_t index);
// loadGeometry in two steps, for the cache: the file's bytes checked against
// the manifest's size and CRC (what the host RAM level keeps), and their
// decoding. Both throw Error naming the file.
std::vector<uint8_t> readGeometryFile(const Scene& scene, uint32_t index);
GeometryData decodeGeometryFile(const Scene& scene, uint32_t index,
                                const std::vector<uint8_t>& bytes);
// The geometry file's size as the manifest lists it (0 when it does not).
uint64_t geometryFileBytes(const Scene& scene, uint32_t index);
TextureData loadTexture(const Scene& scene, uint32_t index);

// The near plane distance every renderer of a scene uses unless told
// otherwise: a small fraction of the scene's diagonal (reversed-Z float depth
// keeps precision out to infinity, so a small near costs nothing).
double defaultNear(const Scene& scene);

}  // namespace dmmr
