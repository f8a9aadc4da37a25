#include "scene.h"

#include <filesystem>

#include "atomic_file.h"
#include "error.h"

namespace dmmr {

namespace {

// Reads `name` from the scene and checks it against the manifest entry.
std::vector<uint8_t> readChecked(const Scene& s, const std::string& name) {
  std::string path = s.dir + "/" + name;
  auto it = s.manifest.files.find(name);
  if (it == s.manifest.files.end())
    throw Error(fileError(s.dir + "/manifest.json", "does not list " + name));
  std::vector<uint8_t> bytes = readFileBytes(path);
  if (bytes.size() != it->second.bytes)
    throw Error(fileError(path, "size " + std::to_string(bytes.size()) +
                                    " differs from the manifest's " +
                                    std::to_string(it->second.bytes)));
  if (manifestCrc(bytes) != it->second.crc)
    throw Error(fileError(path, "checksum differs from the manifest's (file is corrupt)"));
  return bytes;
}

void validateReferences(const Scene& s) {
  const std::string b = s.dir + "/bounds.bin";
  if (s.objects.size() != s.manifest.objects)
    throw Error(fileError(b, "holds " + std::to_string(s.objects.size()) +
                                 " objects, the manifest says " +
                                 std::to_string(s.manifest.objects)));
  for (size_t i = 0; i < s.objects.size(); ++i)
    if (s.objects[i].geometry >= s.manifest.geometries)
      throw Error(fileError(b, "object " + std::to_string(i) + " names geometry " +
                                   std::to_string(s.objects[i].geometry) + " of " +
                                   std::to_string(s.manifest.geometries)));
  const std::string o = s.dir + "/occluders.bin";
  if (s.occluders.size() != s.manifest.occluders)
    throw Error(fileError(o, "count differs from the manifest's"));
  if (!s.occluders.empty() && s.occluders.back() >= s.objects.size())
    throw Error(fileError(
        o, "names object " + std::to_string(s.occluders.back()) + " beyond the object count"));
  if (!s.parts.empty() && s.parts.size() != s.manifest.geometries)
    throw Error(fileError(s.dir + "/parts.bin", "holds " + std::to_string(s.parts.size()) +
                                                    " geometries, the manifest says " +
                                                    std::to_string(s.manifest.geometries)));
  if (s.skeleton.empty()) return;  // not loaded
  const std::string k = s.dir + "/skeleton.bin";
  std::vector<uint8_t> seen(s.objects.size(), 0);
  for (const auto& n : s.skeleton) {
    if (n.kind != NodeKind::Object) continue;
    if (n.object >= s.objects.size() || seen[n.object]++)
      throw Error(
          fileError(k, "object node " + std::to_string(n.object) + " is out of range or repeated"));
  }
  for (size_t i = 0; i < seen.size(); ++i)
    if (!seen[i]) throw Error(fileError(k, "object " + std::to_string(i) + " has no node"));
}

}  // namespace

Scene loadScene(const std::string& dir, bool with_skeleton, bool with_parts) {
  Scene s;
  s.dir = dir;
  const std::string mpath = dir + "/manifest.json";
  if (!std::filesystem::is_directory(dir)) throw Error(fileError(dir, "is not a scene directory"));
  std::vector<uint8_t> m = readFileBytes(mpath);
  s.manifest = decodeManifest(std::string(m.begin(), m.end()), mpath);
  if (with_skeleton)
    s.skeleton = decodeSkeleton(readChecked(s, "skeleton.bin"), dir + "/skeleton.bin");
  s.objects = decodeBounds(readChecked(s, "bounds.bin"), dir + "/bounds.bin");
  s.occluders = decodeOccluders(readChecked(s, "occluders.bin"), dir + "/occluders.bin");
  if (with_parts && s.manifest.files.count("parts.bin"))
    s.parts = decodeParts(readChecked(s, "parts.bin"), dir + "/parts.bin");
  validateReferences(s);
  return s;
}

std::vector<uint8_t> readGeometryFile(const Scene& scene, uint32_t index) {
  return readChecked(scene, geometryFileName(index));
}

GeometryData decodeGeometryFile(const Scene& scene, uint32_t index,
                                const std::vector<uint8_t>& bytes) {
  std::string path = scene.dir + "/" + geometryFileName(index);
  // The encoding byte opens the payload, after the 20-byte container header.
  constexpr size_t kEncodingAt = 20;
  if (bytes.size() > kEncodingAt && bytes[kEncodingAt] != uint8_t(scene.manifest.encoding) &&
      bytes[kEncodingAt] <= uint8_t(Encoding::QuantizedMeshopt))
    throw Error(fileError(
        path, std::string("encoding ") + encodingName(Encoding(bytes[kEncodingAt])) +
                  " differs from the manifest's " + encodingName(scene.manifest.encoding)));
  GeometryData g = decodeGeometry(bytes, path);
  for (const SubMesh& sm : g.submeshes)
    if (sm.texture >= 0 && uint64_t(sm.texture) >= scene.manifest.textures)
      throw Error(fileError(path, "names texture " + std::to_string(sm.texture) + " of " +
                                      std::to_string(scene.manifest.textures)));
  return g;
}

GeometryData loadGeometry(const Scene& scene, uint32_t index) {
  return decodeGeometryFile(scene, index, readGeometryFile(scene, index));
}

uint64_t geometryFileBytes(const Scene& scene, uint32_t index) {
  auto it = scene.manifest.files.find(geometryFileName(index));
  return it == scene.manifest.files.end() ? 0 : it->second.bytes;
}

TextureData loadTexture(const Scene& scene, uint32_t index) {
  std::string name = textureFileName(index);
  return decodeTexture(readChecked(scene, name), scene.dir + "/" + name);
}

double defaultNear(const Scene& scene) {
  double diag = length(scene.manifest.bounds.extent());
  return diag > 0 ? diag * 1e-5 : 1e-3;
}

}  // namespace dmmr
