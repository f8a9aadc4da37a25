// The preprocessed scene directory that the server and clients read:
//
//   manifest.json   format version, counts, scene bounds, size and CRC per file
//   skeleton.bin    the scenegraph without geometry (pre-order nodes)
//   bounds.bin      per object: geometry id, world transform, bounds, weight
//   occluders.bin   objects marked as potential occluders
//   parts.bin       per geometry: part boxes, for tighter occlusion tests
//   geometry/NNNNNN.bin  one file per unique geometry (instances share one)
//   textures/NNNNNN.bin  one file per unique diffuse texture
//
// Every .bin file uses the checked container of bytes.h. Readers validate the
// cross-references they can see (indices in range, sizes consistent); the
// scene loader validates references between files.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "bytes.h"
#include "math.h"

namespace dmmr {

inline constexpr uint32_t kNone = 0xFFFFFFFFu;

// ---- bounds ---------------------------------------------------------------
struct ObjectBounds {
  uint32_t geometry = 0;  // index of the unique geometry it draws
  Mat4d transform;        // geometry-local to world, affine, double precision
  Sphere3d sphere;        // world bounding sphere
  Box3d box;              // world axis-aligned box
  bool use_box = true;    // the box encloses less volume than the sphere
  uint64_t weight = 0;    // rendering cost estimate: triangle count
  friend bool operator==(const ObjectBounds&, const ObjectBounds&) = default;
};

// ---- skeleton -------------------------------------------------------------
enum class NodeKind : uint8_t { Group = 0, Transform = 1, Object = 2 };
struct SkeletonNode {
  NodeKind kind = NodeKind::Group;
  uint32_t parent = kNone;  // kNone for the root; otherwise < this node's index
  uint32_t end = 0;         // one past the last node of this subtree (pre-order)
  uint32_t object = kNone;  // object index for Object nodes
  Box3d box;                // world bounds of the subtree (invalid if empty)
  std::string name;
  friend bool operator==(const SkeletonNode&, const SkeletonNode&) = default;
};

// ---- geometry -------------------------------------------------------------
// How a geometry file stores its vertices and indices (docs/scene-format.md).
// Every decoder returns the float GeometryData below.
enum class Encoding : uint8_t {
  Float32 = 0,           // floats and 16/32-bit indices as they are
  Quantized = 1,         // the Sensors 2022 quantization (lossy)
  Meshopt = 2,           // meshoptimizer's vertex and index codecs over Float32 (exact)
  QuantizedMeshopt = 3,  // the same codecs over Quantized
};
inline constexpr Encoding kEncodings[] = {Encoding::Float32, Encoding::Quantized, Encoding::Meshopt,
                                          Encoding::QuantizedMeshopt};
// "float32", "quantized", "meshopt", "quantized-meshopt": the manifest's and
// dmmr-preprocess --encoding's names.
const char* encodingName(Encoding e);
// False when `name` is none of them.
bool parseEncoding(const std::string& name, Encoding* out);
// Whether decoding gives back exactly what was encoded.
inline bool isLossless(Encoding e) {
  return e == Encoding::Float32 || e == Encoding::Meshopt;
}
struct SubMesh {
  uint32_t first_index = 0;  // into GeometryData::indices
  uint32_t index_count = 0;  // a multiple of 3 (triangle list)
  float diffuse[4] = {0.8f, 0.8f, 0.8f, 1.f};
  int32_t texture = -1;  // texture file index, or -1
  friend bool operator==(const SubMesh&, const SubMesh&) = default;
};
// Triangle lists in the geometry's local frame. Optional attributes are
// empty when the model has none: normals 3, colors 4 (RGBA8), texcoords 2
// values per vertex.
struct GeometryData {
  std::vector<float> positions;
  std::vector<float> normals;
  std::vector<uint8_t> colors;
  std::vector<float> texcoords;
  std::vector<uint32_t> indices;
  std::vector<SubMesh> submeshes;
  // Optional coarser triangle list over the same vertices (meshoptimizer's
  // simplifier), for drawing the geometry as an occluder; empty when none.
  std::vector<uint32_t> lod_indices;
  size_t vertexCount() const { return positions.size() / 3; }
  uint64_t triangleCount() const { return indices.size() / 3; }
  friend bool operator==(const GeometryData&, const GeometryData&) = default;
};

struct TextureData {
  uint32_t width = 0, height = 0;
  bool repeat_s = true, repeat_t = true;
  std::vector<uint8_t> rgba;  // width * height * 4, bottom row first (GL order)
  friend bool operator==(const TextureData&, const TextureData&) = default;
};

// ---- part boxes -----------------------------------------------------------
// Per geometry, up to kMaxParts boxes in its local frame that together hold
// every triangle whole (each the box of one group of triangles). An object
// whose box would show is culled when none of its parts can (client.cpp),
// which keeps the rectangle it is tested over to where its triangles are.
// Each part is stored in 8 bits per coordinate, in 255ths of the geometry's
// box, rounded outward: partBox never gives a box smaller than the part.
inline constexpr size_t kMaxParts = 8;
struct GeometryParts {
  Box3d box;  // the geometry's box, local frame; float values (stored as f32)
  // Per part: lo x, y, z, then hi x, y, z, each in 255ths of `box`'s extent
  // from box.lo (0 is box.lo, 255 box.hi exactly); lo <= hi on each axis.
  std::vector<std::array<uint8_t, 6>> parts;
  // Where the geometry file keeps each part's triangles (version 2): within
  // every submesh, part 0's triangles come first, then part 1's, and so on,
  // each in its original relative order; triangles[s * parts.size() + k] is
  // how many of submesh s's triangles are part k's. Empty when the triangles
  // are not grouped by part (version 1, or no parts): the geometry is then
  // only ever drawn whole. A client checks the counts against the geometry
  // file's submeshes before drawing part by part (partRanges, draw.h).
  std::vector<uint32_t> triangles;
  bool ordered() const { return !triangles.empty(); }
  friend bool operator==(const GeometryParts&, const GeometryParts&) = default;
};
// Part k of `g` (k < g.parts.size()), decoded: within g.box.
Box3d partBox(const GeometryParts& g, size_t k);
// `box` (every coordinate a float) and the parts (each within it, at most
// kMaxParts) quantised so that partBox(result, k) contains parts[k].
GeometryParts quantizeParts(const Box3d& box, const std::vector<Box3d>& parts);

// ---- manifest -------------------------------------------------------------
struct FileEntry {
  uint64_t bytes = 0;
  uint32_t crc = 0;
  friend bool operator==(const FileEntry&, const FileEntry&) = default;
};
struct Manifest {
  // 2: file CRCs are manifestCrc (bytes.h), which tells intact files apart.
  static constexpr uint32_t kVersion = 2;
  uint32_t version = kVersion;
  uint64_t objects = 0, geometries = 0, textures = 0, occluders = 0;
  uint64_t triangles = 0;         // over all objects (instances counted each)
  uint64_t unique_triangles = 0;  // over unique geometries
  uint64_t geometry_bytes = 0;    // sum of geometry and texture file sizes
  Box3d bounds;                   // world bounds of the whole scene
  Encoding encoding = Encoding::Float32;
  std::vector<std::string> inputs;
  std::map<std::string, FileEntry> files;  // relative path -> size and CRC
  friend bool operator==(const Manifest&, const Manifest&) = default;
};

std::string geometryFileName(uint32_t index);  // "geometry/000042.bin"
std::string textureFileName(uint32_t index);   // "textures/000007.bin"

// Encoders return complete files (container included); decoders take a whole
// file's bytes and the path to name in errors.
std::vector<uint8_t> encodeBounds(const std::vector<ObjectBounds>& objects);
std::vector<ObjectBounds> decodeBounds(const std::vector<uint8_t>& file, const std::string& path);
std::vector<uint8_t> encodeSkeleton(const std::vector<SkeletonNode>& nodes);
std::vector<SkeletonNode> decodeSkeleton(const std::vector<uint8_t>& file, const std::string& path);
std::vector<uint8_t> encodeOccluders(const std::vector<uint32_t>& objects);
std::vector<uint32_t> decodeOccluders(const std::vector<uint8_t>& file, const std::string& path);
// Any encoding's file decodes with decodeGeometry; the default writes the
// Float32 layout, byte for byte what dmmr has always written.
std::vector<uint8_t> encodeGeometry(const GeometryData& g, Encoding encoding = Encoding::Float32);
GeometryData decodeGeometry(const std::vector<uint8_t>& file, const std::string& path);
std::vector<uint8_t> encodeParts(const std::vector<GeometryParts>& geometries);
std::vector<GeometryParts> decodeParts(const std::vector<uint8_t>& file, const std::string& path);
std::vector<uint8_t> encodeTexture(const TextureData& t);
TextureData decodeTexture(const std::vector<uint8_t>& file, const std::string& path);
std::string encodeManifest(const Manifest& m);
Manifest decodeManifest(const std::string& text, const std::string& path);

}  // namespace dmmr
