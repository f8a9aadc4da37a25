#include "formats.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <nlohmann/json.hpp>

#include "geometry_codec.h"

namespace dmmr {

namespace {

constexpr FileKind kBoundsKind{"DMMRBNDS", 1, "bounds"};
constexpr FileKind kSkeletonKind{"DMMRSKEL", 1, "skeleton"};
constexpr FileKind kOccludersKind{"DMMROCCL", 1, "occluders"};
constexpr FileKind kGeometryKind{"DMMRGEOM", 1, "geometry"};
constexpr FileKind kTextureKind{"DMMRTEXR", 1, "texture"};
// Version 2 adds where each part's triangles are (GeometryParts::triangles);
// version 1 files still read, as parts that are not ordered.
constexpr FileKind kPartsKind{"DMMRPART", 2, "part boxes", 1};

enum GeometryFlags : uint8_t {
  kHasNormals = 1,
  kHasColors = 2,
  kHasTexcoords = 4,
  kIndex16 = 8,
  kHasLod = 16
};
constexpr uint32_t kMaxTextureSide = 16384;

void putVec(ByteWriter& w, Vec3d v) {
  w.f64(v.x);
  w.f64(v.y);
  w.f64(v.z);
}
Vec3d getVec(ByteReader& r, const char* field) {
  Vec3d v;
  v.x = r.f64(field);
  v.y = r.f64(field);
  v.z = r.f64(field);
  if (!isFinite(v)) r.fail(std::string(field) + " is not finite");
  return v;
}
void putBox(ByteWriter& w, const Box3d& b) {
  putVec(w, b.lo);
  putVec(w, b.hi);
}
Box3d getBox(ByteReader& r, const char* field) {
  Box3d b;
  b.lo = getVec(r, field);
  b.hi = getVec(r, field);
  if (!b.valid()) r.fail(std::string(field) + " has min greater than max");
  return b;
}

ByteReader payloadReader(const FileKind& kind, const std::vector<uint8_t>& file,
                         const std::string& path) {
  auto [p, n] = openContainer(kind, file, path);
  return ByteReader(p, n, path);
}

std::string at(const char* what, size_t i) {
  return std::string(what) + " " + std::to_string(i);
}

}  // namespace

std::string geometryFileName(uint32_t index) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "geometry/%06u.bin", index);
  return buf;
}
std::string textureFileName(uint32_t index) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "textures/%06u.bin", index);
  return buf;
}

// ---- bounds ---------------------------------------------------------------

std::vector<uint8_t> encodeBounds(const std::vector<ObjectBounds>& objects) {
  ByteWriter w;
  w.u32(uint32_t(objects.size()));
  for (const auto& o : objects) {
    w.u32(o.geometry);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) w.f64(o.transform.at(r, c));
    putVec(w, o.sphere.center);
    w.f64(o.sphere.radius);
    putBox(w, o.box);
    w.u8(o.use_box ? 1 : 0);
    w.u64(o.weight);
  }
  return wrapContainer(kBoundsKind, w.bytes());
}

std::vector<ObjectBounds> decodeBounds(const std::vector<uint8_t>& file, const std::string& path) {
  ByteReader r = payloadReader(kBoundsKind, file, path);
  uint32_t n = r.u32("object count");
  constexpr size_t kRecord = 4 + 12 * 8 + 4 * 8 + 6 * 8 + 1 + 8;
  if (n > r.remaining() / kRecord) r.fail("truncated: object count exceeds the file");
  std::vector<ObjectBounds> out(n);
  for (uint32_t i = 0; i < n; ++i) {
    ObjectBounds& o = out[i];
    o.geometry = r.u32("geometry index");
    o.transform = Mat4d::identity();
    for (int row = 0; row < 3; ++row)
      for (int c = 0; c < 4; ++c) {
        o.transform.at(row, c) = r.f64("transform");
        if (!std::isfinite(o.transform.at(row, c)))
          r.fail(at("object", i) + ": transform not finite");
      }
    o.sphere.center = getVec(r, "sphere centre");
    o.sphere.radius = r.f64("sphere radius");
    if (!(o.sphere.radius >= 0) || !std::isfinite(o.sphere.radius))
      r.fail(at("object", i) + ": bad sphere radius");
    o.box = getBox(r, "box");
    uint8_t ub = r.u8("volume kind");
    if (ub > 1) r.fail(at("object", i) + ": volume kind must be 0 or 1");
    o.use_box = ub == 1;
    o.weight = r.u64("weight");
  }
  r.finish();
  return out;
}

// ---- part boxes -----------------------------------------------------------

namespace {
// Coordinate `q` (0..255) of axis `a` of g.box: the ends exactly, and
// clamped to the box between them (lo + extent * q / 255 may round past hi).
double partCoordinate(const Box3d& box, int a, uint8_t q) {
  if (q == 0) return box.lo[a];
  if (q == 255) return box.hi[a];
  return std::min(box.hi[a], box.lo[a] + (box.hi[a] - box.lo[a]) * (q / 255.0));
}
}  // namespace

Box3d partBox(const GeometryParts& g, size_t k) {
  const auto& q = g.parts[k];
  Box3d b;
  for (int a = 0; a < 3; ++a) {
    b.lo[a] = partCoordinate(g.box, a, q[size_t(a)]);
    b.hi[a] = partCoordinate(g.box, a, q[size_t(a) + 3]);
  }
  return b;
}

GeometryParts quantizeParts(const Box3d& box, const std::vector<Box3d>& parts) {
  DMMR_CHECK(box.valid() && parts.size() <= kMaxParts);
  GeometryParts g;
  g.box = box;
  for (const Box3d& p : parts) {
    std::array<uint8_t, 6> q{};
    for (int a = 0; a < 3; ++a) {
      DMMR_CHECK(box.lo[a] <= p.lo[a] && p.lo[a] <= p.hi[a] && p.hi[a] <= box.hi[a]);
      double ext = box.hi[a] - box.lo[a];
      auto at = [&](double v) { return ext > 0 ? (v - box.lo[a]) / ext * 255 : 0.0; };
      int lo = std::clamp(int(std::floor(at(p.lo[a]))), 0, 255);
      int hi = std::clamp(int(std::ceil(at(p.hi[a]))), lo, 255);
      // Outward until the decoded value holds the part (rounding).
      while (lo > 0 && partCoordinate(box, a, uint8_t(lo)) > p.lo[a]) --lo;
      while (hi < 255 && partCoordinate(box, a, uint8_t(hi)) < p.hi[a]) ++hi;
      q[size_t(a)] = uint8_t(lo);
      q[size_t(a) + 3] = uint8_t(hi);
    }
    g.parts.push_back(q);
  }
  return g;
}

std::vector<uint8_t> encodeParts(const std::vector<GeometryParts>& geometries) {
  ByteWriter w;
  w.u32(uint32_t(geometries.size()));
  for (const auto& g : geometries) {
    for (double v : {g.box.lo.x, g.box.lo.y, g.box.lo.z, g.box.hi.x, g.box.hi.y, g.box.hi.z})
      w.f32(float(v));
    w.u8(uint8_t(g.parts.size()));
    for (const auto& q : g.parts)
      for (uint8_t c : q) w.u8(c);
    if (g.parts.empty()) continue;
    DMMR_CHECK(g.triangles.size() % g.parts.size() == 0 &&
               g.triangles.size() / g.parts.size() <= UINT16_MAX);
    w.u16(uint16_t(g.triangles.size() / g.parts.size()));
    for (uint32_t t : g.triangles) w.u32(t);
  }
  return wrapContainer(kPartsKind, w.bytes());
}

std::vector<GeometryParts> decodeParts(const std::vector<uint8_t>& file, const std::string& path) {
  uint32_t version = 0;
  auto [payload, size] = openContainer(kPartsKind, file, path, &version);
  ByteReader r(payload, size, path);
  uint32_t n = r.u32("geometry count");
  constexpr size_t kRecord = 6 * 4 + 1;  // the least a geometry takes
  if (n > r.remaining() / kRecord) r.fail("truncated: geometry count exceeds the file");
  std::vector<GeometryParts> out(n);
  for (uint32_t i = 0; i < n; ++i) {
    GeometryParts& g = out[i];
    float v[6];
    for (float& x : v) {
      x = r.f32("geometry box");
      if (!std::isfinite(x)) r.fail(at("geometry", i) + ": box not finite");
    }
    g.box.lo = Vec3d{v[0], v[1], v[2]};
    g.box.hi = Vec3d{v[3], v[4], v[5]};
    if (!g.box.valid()) r.fail(at("geometry", i) + ": box has min greater than max");
    uint8_t count = r.u8("part count");
    if (count > kMaxParts)
      r.fail(at("geometry", i) + ": " + std::to_string(count) + " parts, at most " +
             std::to_string(kMaxParts));
    g.parts.resize(count);
    for (auto& q : g.parts) {
      for (uint8_t& c : q) c = r.u8("part");
      for (size_t a = 0; a < 3; ++a)
        if (q[a] > q[a + 3]) r.fail(at("geometry", i) + ": a part has min greater than max");
    }
    if (version < 2 || count == 0) continue;
    size_t submeshes = r.u16("submesh count");
    if (submeshes * count > r.remaining() / 4)
      r.fail("truncated: " + at("geometry", i) + "'s part triangles exceed the file");
    g.triangles.resize(submeshes * count);
    for (uint32_t& t : g.triangles) t = r.u32("part triangles");
  }
  r.finish();
  return out;
}

// ---- skeleton -------------------------------------------------------------

std::vector<uint8_t> encodeSkeleton(const std::vector<SkeletonNode>& nodes) {
  ByteWriter w;
  w.u32(uint32_t(nodes.size()));
  for (const auto& n : nodes) {
    w.u8(uint8_t(n.kind));
    w.u32(n.parent);
    w.u32(n.end);
    w.u32(n.object);
    w.u8(n.box.valid() ? 1 : 0);
    if (n.box.valid()) putBox(w, n.box);
    w.str(n.name);
  }
  return wrapContainer(kSkeletonKind, w.bytes());
}

std::vector<SkeletonNode> decodeSkeleton(const std::vector<uint8_t>& file,
                                         const std::string& path) {
  ByteReader r = payloadReader(kSkeletonKind, file, path);
  uint32_t n = r.u32("node count");
  if (n == 0) r.fail("skeleton has no nodes");
  if (n > r.remaining() / 18) r.fail("truncated: node count exceeds the file");
  std::vector<SkeletonNode> nodes(n);
  std::vector<uint32_t> open;  // the nodes whose subtrees enclose node i, outermost first
  for (uint32_t i = 0; i < n; ++i) {
    SkeletonNode& s = nodes[i];
    uint8_t kind = r.u8("node kind");
    if (kind > 2) r.fail(at("node", i) + ": unknown kind " + std::to_string(kind));
    s.kind = NodeKind(kind);
    s.parent = r.u32("parent");
    s.end = r.u32("subtree end");
    s.object = r.u32("object");
    uint8_t hasBox = r.u8("box flag");
    if (hasBox > 1) r.fail(at("node", i) + ": box flag must be 0 or 1");
    if (hasBox) s.box = getBox(r, "node box");
    s.name = r.str("name", 4096);
    // Structure: pre-order, parents before children, subtrees nested: the
    // parent is the innermost subtree still open at node i.
    while (!open.empty() && nodes[open.back()].end <= i) open.pop_back();
    if (i == 0 ? s.parent != kNone : (open.empty() || s.parent != open.back()))
      r.fail(at("node", i) + ": parent " + std::to_string(s.parent) + " is not an enclosing node");
    if (s.end <= i || s.end > n || (i > 0 && s.end > nodes[s.parent].end))
      r.fail(at("node", i) + ": subtree end " + std::to_string(s.end) + " out of range");
    if (i > 0 && nodes[s.parent].kind == NodeKind::Object)
      r.fail(at("node", i) + ": an object node cannot have children");
    if ((s.kind == NodeKind::Object) != (s.object != kNone))
      r.fail(at("node", i) + ": object index present exactly on object nodes");
    if (s.kind == NodeKind::Object && s.end != i + 1)
      r.fail(at("node", i) + ": object node with children");
    open.push_back(i);
  }
  if (nodes[0].end != n) r.fail("root does not span all nodes");
  r.finish();
  return nodes;
}

// ---- occluders ------------------------------------------------------------

std::vector<uint8_t> encodeOccluders(const std::vector<uint32_t>& objects) {
  ByteWriter w;
  w.u32(uint32_t(objects.size()));
  w.array(objects.data(), objects.size());
  return wrapContainer(kOccludersKind, w.bytes());
}

std::vector<uint32_t> decodeOccluders(const std::vector<uint8_t>& file, const std::string& path) {
  ByteReader r = payloadReader(kOccludersKind, file, path);
  std::vector<uint32_t> out;
  r.array(&out, r.u32("occluder count"), "occluder indices");
  for (size_t i = 1; i < out.size(); ++i)
    if (out[i] <= out[i - 1])
      r.fail("occluder indices are not strictly increasing at entry " + std::to_string(i));
  r.finish();
  return out;
}

// ---- geometry -------------------------------------------------------------
//
// Every encoding: encoding u8 | flags u8 | vertex count u32 | index count u32
// | submesh count u32 | submeshes, then the encoding's body (see
// docs/scene-format.md). Flags say which attributes are present; kIndex16
// applies to the layouts that store indices as they are.

namespace {

bool isMeshopt(Encoding e) {
  return e == Encoding::Meshopt || e == Encoding::QuantizedMeshopt;
}
bool isQuantized(Encoding e) {
  return e == Encoding::Quantized || e == Encoding::QuantizedMeshopt;
}

// Texture coordinates in the quantized layouts: 16-bit fixed point after
// per-geometry integer offsets, or floats where that cannot hold them.
enum TexcoordMode : uint8_t { kTexcoordFixed = 0, kTexcoordFloat = 1 };

// Little-endian stores into vertex records (meshopt streams).
void storeLE(uint8_t* p, uint32_t v, int n) {
  for (int i = 0; i < n; ++i) p[i] = uint8_t(v >> (8 * i));
}
uint32_t loadLE(const uint8_t* p, int n) {
  uint32_t v = 0;
  for (int i = 0; i < n; ++i) v |= uint32_t(p[i]) << (8 * i);
  return v;
}

void putIndices(ByteWriter& w, const std::vector<uint32_t>& idx, bool idx16) {
  if (idx16) {
    std::vector<uint16_t> small(idx.begin(), idx.end());
    w.array(small.data(), small.size());
  } else {
    w.array(idx.data(), idx.size());
  }
}

void getIndices(ByteReader& r, std::vector<uint32_t>* out, uint64_t n, bool idx16, uint32_t nv,
                const char* field) {
  if (idx16) {
    std::vector<uint16_t> small;
    r.array(&small, n, field);
    out->assign(small.begin(), small.end());
  } else {
    r.array(out, n, field);
  }
  for (uint32_t idx : *out)
    if (idx >= nv)
      r.fail(std::string(field) + ": index " + std::to_string(idx) + " out of range (" +
             std::to_string(nv) + " vertices)");
}

// meshopt-coded triangles: stream size u32 | stream | rotations.
void putTriangles(ByteWriter& w, const std::vector<uint32_t>& idx, size_t nv) {
  std::vector<uint8_t> stream, rotations;
  codec::encodeTriangles(idx.data(), idx.size(), nv, &stream, &rotations);
  w.u32(uint32_t(stream.size()));
  w.array(stream.data(), stream.size());
  w.array(rotations.data(), rotations.size());
}

void getTriangles(ByteReader& r, std::vector<uint32_t>* out, uint32_t n, uint32_t nv,
                  const char* field) {
  std::string f(field);
  uint32_t size = r.u32((f + " stream size").c_str());
  const uint8_t* stream = r.bytes(size, (f + " stream").c_str());
  if (n > codec::maxTriangleIndices(size))
    r.fail(f + ": stream of " + std::to_string(size) + " bytes cannot hold " + std::to_string(n) +
           " indices");
  const uint8_t* rotations = r.bytes(codec::rotationBytes(n), (f + " rotations").c_str());
  out->resize(n);
  std::string e = codec::decodeTriangles(stream, size, rotations, n, nv, out->data());
  if (!e.empty()) r.fail(f + ": " + e);
}

void putGrid(ByteWriter& w, const codec::PositionGrid& g) {
  putVec(w, g.origin);
  w.f64(g.cell);
  w.u32(uint32_t(g.cellCount()));
  w.array(g.cells.data(), g.cells.size());
}

codec::PositionGrid getGrid(ByteReader& r) {
  codec::PositionGrid g;
  for (int a = 0; a < 3; ++a) g.origin[a] = r.f64("position origin");
  g.cell = r.f64("position cell size");
  uint32_t n = r.u32("position cell count");
  if (n > codec::kMaxCells) r.fail("position cell count " + std::to_string(n) + " exceeds 65536");
  r.array(&g.cells, uint64_t(n) * 3, "position cell table");
  std::string e = codec::checkPositionGrid(g);
  if (!e.empty()) r.fail(e);
  return g;
}

// The quantized attributes of one geometry, structure of arrays.
struct QuantizedVertices {
  codec::PositionGrid grid;
  std::vector<uint16_t> cell;
  std::vector<uint32_t> offsets;
  std::vector<uint16_t> normals;
  uint8_t texcoord_mode = kTexcoordFixed;
  int32_t texcoord_offsets[2] = {0, 0};
  std::vector<uint16_t> texcoords;  // fixed mode
};

QuantizedVertices quantize(const GeometryData& g) {
  size_t nv = g.vertexCount();
  QuantizedVertices q;
  q.grid = codec::choosePositionGrid(g.positions.data(), nv, codec::cellBudget(nv));
  q.cell.resize(nv);
  q.offsets.resize(nv);
  codec::quantizePositions(g.positions.data(), nv, q.grid, q.cell.data(), q.offsets.data());
  if (!g.normals.empty()) {
    q.normals.resize(nv);
    codec::encodeNormals(g.normals.data(), nv, q.normals.data());
  }
  if (!g.texcoords.empty()) {
    if (codec::chooseTexcoordOffsets(g.texcoords.data(), nv, q.texcoord_offsets)) {
      q.texcoords.resize(2 * nv);
      codec::quantizeTexcoords(g.texcoords.data(), nv, q.texcoord_offsets, q.texcoords.data());
    } else {
      q.texcoord_mode = kTexcoordFloat;
    }
  }
  return q;
}

void putTexcoordHeader(ByteWriter& w, const QuantizedVertices& q) {
  w.u8(q.texcoord_mode);
  if (q.texcoord_mode == kTexcoordFixed) {
    w.i32(q.texcoord_offsets[0]);
    w.i32(q.texcoord_offsets[1]);
  }
}

void getTexcoordHeader(ByteReader& r, QuantizedVertices* q) {
  q->texcoord_mode = r.u8("texcoord mode");
  if (q->texcoord_mode > kTexcoordFloat)
    r.fail("unknown texcoord mode " + std::to_string(q->texcoord_mode));
  if (q->texcoord_mode == kTexcoordFixed) {
    q->texcoord_offsets[0] = r.i32("texcoord offset");
    q->texcoord_offsets[1] = r.i32("texcoord offset");
  }
}

// Decodes the quantized arrays of *q into *g (positions, normals and fixed
// texture coordinates; colours and float texture coordinates are already there).
void dequantize(ByteReader& r, const QuantizedVertices& q, uint32_t nv, GeometryData* g) {
  g->positions.resize(size_t(nv) * 3);
  std::string e =
      codec::dequantizePositions(q.grid, q.cell.data(), q.offsets.data(), nv, g->positions.data());
  if (!e.empty()) r.fail(e);
  if (!q.normals.empty()) {
    g->normals.resize(size_t(nv) * 3);
    e = codec::decodeNormals(q.normals.data(), nv, g->normals.data());
    if (!e.empty()) r.fail(e);
  }
  if (!q.texcoords.empty()) {
    g->texcoords.resize(size_t(nv) * 2);
    e = codec::dequantizeTexcoords(q.texcoords.data(), nv, q.texcoord_offsets, g->texcoords.data());
    if (!e.empty()) r.fail(e);
  }
}

// Vertex records for the meshopt layouts. Float32: position, normal, RGBA8,
// texcoords as stored. Quantized: offsets u32 | cell u16 | normal code u16
// (0 without normals) | RGBA8 | texcoords (u16 x 2, or f32 x 2 in float mode).
struct RecordLayout {
  size_t stride = 0, normal = 0, color = 0, uv = 0;
};

RecordLayout recordLayout(Encoding e, uint8_t flags, uint8_t texcoord_mode) {
  RecordLayout l;
  bool quantized = isQuantized(e);
  l.stride = quantized ? 8 : 12;
  l.normal = quantized ? 6 : l.stride;
  if (!quantized && (flags & kHasNormals)) l.stride += 12;
  l.color = l.stride;
  if (flags & kHasColors) l.stride += 4;
  l.uv = l.stride;
  if (flags & kHasTexcoords) l.stride += quantized && texcoord_mode == kTexcoordFixed ? 4 : 8;
  return l;
}

std::vector<uint8_t> floatRecords(const GeometryData& g, const RecordLayout& l) {
  size_t nv = g.vertexCount();
  std::vector<uint8_t> rec(nv * l.stride, 0);
  auto putF = [](uint8_t* p, float f) { storeLE(p, std::bit_cast<uint32_t>(f), 4); };
  for (size_t v = 0; v < nv; ++v) {
    uint8_t* p = &rec[v * l.stride];
    for (int a = 0; a < 3; ++a) putF(p + 4 * a, g.positions[3 * v + size_t(a)]);
    if (!g.normals.empty())
      for (int a = 0; a < 3; ++a) putF(p + l.normal + 4 * size_t(a), g.normals[3 * v + size_t(a)]);
    if (!g.colors.empty()) std::memcpy(p + l.color, &g.colors[4 * v], 4);
    if (!g.texcoords.empty())
      for (int a = 0; a < 2; ++a) putF(p + l.uv + 4 * size_t(a), g.texcoords[2 * v + size_t(a)]);
  }
  return rec;
}

// `n` little-endian floats from p to out.
void loadFloats(const uint8_t* p, float* out, int n) {
  if constexpr (std::endian::native == std::endian::little)
    std::memcpy(out, p, 4 * size_t(n));  // a plain copy: this loop bounds decode speed
  else
    for (int i = 0; i < n; ++i) out[i] = std::bit_cast<float>(loadLE(p + 4 * i, 4));
}

void fromFloatRecords(const std::vector<uint8_t>& rec, const RecordLayout& l, uint8_t flags,
                      uint32_t nv, GeometryData* g) {
  g->positions.resize(size_t(nv) * 3);
  if (flags & kHasNormals) g->normals.resize(size_t(nv) * 3);
  if (flags & kHasColors) g->colors.resize(size_t(nv) * 4);
  if (flags & kHasTexcoords) g->texcoords.resize(size_t(nv) * 2);
  for (size_t v = 0; v < nv; ++v) {
    const uint8_t* p = &rec[v * l.stride];
    loadFloats(p, &g->positions[3 * v], 3);
    if (flags & kHasNormals) loadFloats(p + l.normal, &g->normals[3 * v], 3);
    if (flags & kHasColors) std::memcpy(&g->colors[4 * v], p + l.color, 4);
    if (flags & kHasTexcoords) loadFloats(p + l.uv, &g->texcoords[2 * v], 2);
  }
}

std::vector<uint8_t> quantizedRecords(const GeometryData& g, const QuantizedVertices& q,
                                      const RecordLayout& l) {
  size_t nv = g.vertexCount();
  std::vector<uint8_t> rec(nv * l.stride, 0);
  for (size_t v = 0; v < nv; ++v) {
    uint8_t* p = &rec[v * l.stride];
    storeLE(p, q.offsets[v], 4);
    storeLE(p + 4, q.cell[v], 2);
    if (!q.normals.empty()) storeLE(p + l.normal, q.normals[v], 2);
    if (!g.colors.empty()) std::memcpy(p + l.color, &g.colors[4 * v], 4);
    if (!g.texcoords.empty()) {
      for (int a = 0; a < 2; ++a) {
        if (q.texcoord_mode == kTexcoordFixed)
          storeLE(p + l.uv + 2 * size_t(a), q.texcoords[2 * v + size_t(a)], 2);
        else
          storeLE(p + l.uv + 4 * size_t(a), std::bit_cast<uint32_t>(g.texcoords[2 * v + size_t(a)]),
                  4);
      }
    }
  }
  return rec;
}

// Splits quantized records into *q's arrays and *g's colours and float
// texture coordinates.
void fromQuantizedRecords(ByteReader& r, const std::vector<uint8_t>& rec, const RecordLayout& l,
                          uint8_t flags, uint32_t nv, QuantizedVertices* q, GeometryData* g) {
  q->cell.resize(nv);
  q->offsets.resize(nv);
  if (flags & kHasNormals) q->normals.resize(nv);
  if (flags & kHasColors) g->colors.resize(size_t(nv) * 4);
  bool fixed = q->texcoord_mode == kTexcoordFixed;
  if (flags & kHasTexcoords)
    (fixed ? q->texcoords.resize(size_t(nv) * 2) : g->texcoords.resize(size_t(nv) * 2));
  for (size_t v = 0; v < nv; ++v) {
    const uint8_t* p = &rec[v * l.stride];
    q->offsets[v] = loadLE(p, 4);
    q->cell[v] = uint16_t(loadLE(p + 4, 2));
    uint16_t n = uint16_t(loadLE(p + l.normal, 2));
    if (flags & kHasNormals)
      q->normals[v] = n;
    else if (n != 0)
      r.fail("vertex stream: padding of vertex " + std::to_string(v) + " is not zero");
    if (flags & kHasColors) std::memcpy(&g->colors[4 * v], p + l.color, 4);
    if (flags & kHasTexcoords)
      for (int a = 0; a < 2; ++a) {
        if (fixed)
          q->texcoords[2 * v + size_t(a)] = uint16_t(loadLE(p + l.uv + 2 * size_t(a), 2));
        else
          g->texcoords[2 * v + size_t(a)] =
              std::bit_cast<float>(loadLE(p + l.uv + 4 * size_t(a), 4));
      }
  }
}

void putVertexStream(ByteWriter& w, const std::vector<uint8_t>& records, size_t nv, size_t stride) {
  std::vector<uint8_t> stream;
  codec::encodeVertexStream(records.data(), nv, stride, &stream);
  w.u32(uint32_t(stream.size()));
  w.array(stream.data(), stream.size());
}

std::vector<uint8_t> getVertexStream(ByteReader& r, uint32_t nv, size_t stride) {
  uint32_t size = r.u32("vertex stream size");
  const uint8_t* stream = r.bytes(size, "vertex stream");
  // Bounded before allocating: a hostile vertex count fails here.
  if (nv > codec::maxVertexRecords(size, stride))
    r.fail("vertex stream of " + std::to_string(size) + " bytes cannot hold " + std::to_string(nv) +
           " vertices");
  std::vector<uint8_t> rec(size_t(nv) * stride);
  std::string e = codec::decodeVertexStream(stream, size, nv, stride, rec.data());
  if (!e.empty()) r.fail(e);
  return rec;
}

}  // namespace

const char* encodingName(Encoding e) {
  switch (e) {
    case Encoding::Float32:
      return "float32";
    case Encoding::Quantized:
      return "quantized";
    case Encoding::Meshopt:
      return "meshopt";
    case Encoding::QuantizedMeshopt:
      return "quantized-meshopt";
  }
  return "?";
}

bool parseEncoding(const std::string& name, Encoding* out) {
  for (Encoding e : kEncodings)
    if (name == encodingName(e)) {
      *out = e;
      return true;
    }
  return false;
}

std::vector<uint8_t> encodeGeometry(const GeometryData& g, Encoding encoding) {
  size_t nv = g.vertexCount();
  DMMR_CHECK(g.positions.size() == nv * 3);
  DMMR_CHECK(g.normals.empty() || g.normals.size() == nv * 3);
  DMMR_CHECK(g.colors.empty() || g.colors.size() == nv * 4);
  DMMR_CHECK(g.texcoords.empty() || g.texcoords.size() == nv * 2);
  bool idx16 = nv <= 65536 && !isMeshopt(encoding);
  uint8_t flags = (g.normals.empty() ? 0 : kHasNormals) | (g.colors.empty() ? 0 : kHasColors) |
                  (g.texcoords.empty() ? 0 : kHasTexcoords) | (idx16 ? kIndex16 : 0) |
                  (g.lod_indices.empty() ? 0 : kHasLod);
  ByteWriter w;
  w.u8(uint8_t(encoding));
  w.u8(flags);
  w.u32(uint32_t(nv));
  w.u32(uint32_t(g.indices.size()));
  w.u32(uint32_t(g.submeshes.size()));
  for (const auto& s : g.submeshes) {
    w.u32(s.first_index);
    w.u32(s.index_count);
    w.array(s.diffuse, 4);
    w.i32(s.texture);
  }
  QuantizedVertices q;
  if (isQuantized(encoding)) {
    q = quantize(g);
    putGrid(w, q.grid);
    if (!g.texcoords.empty()) putTexcoordHeader(w, q);
  }
  switch (encoding) {
    case Encoding::Float32:
      w.array(g.positions.data(), g.positions.size());
      w.array(g.normals.data(), g.normals.size());
      w.array(g.colors.data(), g.colors.size());
      w.array(g.texcoords.data(), g.texcoords.size());
      break;
    case Encoding::Quantized:
      w.array(q.cell.data(), q.cell.size());
      w.array(q.offsets.data(), q.offsets.size());
      w.array(q.normals.data(), q.normals.size());
      w.array(g.colors.data(), g.colors.size());
      if (q.texcoord_mode == kTexcoordFixed)
        w.array(q.texcoords.data(), q.texcoords.size());
      else
        w.array(g.texcoords.data(), g.texcoords.size());
      break;
    case Encoding::Meshopt: {
      RecordLayout l = recordLayout(encoding, flags, 0);
      putVertexStream(w, floatRecords(g, l), nv, l.stride);
      break;
    }
    case Encoding::QuantizedMeshopt: {
      RecordLayout l = recordLayout(encoding, flags, q.texcoord_mode);
      putVertexStream(w, quantizedRecords(g, q, l), nv, l.stride);
      break;
    }
  }
  auto putTris = [&](const std::vector<uint32_t>& idx) {
    if (isMeshopt(encoding))
      putTriangles(w, idx, nv);
    else
      putIndices(w, idx, idx16);
  };
  putTris(g.indices);
  if (!g.lod_indices.empty()) {
    w.u32(uint32_t(g.lod_indices.size()));
    putTris(g.lod_indices);
  }
  return wrapContainer(kGeometryKind, w.bytes());
}

GeometryData decodeGeometry(const std::vector<uint8_t>& file, const std::string& path) {
  ByteReader r = payloadReader(kGeometryKind, file, path);
  uint8_t enc = r.u8("encoding");
  if (enc > uint8_t(Encoding::QuantizedMeshopt))
    r.fail("unknown geometry encoding " + std::to_string(enc));
  const Encoding encoding = Encoding(enc);
  uint8_t flags = r.u8("flags");
  uint8_t known = kHasNormals | kHasColors | kHasTexcoords | kHasLod;
  if (!isMeshopt(encoding)) known |= kIndex16;  // meshopt's index codec has no width
  if (flags & ~known)
    r.fail("unknown geometry flags for encoding " + std::string(encodingName(encoding)));
  uint32_t nv = r.u32("vertex count");
  uint32_t ni = r.u32("index count");
  uint32_t ns = r.u32("submesh count");
  if (ni % 3) r.fail("index count " + std::to_string(ni) + " is not a multiple of 3");
  if ((flags & kIndex16) && nv > 65536) r.fail("16-bit indices with more than 65536 vertices");
  if (ns > r.remaining() / 28) r.fail("truncated: submesh count exceeds the file");
  GeometryData g;
  g.submeshes.resize(ns);
  for (uint32_t i = 0; i < ns; ++i) {
    SubMesh& s = g.submeshes[i];
    s.first_index = r.u32("submesh first index");
    s.index_count = r.u32("submesh index count");
    for (float& d : s.diffuse) d = r.f32("diffuse");
    s.texture = r.i32("texture");
    if (s.first_index % 3 || s.index_count % 3 || s.first_index > ni ||
        s.index_count > ni - s.first_index)
      r.fail(at("submesh", i) + ": index range out of bounds");
    if (s.texture < -1) r.fail(at("submesh", i) + ": bad texture index");
    for (float d : s.diffuse)
      if (!std::isfinite(d)) r.fail(at("submesh", i) + ": diffuse colour not finite");
  }
  QuantizedVertices q;
  if (isQuantized(encoding)) {
    q.grid = getGrid(r);
    if (flags & kHasTexcoords) getTexcoordHeader(r, &q);
  }
  switch (encoding) {
    case Encoding::Float32:
      r.array(&g.positions, uint64_t(nv) * 3, "positions");
      for (float v : g.positions)
        if (!std::isfinite(v)) r.fail("positions contain a non-finite value");
      if (flags & kHasNormals) r.array(&g.normals, uint64_t(nv) * 3, "normals");
      if (flags & kHasColors) r.array(&g.colors, uint64_t(nv) * 4, "colors");
      if (flags & kHasTexcoords) r.array(&g.texcoords, uint64_t(nv) * 2, "texcoords");
      break;
    case Encoding::Quantized:
      r.array(&q.cell, nv, "position cell indices");
      r.array(&q.offsets, nv, "position offsets");
      if (flags & kHasNormals) r.array(&q.normals, nv, "normal indices");
      if (flags & kHasColors) r.array(&g.colors, uint64_t(nv) * 4, "colors");
      if (flags & kHasTexcoords) {
        if (q.texcoord_mode == kTexcoordFixed)
          r.array(&q.texcoords, uint64_t(nv) * 2, "texcoords");
        else
          r.array(&g.texcoords, uint64_t(nv) * 2, "texcoords");
      }
      dequantize(r, q, nv, &g);
      break;
    case Encoding::Meshopt: {
      RecordLayout l = recordLayout(encoding, flags, 0);
      std::vector<uint8_t> rec = getVertexStream(r, nv, l.stride);
      fromFloatRecords(rec, l, flags, nv, &g);
      for (float v : g.positions)
        if (!std::isfinite(v)) r.fail("positions contain a non-finite value");
      break;
    }
    case Encoding::QuantizedMeshopt: {
      RecordLayout l = recordLayout(encoding, flags, q.texcoord_mode);
      std::vector<uint8_t> rec = getVertexStream(r, nv, l.stride);
      fromQuantizedRecords(r, rec, l, flags, nv, &q, &g);
      dequantize(r, q, nv, &g);
      break;
    }
  }
  auto getTris = [&](std::vector<uint32_t>* out, uint32_t n, const char* field) {
    if (isMeshopt(encoding))
      getTriangles(r, out, n, nv, field);
    else
      getIndices(r, out, n, flags & kIndex16, nv, field);
  };
  getTris(&g.indices, ni, "indices");
  if (flags & kHasLod) {
    uint32_t nl = r.u32("lod index count");
    if (nl == 0 || nl % 3)
      r.fail("lod index count " + std::to_string(nl) + " is not a positive multiple of 3");
    getTris(&g.lod_indices, nl, "lod indices");
  }
  r.finish();
  return g;
}

// ---- textures -------------------------------------------------------------

std::vector<uint8_t> encodeTexture(const TextureData& t) {
  DMMR_CHECK(t.rgba.size() == size_t(t.width) * t.height * 4);
  ByteWriter w;
  w.u32(t.width);
  w.u32(t.height);
  w.u8(t.repeat_s ? 1 : 0);
  w.u8(t.repeat_t ? 1 : 0);
  w.array(t.rgba.data(), t.rgba.size());
  return wrapContainer(kTextureKind, w.bytes());
}

TextureData decodeTexture(const std::vector<uint8_t>& file, const std::string& path) {
  ByteReader r = payloadReader(kTextureKind, file, path);
  TextureData t;
  t.width = r.u32("width");
  t.height = r.u32("height");
  if (t.width == 0 || t.height == 0 || t.width > kMaxTextureSide || t.height > kMaxTextureSide)
    r.fail("texture size " + std::to_string(t.width) + "x" + std::to_string(t.height) +
           " out of range");
  uint8_t rs = r.u8("repeat s"), rt = r.u8("repeat t");
  if (rs > 1 || rt > 1) r.fail("repeat flags must be 0 or 1");
  t.repeat_s = rs;
  t.repeat_t = rt;
  r.array(&t.rgba, uint64_t(t.width) * t.height * 4, "pixels");
  r.finish();
  return t;
}

// ---- manifest -------------------------------------------------------------

namespace {
using nlohmann::json;

json vecJson(Vec3d v) {
  return json::array({v.x, v.y, v.z});
}

struct JsonReader {
  const std::string& path;
  [[noreturn]] void fail(const std::string& what) const { throw Error(fileError(path, what)); }
  const json& field(const json& obj, const char* key) const {
    if (!obj.is_object()) fail(std::string("expected an object holding '") + key + "'");
    auto it = obj.find(key);
    if (it == obj.end()) fail(std::string("missing field '") + key + "'");
    return *it;
  }
  uint64_t u64(const json& obj, const char* key) const {
    const json& v = field(obj, key);
    if (!v.is_number_unsigned())
      fail(std::string("field '") + key + "' must be an unsigned integer");
    return v.get<uint64_t>();
  }
  std::string str(const json& obj, const char* key) const {
    const json& v = field(obj, key);
    if (!v.is_string()) fail(std::string("field '") + key + "' must be a string");
    return v.get<std::string>();
  }
  Vec3d vec(const json& obj, const char* key) const {
    const json& v = field(obj, key);
    if (!v.is_array() || v.size() != 3) fail(std::string("field '") + key + "' must be [x, y, z]");
    Vec3d r;
    for (int i = 0; i < 3; ++i) {
      if (!v[i].is_number()) fail(std::string("field '") + key + "' must hold numbers");
      r[i] = v[i].get<double>();
    }
    return r;
  }
};
}  // namespace

std::string encodeManifest(const Manifest& m) {
  json j;
  j["format"] = "dmmr-scene";
  j["version"] = m.version;
  j["counts"] = {{"objects", m.objects},
                 {"geometries", m.geometries},
                 {"textures", m.textures},
                 {"occluders", m.occluders},
                 {"triangles", m.triangles},
                 {"unique_triangles", m.unique_triangles},
                 {"geometry_bytes", m.geometry_bytes}};
  j["bounds"] = {{"min", m.bounds.valid() ? vecJson(m.bounds.lo) : vecJson({0, 0, 0})},
                 {"max", m.bounds.valid() ? vecJson(m.bounds.hi) : vecJson({0, 0, 0})}};
  j["encoding"] = encodingName(m.encoding);
  j["inputs"] = m.inputs;
  json files = json::object();
  for (const auto& [name, e] : m.files) files[name] = {{"bytes", e.bytes}, {"crc32", e.crc}};
  j["files"] = files;
  return j.dump(1) + "\n";
}

Manifest decodeManifest(const std::string& text, const std::string& path) {
  JsonReader R{path};
  json j = json::parse(text, nullptr, false);
  if (j.is_discarded()) R.fail("manifest is not valid JSON");
  if (R.str(j, "format") != "dmmr-scene") R.fail("not a dmmr scene manifest");
  Manifest m;
  uint64_t version = R.u64(j, "version");  // compared before narrowing: 2^32 + 1 is not 1
  if (version != Manifest::kVersion)
    R.fail("unsupported manifest version " + std::to_string(version) +
           " (this build reads version " + std::to_string(Manifest::kVersion) + ")");
  m.version = uint32_t(version);
  const json& c = R.field(j, "counts");
  m.objects = R.u64(c, "objects");
  m.geometries = R.u64(c, "geometries");
  m.textures = R.u64(c, "textures");
  m.occluders = R.u64(c, "occluders");
  m.triangles = R.u64(c, "triangles");
  m.unique_triangles = R.u64(c, "unique_triangles");
  m.geometry_bytes = R.u64(c, "geometry_bytes");
  const json& b = R.field(j, "bounds");
  m.bounds.lo = R.vec(b, "min");
  m.bounds.hi = R.vec(b, "max");
  if (!isFinite(m.bounds.lo) || !isFinite(m.bounds.hi) || !m.bounds.valid())
    R.fail("scene bounds are invalid");
  std::string encoding = R.str(j, "encoding");
  if (!parseEncoding(encoding, &m.encoding)) R.fail("unknown geometry encoding '" + encoding + "'");
  const json& in = R.field(j, "inputs");
  if (!in.is_array()) R.fail("field 'inputs' must be an array");
  for (const auto& s : in) {
    if (!s.is_string()) R.fail("field 'inputs' must hold strings");
    m.inputs.push_back(s.get<std::string>());
  }
  const json& files = R.field(j, "files");
  if (!files.is_object()) R.fail("field 'files' must be an object");
  for (const auto& [name, e] : files.items()) {
    if (name.empty() || name[0] == '/' || name.find("..") != std::string::npos)
      R.fail("file name '" + name + "' is not a plain relative path");
    uint64_t crc = R.u64(e, "crc32");
    if (crc > 0xFFFFFFFFu) R.fail("crc32 of '" + name + "' out of range");
    m.files[name] = {R.u64(e, "bytes"), uint32_t(crc)};
  }
  if (m.geometries > m.files.size() || m.objects > 0xFFFFFFF0u || m.geometries > 0xFFFFFFF0u)
    R.fail("counts disagree with the file list");
  return m;
}

}  // namespace dmmr
