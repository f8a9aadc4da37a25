// Compact geometry: the arithmetic behind the geometry file encodings (see
// formats.h, docs/scene-format.md), over caller-owned arrays; no file layout,
// no GL, no I/O. formats.cpp lays the results out and names files in errors.
//
//  - Positions (Sensors 2022, section 3.1.1): the geometry's box is cut into
//    cubic cells; a vertex is a 16-bit index into a table of the occupied
//    cells (at most 65,536) plus three 10-bit offsets within its cell.
//  - Normals: a 16-bit octahedral code, 8 + 8 bits.
//  - Texture coordinates: 16 bits each, 1 integer and 15 fractional bits,
//    after a per-geometry integer offset.
//  - meshoptimizer's vertex and index codecs, made exact.
//
// Decoders return "" on success and otherwise what is wrong (naming the
// field), never throw for bad input, and never read or write past the
// counts they are given.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "math.h"

namespace dmmr::codec {

// ---- positions --------------------------------------------------------------

inline constexpr size_t kMaxCells = 65536;           // cell indices are 16 bits
inline constexpr uint32_t kMaxSubdivisions = 65535;  // cell coordinates are 16 bits
inline constexpr uint32_t kOffsetSteps =
    1023;  // 10-bit offsets 0..1023 span a cell, both faces included

// The cubic cells of one geometry, computed in double in the geometry's
// local frame. Cell (i, j, k) spans origin + [i, i + 1] * cell (and so on).
struct PositionGrid {
  Vec3d origin;                 // the box minimum of the positions
  double cell = 1;              // side of every cell, > 0
  std::vector<uint16_t> cells;  // i, j, k per occupied cell, strictly increasing as (i, j, k)
  size_t cellCount() const { return cells.size() / 3; }
  friend bool operator==(const PositionGrid&, const PositionGrid&) = default;
};

// How many cells a geometry of `vertex_count` vertices may use: one per two
// vertices (the table costs 6 bytes a cell, so at most 3 bytes a vertex), and
// 64 whatever the size, which gives small geometries (the walls and floors of
// a few vertices) the finest cells. Measured in docs/benchmarks.md: one cell
// per four vertices cost the monument walkthrough 2 dB; one per vertex gained
// 6 dB for 20% more bytes.
size_t cellBudget(size_t vertex_count);

// The finest grid whose occupied cells number at most `max_cells` (1 to
// kMaxCells): the longest side of the box is cut into n equal parts, n found
// by bisection in [1, kMaxSubdivisions] as in the paper. `xyz` holds
// `count` finite points (3 floats each).
PositionGrid choosePositionGrid(const float* xyz, size_t count, size_t max_cells);

// Each point as its cell's index in grid.cells and offsets packed as
// x | y << 10 | z << 20 (the top 2 bits 0). Every point must lie in an
// occupied cell of `grid` (true for the grid choosePositionGrid made from
// the same points). Error per axis: at most cell / 2046 before the decoded
// value is rounded to float.
void quantizePositions(const float* xyz, size_t count, const PositionGrid& grid,
                       uint16_t* cell_index, uint32_t* offsets);

// A grid read from a file: finite origin, finite cell > 0, at most kMaxCells
// cells, strictly increasing.
std::string checkPositionGrid(const PositionGrid& grid);

// origin + (cell coordinate + offset / 1023) * cell, in double, rounded to
// float. Rejects cell indices out of the table, offsets using the top 2
// bits, and results that are not finite floats. `grid` passed checkPositionGrid.
std::string dequantizePositions(const PositionGrid& grid, const uint16_t* cell_index,
                                const uint32_t* offsets, size_t count, float* xyz);

// ---- normals ----------------------------------------------------------------

// Octahedral code: low byte x, high byte y, each a signed byte in
// [-127, 127] for x / 127 and y / 127 on the octahedron's unfolded square.
// 0x8080 stands for the zero vector (geometries where some drawables had no
// normals store (0, 0, 0), which the shader replaces by the facet normal);
// any other code with a byte of -128 is not in the table (255 x 255 + 1
// entries). Worst angular error of a unit normal: 0.64 degrees, near the
// octant diagonals where the octahedron is stretched most (measured over 10^6
// random directions; a wider search than the 4 neighbours gains nothing);
// mean 0.31 degrees. A test checks kNormalMaxErrorDegrees.
inline constexpr uint16_t kZeroNormal = 0x8080;
inline constexpr double kNormalMaxErrorDegrees = 0.65;

// Encodes the direction of each normal (its length is dropped; the shader
// normalises after interpolation): the code whose direction is closest of
// the four around it. Zero, non-finite or denormal-length normals become
// kZeroNormal.
void encodeNormals(const float* xyz, size_t count, uint16_t* codes);
bool normalCodeValid(uint16_t code);
// Unit vectors (or zero for kZeroNormal) from the table. Rejects codes not in it.
std::string decodeNormals(const uint16_t* codes, size_t count, float* xyz);

// ---- texture coordinates ----------------------------------------------------

inline constexpr double kTexcoordScale = 32768;  // 15 fractional bits
inline constexpr int32_t kMaxTexcoordOffset = 256;

// The per-axis integer offsets that bring every coordinate into [0, 2): u
// is stored as round((u - offset) * 32768). Returns false when the 16-bit
// form cannot hold them (a coordinate not finite, an axis spanning 2 or more,
// or |offset| > 256, past which floats near the values are coarser than
// 2^-15); the caller then keeps float texture coordinates. `uv` holds
// `count` pairs.
bool chooseTexcoordOffsets(const float* uv, size_t count, int32_t offsets[2]);
// Error at most 2^-16 per coordinate, exactly (the decoded values are floats).
void quantizeTexcoords(const float* uv, size_t count, const int32_t offsets[2], uint16_t* q);
// Rejects offsets beyond kMaxTexcoordOffset.
std::string dequantizeTexcoords(const uint16_t* q, size_t count, const int32_t offsets[2],
                                float* uv);

// ---- meshoptimizer ----------------------------------------------------------

// meshopt_encodeVertexBuffer over `count` records of `stride` bytes (a
// multiple of 4 below 256), appended to *out. Lossless.
void encodeVertexStream(const uint8_t* records, size_t count, size_t stride,
                        std::vector<uint8_t>* out);
// Rejects streams meshoptimizer cannot decode and, before writing, counts
// the stream cannot hold (its decoder expands at most 64 times).
std::string decodeVertexStream(const uint8_t* data, size_t size, size_t count, size_t stride,
                               uint8_t* records);
// The largest number of records a stream of `size` bytes can decode to.
size_t maxVertexRecords(size_t size, size_t stride);

// Triangle lists through meshopt_encodeIndexBuffer. That codec may rotate a
// triangle's corners ((a, b, c) -> (b, c, a), winding kept); `rotations`
// (2 bits a triangle, rotationBytes(count) bytes) undoes it, so that decoding
// gives back exactly the triangles encoded. `indices` holds `count` (a
// multiple of 3) indices below `vertex_count`.
void encodeTriangles(const uint32_t* indices, size_t count, size_t vertex_count,
                     std::vector<uint8_t>* stream, std::vector<uint8_t>* rotations);
inline size_t rotationBytes(size_t index_count) {
  return (index_count / 3 + 3) / 4;
}
// Rejects streams meshoptimizer cannot decode, rotations other than 0..2 or
// with unused bits set, and indices of `vertex_count` or more.
std::string decodeTriangles(const uint8_t* stream, size_t size, const uint8_t* rotations,
                            size_t count, size_t vertex_count, uint32_t* indices);
// The largest index count a stream of `size` bytes can decode to (the codec
// spends at least a byte a triangle).
size_t maxTriangleIndices(size_t size);

}  // namespace dmmr::codec
