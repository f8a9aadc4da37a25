#include "geometry_codec.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <mutex>

#include <meshoptimizer.h>

#include "error.h"

namespace dmmr::codec {

namespace {

// ---- positions --------------------------------------------------------------

uint64_t cellKey(uint32_t i, uint32_t j, uint32_t k) {
  return uint64_t(i) << 32 | uint64_t(j) << 16 | k;
}

// The cell coordinate of `v` on one axis: floor((v - origin) / cell), the
// last cell taking the box's far face.
uint32_t cellCoord(double v, double origin, double cell, uint32_t n) {
  double c = std::floor((v - origin) / cell);
  return c <= 0 ? 0 : (c >= double(n - 1) ? n - 1 : uint32_t(c));
}

struct Box {
  Vec3d lo, hi;
};

Box boundsOf(const float* xyz, size_t count) {
  Box b{{xyz[0], xyz[1], xyz[2]}, {xyz[0], xyz[1], xyz[2]}};
  for (size_t v = 1; v < count; ++v)
    for (int a = 0; a < 3; ++a) {
      double x = xyz[3 * v + size_t(a)];
      b.lo[a] = std::min(b.lo[a], x);
      b.hi[a] = std::max(b.hi[a], x);
    }
  return b;
}

// The sorted, unique cell keys of all points with n subdivisions.
std::vector<uint64_t> occupiedCells(const float* xyz, size_t count, Vec3d origin, double cell,
                                    uint32_t n) {
  std::vector<uint64_t> keys(count);
  for (size_t v = 0; v < count; ++v) {
    const float* p = xyz + 3 * v;
    keys[v] = cellKey(cellCoord(p[0], origin.x, cell, n), cellCoord(p[1], origin.y, cell, n),
                      cellCoord(p[2], origin.z, cell, n));
  }
  std::sort(keys.begin(), keys.end());
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  return keys;
}

// ---- normals ----------------------------------------------------------------

Vec3d octDecode(int x, int y) {
  double u = x / 127.0, v = y / 127.0, z = 1 - std::fabs(u) - std::fabs(v);
  if (z < 0) {  // the lower hemisphere is folded into the square's corners
    double fu = (1 - std::fabs(v)) * (u >= 0 ? 1 : -1);
    double fv = (1 - std::fabs(u)) * (v >= 0 ? 1 : -1);
    u = fu;
    v = fv;
  }
  return normalize(Vec3d{u, v, z});
}

uint16_t octCode(int x, int y) {
  return uint16_t(uint8_t(int8_t(x)) | uint16_t(uint8_t(int8_t(y))) << 8);
}

// Every code's unit vector as floats (the zero vector for kZeroNormal and
// for codes not in the table), computed once in double.
const std::vector<float>& normalTable() {
  static const std::vector<float> table = [] {
    std::vector<float> t(65536 * 3, 0.f);
    for (int y = -127; y <= 127; ++y)
      for (int x = -127; x <= 127; ++x) {
        Vec3d n = octDecode(x, y);
        float* o = &t[size_t(octCode(x, y)) * 3];
        o[0] = float(n.x);
        o[1] = float(n.y);
        o[2] = float(n.z);
      }
    return t;
  }();
  return table;
}

uint16_t encodeNormal(const float* n, const std::vector<float>& table) {
  Vec3d d{n[0], n[1], n[2]};
  double len = length(d);
  if (!std::isfinite(len) || len < 1e-30) return kZeroNormal;
  d = d / len;
  double s = std::fabs(d.x) + std::fabs(d.y) + std::fabs(d.z);
  double u = d.x / s, v = d.y / s;
  if (d.z < 0) {
    double fu = (1 - std::fabs(v)) * (u >= 0 ? 1 : -1);
    double fv = (1 - std::fabs(u)) * (v >= 0 ? 1 : -1);
    u = fu;
    v = fv;
  }
  // Of the four codes around (u, v), the one whose direction is closest:
  // rounding each coordinate alone is up to twice as far off.
  int x0 = int(std::floor(u * 127)), y0 = int(std::floor(v * 127));
  uint16_t best = kZeroNormal;
  double bestDot = -2;
  for (int dy = 0; dy <= 1; ++dy)
    for (int dx = 0; dx <= 1; ++dx) {
      int x = std::clamp(x0 + dx, -127, 127), y = std::clamp(y0 + dy, -127, 127);
      uint16_t c = octCode(x, y);
      const float* t = &table[size_t(c) * 3];
      double dp = d.x * t[0] + d.y * t[1] + d.z * t[2];
      if (dp > bestDot) {
        bestDot = dp;
        best = c;
      }
    }
  return best;
}

// ---- meshoptimizer ----------------------------------------------------------

void setEncoderVersions() {
  // Index format 1 (decodable by meshoptimizer 0.14 and later) compresses
  // better than the library's default 0; set once, before any encoding.
  static std::once_flag once;
  std::call_once(once, [] {
    meshopt_encodeIndexVersion(1);
    meshopt_encodeVertexVersion(0);
  });
}

// The r for which original corner k is decoded corner (k + r) % 3.
int rotationOf(const uint32_t* original, const uint32_t* decoded) {
  for (int r = 0; r < 3; ++r)
    if (original[0] == decoded[r] && original[1] == decoded[(r + 1) % 3] &&
        original[2] == decoded[(r + 2) % 3])
      return r;
  return -1;
}

}  // namespace

// ---- positions --------------------------------------------------------------

size_t cellBudget(size_t vertex_count) {
  return std::min(kMaxCells, std::max<size_t>(64, vertex_count / 2));
}

PositionGrid choosePositionGrid(const float* xyz, size_t count, size_t max_cells) {
  DMMR_CHECK(max_cells >= 1 && max_cells <= kMaxCells);
  PositionGrid g;
  if (count == 0) return g;
  Box b = boundsOf(xyz, count);
  g.origin = b.lo;
  double longest = std::max({b.hi.x - b.lo.x, b.hi.y - b.lo.y, b.hi.z - b.lo.z});
  auto cellFor = [&](uint32_t n) { return longest > 0 ? longest / n : 1.0; };
  // Occupied cells grow with n (not strictly, so n is the bisection's answer,
  // not always the largest that fits); n = 1 always fits, all in cell 0.
  uint32_t lo = 1, hi = kMaxSubdivisions;
  std::vector<uint64_t> keys = occupiedCells(xyz, count, g.origin, cellFor(hi), hi);
  if (keys.size() <= max_cells || longest == 0) {
    lo = hi;
  } else {
    while (hi - lo > 1) {
      uint32_t mid = lo + (hi - lo) / 2;
      if (occupiedCells(xyz, count, g.origin, cellFor(mid), mid).size() <= max_cells)
        lo = mid;
      else
        hi = mid;
    }
    keys = occupiedCells(xyz, count, g.origin, cellFor(lo), lo);
  }
  g.cell = cellFor(lo);
  g.cells.reserve(keys.size() * 3);
  for (uint64_t k : keys)
    g.cells.insert(g.cells.end(), {uint16_t(k >> 32), uint16_t(k >> 16), uint16_t(k)});
  return g;
}

void quantizePositions(const float* xyz, size_t count, const PositionGrid& grid,
                       uint16_t* cell_index, uint32_t* offsets) {
  std::vector<uint64_t> keys(grid.cellCount());
  for (size_t c = 0; c < keys.size(); ++c)
    keys[c] = cellKey(grid.cells[3 * c], grid.cells[3 * c + 1], grid.cells[3 * c + 2]);
  // choosePositionGrid put the box's far faces in the last cell of n; on
  // every axis that is the table's largest coordinate or beyond it, so
  // clamping there instead gives the same cells without knowing n.
  uint32_t n[3] = {1, 1, 1};
  for (size_t c = 0; c < grid.cells.size(); ++c)
    n[c % 3] = std::max(n[c % 3], uint32_t(grid.cells[c]) + 1);
  const double step = grid.cell / kOffsetSteps;
  for (size_t v = 0; v < count; ++v) {
    const float* p = xyz + 3 * v;
    uint32_t c[3];
    for (int a = 0; a < 3; ++a) c[a] = cellCoord(p[a], grid.origin[a], grid.cell, n[a]);
    auto it = std::lower_bound(keys.begin(), keys.end(), cellKey(c[0], c[1], c[2]));
    DMMR_CHECK_MSG(it != keys.end() && *it == cellKey(c[0], c[1], c[2]),
                   "vertex " << v << " lies in no cell of the grid");
    cell_index[v] = uint16_t(it - keys.begin());
    uint32_t packed = 0;
    for (int a = 0; a < 3; ++a) {
      double o = std::round((p[a] - grid.origin[a]) / step - double(c[a]) * kOffsetSteps);
      packed |= uint32_t(std::clamp(o, 0.0, double(kOffsetSteps))) << (10 * a);
    }
    offsets[v] = packed;
  }
}

std::string checkPositionGrid(const PositionGrid& grid) {
  if (!isFinite(grid.origin)) return "position origin is not finite";
  if (!(grid.cell > 0) || !std::isfinite(grid.cell))
    return "position cell size " + std::to_string(grid.cell) + " is not a positive number";
  if (grid.cells.size() % 3 || grid.cellCount() > kMaxCells)
    return "position cell table holds more than 65536 cells";
  for (size_t c = 1; c < grid.cellCount(); ++c)
    if (cellKey(grid.cells[3 * c - 3], grid.cells[3 * c - 2], grid.cells[3 * c - 1]) >=
        cellKey(grid.cells[3 * c], grid.cells[3 * c + 1], grid.cells[3 * c + 2]))
      return "position cell table is not strictly increasing at cell " + std::to_string(c);
  return "";
}

std::string dequantizePositions(const PositionGrid& grid, const uint16_t* cell_index,
                                const uint32_t* offsets, size_t count, float* xyz) {
  const size_t cells = grid.cellCount();
  const double step = grid.cell / kOffsetSteps;
  for (size_t v = 0; v < count; ++v) {
    if (cell_index[v] >= cells)
      return "position cell index " + std::to_string(cell_index[v]) + " out of range (" +
             std::to_string(cells) + " cells) at vertex " + std::to_string(v);
    if (offsets[v] >> 30)
      return "position offsets of vertex " + std::to_string(v) + " use the 2 reserved bits";
    const uint16_t* c = &grid.cells[3 * size_t(cell_index[v])];
    for (int a = 0; a < 3; ++a) {
      uint32_t o = (offsets[v] >> (10 * a)) & 0x3FF;
      double x = grid.origin[a] + double(uint32_t(c[a]) * kOffsetSteps + o) * step;
      float f = float(x);
      if (!std::isfinite(f))
        return "positions contain a non-finite value at vertex " + std::to_string(v);
      xyz[3 * v + size_t(a)] = f;
    }
  }
  return "";
}

// ---- normals ----------------------------------------------------------------

bool normalCodeValid(uint16_t code) {
  return code == kZeroNormal || ((code & 0xFF) != 0x80 && (code >> 8) != 0x80);
}

void encodeNormals(const float* xyz, size_t count, uint16_t* codes) {
  const std::vector<float>& table = normalTable();
  for (size_t v = 0; v < count; ++v) codes[v] = encodeNormal(xyz + 3 * v, table);
}

std::string decodeNormals(const uint16_t* codes, size_t count, float* xyz) {
  const std::vector<float>& table = normalTable();
  for (size_t v = 0; v < count; ++v) {
    if (!normalCodeValid(codes[v])) {
      char hex[8];
      std::snprintf(hex, sizeof hex, "0x%04x", codes[v]);
      return std::string("normal index ") + hex + " at vertex " + std::to_string(v) +
             " is not in the table";
    }
    const float* t = &table[size_t(codes[v]) * 3];
    xyz[3 * v] = t[0];
    xyz[3 * v + 1] = t[1];
    xyz[3 * v + 2] = t[2];
  }
  return "";
}

// ---- texture coordinates ----------------------------------------------------

bool chooseTexcoordOffsets(const float* uv, size_t count, int32_t offsets[2]) {
  for (int a = 0; a < 2; ++a) {
    double lo = 0, hi = 0;
    for (size_t v = 0; v < count; ++v) {
      double x = uv[2 * v + size_t(a)];
      if (!std::isfinite(x)) return false;
      lo = v == 0 ? x : std::min(lo, x);
      hi = v == 0 ? x : std::max(hi, x);
    }
    double off = std::floor(lo);
    if (std::fabs(off) > kMaxTexcoordOffset) return false;
    if (std::round((hi - off) * kTexcoordScale) > 65535) return false;
    offsets[a] = int32_t(off);
  }
  return true;
}

void quantizeTexcoords(const float* uv, size_t count, const int32_t offsets[2], uint16_t* q) {
  for (size_t i = 0; i < 2 * count; ++i) {
    // Exact in double: |uv| < 258, so the difference and the product are.
    double x = std::round((double(uv[i]) - offsets[i % 2]) * kTexcoordScale);
    DMMR_CHECK(x >= 0 && x <= 65535);
    q[i] = uint16_t(x);
  }
}

std::string dequantizeTexcoords(const uint16_t* q, size_t count, const int32_t offsets[2],
                                float* uv) {
  for (int a = 0; a < 2; ++a)
    if (offsets[a] > kMaxTexcoordOffset || offsets[a] < -kMaxTexcoordOffset)
      return "texcoord offset " + std::to_string(offsets[a]) + " beyond +-256";
  // offset + q / 2^15 has at most 24 significant bits below 2^9: exact in float.
  for (size_t i = 0; i < 2 * count; ++i)
    uv[i] = float(offsets[i % 2] + double(q[i]) / kTexcoordScale);
  return "";
}

// ---- meshoptimizer ----------------------------------------------------------

void encodeVertexStream(const uint8_t* records, size_t count, size_t stride,
                        std::vector<uint8_t>* out) {
  DMMR_CHECK(stride > 0 && stride % 4 == 0 && stride < 256);
  setEncoderVersions();
  size_t at = out->size();
  out->resize(at + meshopt_encodeVertexBufferBound(count, stride));
  size_t n = meshopt_encodeVertexBuffer(out->data() + at, out->size() - at, records, count, stride);
  DMMR_CHECK(n > 0);
  out->resize(at + n);
}

size_t maxVertexRecords(size_t size, size_t stride) {
  // Each byte of a record costs at least 2 bits per group of 16 records.
  return size * 64 / stride;
}

std::string decodeVertexStream(const uint8_t* data, size_t size, size_t count, size_t stride,
                               uint8_t* records) {
  DMMR_CHECK(stride > 0 && stride % 4 == 0 && stride < 256);
  if (count > maxVertexRecords(size, stride))
    return "vertex stream of " + std::to_string(size) + " bytes cannot hold " +
           std::to_string(count) + " vertices";
  int rc = meshopt_decodeVertexBuffer(records, count, stride, data, size);
  if (rc != 0)
    return "vertex stream: meshoptimizer cannot decode it (error " + std::to_string(rc) + ")";
  return "";
}

void encodeTriangles(const uint32_t* indices, size_t count, size_t vertex_count,
                     std::vector<uint8_t>* stream, std::vector<uint8_t>* rotations) {
  DMMR_CHECK(count % 3 == 0);
  setEncoderVersions();
  size_t at = stream->size();
  stream->resize(at + meshopt_encodeIndexBufferBound(count, vertex_count));
  size_t n = meshopt_encodeIndexBuffer(stream->data() + at, stream->size() - at, indices, count);
  DMMR_CHECK(n > 0);
  stream->resize(at + n);
  // Decode what was written to learn each triangle's rotation (and to
  // check the codec gave back the triangles, rotated at most).
  std::vector<uint32_t> decoded(count);
  DMMR_CHECK(meshopt_decodeIndexBuffer(decoded.data(), count, 4, stream->data() + at, n) == 0);
  size_t r0 = rotations->size();
  rotations->resize(r0 + rotationBytes(count), 0);
  for (size_t t = 0; t < count / 3; ++t) {
    int r = rotationOf(indices + 3 * t, decoded.data() + 3 * t);
    DMMR_CHECK_MSG(r >= 0, "index codec changed triangle " << t);
    (*rotations)[r0 + t / 4] |= uint8_t(r << (2 * (t % 4)));
  }
}

size_t maxTriangleIndices(size_t size) {
  return size * 3;  // a code byte per triangle at least
}

std::string decodeTriangles(const uint8_t* stream, size_t size, const uint8_t* rotations,
                            size_t count, size_t vertex_count, uint32_t* indices) {
  DMMR_CHECK(count % 3 == 0);
  if (count > maxTriangleIndices(size))
    return "index stream of " + std::to_string(size) + " bytes cannot hold " +
           std::to_string(count) + " indices";
  int rc = meshopt_decodeIndexBuffer(indices, count, 4, stream, size);
  if (rc != 0)
    return "index stream: meshoptimizer cannot decode it (error " + std::to_string(rc) + ")";
  size_t triangles = count / 3;
  for (size_t b = 0; b < rotationBytes(count); ++b) {
    size_t used = std::min<size_t>(4, triangles - 4 * b);
    if (used < 4 && (rotations[b] >> (2 * used)))
      return "triangle rotations: unused bits set in the last byte";
  }
  // Branch-free: the rotations are as good as random, so branches on them
  // would mispredict every other triangle.
  static constexpr uint8_t kPerm[4][3] = {{0, 1, 2}, {1, 2, 0}, {2, 0, 1}, {0, 1, 2}};
  uint32_t largest = 0;
  bool rotation3 = false;
  for (size_t t = 0; t < triangles; ++t) {
    int r = (rotations[t / 4] >> (2 * (t % 4))) & 3;
    rotation3 |= r == 3;
    uint32_t* tri = indices + 3 * t;
    uint32_t d[3] = {tri[0], tri[1], tri[2]};
    for (int k = 0; k < 3; ++k) tri[k] = d[kPerm[r][k]];
    largest = std::max({largest, d[0], d[1], d[2]});
  }
  if (rotation3)
    for (size_t t = 0; t < triangles; ++t)  // the first one, for the message
      if (((rotations[t / 4] >> (2 * (t % 4))) & 3) == 3)
        return "triangle rotation 3 (of 0..2) for triangle " + std::to_string(t);
  if (count && largest >= vertex_count)
    for (size_t i = 0; i < count; ++i)  // the first one, for the message
      if (indices[i] >= vertex_count)
        return "index " + std::to_string(indices[i]) + " out of range (" +
               std::to_string(vertex_count) + " vertices)";
  return "";
}

}  // namespace dmmr::codec
