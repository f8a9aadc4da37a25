// Tests for compact geometry: the codecs (common/geometry_codec.h) and the
// geometry file encodings built on them (common/formats.h). Fixed-seed
// random meshes check the error bounds stated in geometry_codec.h; one test
// per rejection; expected layouts are written out by hand from
// docs/scene-format.md.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "bytes.h"
#include "error.h"
#include "formats.h"
#include "geometry_codec.h"
#include "test_support.h"

namespace dmmr {
namespace {

using Bytes = std::vector<uint8_t>;
using dmmr::test::errorOf;
constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();
constexpr float kInff = std::numeric_limits<float>::infinity();

// ---- meshes ------------------------------------------------------------------

struct Attribs {
  bool normals = true, colors = true, texcoords = true;
};

// A height field of w x h quads: the connectivity of real meshes (shared
// edges, vertices in first-use order), spanning `extent` around `centre`.
GeometryData gridMesh(int w, int h, double extent, Vec3d centre, Attribs a, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> bump(-0.05, 0.05), t(0, 1);
  GeometryData g;
  for (int y = 0; y <= h; ++y)
    for (int x = 0; x <= w; ++x) {
      Vec3d p{extent * (double(x) / w - 0.5), extent * (double(y) / h - 0.5), extent * bump(rng)};
      p = p + centre;
      g.positions.insert(g.positions.end(), {float(p.x), float(p.y), float(p.z)});
      if (a.normals) {
        Vec3d n = normalize(Vec3d{bump(rng), bump(rng), 1});
        g.normals.insert(g.normals.end(), {float(n.x), float(n.y), float(n.z)});
      }
      if (a.colors)
        for (int k = 0; k < 4; ++k) g.colors.push_back(uint8_t(rng()));
      if (a.texcoords) g.texcoords.insert(g.texcoords.end(), {float(x) / w, float(y) / h});
    }
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      uint32_t i = uint32_t(y * (w + 1) + x), j = i + 1, k = i + uint32_t(w + 1), l = k + 1;
      g.indices.insert(g.indices.end(), {i, j, l, i, l, k});
    }
  uint32_t cut = uint32_t(g.indices.size()) / 3 / 2 * 3;
  SubMesh s0, s1;
  s0.index_count = cut;
  s1.first_index = cut;
  s1.index_count = uint32_t(g.indices.size()) - cut;
  s1.texture = 2;
  g.submeshes = {s0, s1};
  return g;
}

// Random vertices in a box and random triangles (degenerate ones too).
GeometryData randomMesh(size_t nv, size_t nt, double extent, Vec3d centre, Attribs a,
                        uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-0.5, 0.5), n(-1, 1), t(-3, 3);
  GeometryData g;
  for (size_t v = 0; v < nv; ++v) {
    for (int k = 0; k < 3; ++k) g.positions.push_back(float(centre[k] + extent * u(rng)));
    if (a.normals) {
      Vec3d d{n(rng), n(rng), n(rng)};
      d = length(d) > 1e-3 ? normalize(d) : Vec3d{0, 0, 1};
      g.normals.insert(g.normals.end(), {float(d.x), float(d.y), float(d.z)});
    }
    if (a.colors)
      for (int k = 0; k < 4; ++k) g.colors.push_back(uint8_t(rng()));
    if (a.texcoords) g.texcoords.insert(g.texcoords.end(), {float(t(rng)), float(t(rng) / 3)});
  }
  for (size_t i = 0; nv && i < 3 * nt; ++i) g.indices.push_back(uint32_t(rng() % nv));
  if (nt) {
    SubMesh s;
    s.index_count = uint32_t(g.indices.size());
    g.submeshes = {s};
  }
  return g;
}

double ulpOf(float f) {
  float a = std::fabs(f);
  return double(std::nextafter(a, kInff)) - double(a);
}

double angleDegrees(const float* a, const float* b) {
  Vec3d x{a[0], a[1], a[2]}, y{b[0], b[1], b[2]};
  double c = dot(normalize(x), normalize(y));
  return std::acos(std::clamp(c, -1.0, 1.0)) * 180 / M_PI;
}

// ---- positions ---------------------------------------------------------------

// |decoded - original| <= cell / 2046 per axis, plus half an ulp for rounding
// the decoded double to float. Proof: a vertex lies in cell c with
// t = (p - origin) / step in [1023 c, 1023 (c + 1)] (step = cell / 1023) and
// is stored as o = round(t) - 1023 c, clamped to [0, 1023]; the clamp only
// bites beyond the cell by rounding noise, so |t - (1023 c + o)| <= 1/2.
void expectPositionBound(const GeometryData& g, const codec::PositionGrid& grid,
                         const std::vector<float>& decoded) {
  double bound = grid.cell / 2046 * (1 + 1e-9);
  double worst = 0;
  for (size_t i = 0; i < g.positions.size(); ++i) {
    double err = std::fabs(double(decoded[i]) - g.positions[i]);
    double allowed = bound + 0.5 * ulpOf(decoded[i]);
    worst = std::max(worst, err / allowed);
    if (err > allowed) {
      ADD_FAILURE() << "coordinate " << i << ": error " << err << " > " << allowed;
      return;
    }
  }
  EXPECT_LE(worst, 1.0);
}

codec::PositionGrid gridFor(const GeometryData& g) {
  return codec::choosePositionGrid(g.positions.data(), g.vertexCount(),
                                   codec::cellBudget(g.vertexCount()));
}

std::vector<float> roundTripPositions(const GeometryData& g, const codec::PositionGrid& grid) {
  size_t nv = g.vertexCount();
  std::vector<uint16_t> cell(nv);
  std::vector<uint32_t> off(nv);
  codec::quantizePositions(g.positions.data(), nv, grid, cell.data(), off.data());
  std::vector<float> out(nv * 3);
  EXPECT_EQ(codec::dequantizePositions(grid, cell.data(), off.data(), nv, out.data()), "");
  return out;
}

TEST(PositionCodec, RandomMeshesStayWithinCellOver2046PerAxis) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> logExtent(-3, 5), c(-1e4, 1e4);
  for (int trial = 0; trial < 40; ++trial) {
    size_t nv = 1 + rng() % 3000;
    double extent = std::pow(10.0, logExtent(rng));
    GeometryData g = trial % 2 ? randomMesh(nv, nv, extent, {c(rng), c(rng), c(rng)}, {}, rng())
                               : gridMesh(1 + int(rng() % 60), 1 + int(rng() % 60), extent,
                                          {c(rng), c(rng), c(rng)}, {}, rng());
    SCOPED_TRACE("trial " + std::to_string(trial));
    codec::PositionGrid grid = gridFor(g);
    EXPECT_EQ(codec::checkPositionGrid(grid), "");
    EXPECT_LE(grid.cellCount(), codec::cellBudget(g.vertexCount()));
    expectPositionBound(g, grid, roundTripPositions(g, grid));
  }
}

TEST(PositionCodec, DenseMeshUsesAtMost65536Cells) {
  // 160,000 vertices: the budget is the table's limit, and the bisection
  // finds a grid under it.
  GeometryData g = gridMesh(399, 399, 100, {0, 0, 0}, {false, false, false}, 3);
  codec::PositionGrid grid = gridFor(g);
  EXPECT_EQ(codec::cellBudget(g.vertexCount()), codec::kMaxCells);
  EXPECT_LE(grid.cellCount(), codec::kMaxCells);
  EXPECT_GT(grid.cellCount(), codec::kMaxCells / 8);  // and not a coarse one
  expectPositionBound(g, grid, roundTripPositions(g, grid));
}

TEST(PositionCodec, SmallGeometriesGetTheFinestCells) {
  // A 4-vertex wall 25 units square: each vertex its own cell of 25 / 65535.
  GeometryData g;
  g.positions = {0, 0, 0, 25, 0, 0, 25, 0, 25, 0, 0, 25};
  codec::PositionGrid grid = gridFor(g);
  EXPECT_DOUBLE_EQ(grid.cell, 25.0 / codec::kMaxSubdivisions);
  EXPECT_EQ(grid.cellCount(), 4u);
  std::vector<float> d = roundTripPositions(g, grid);
  for (size_t i = 0; i < d.size(); ++i) EXPECT_EQ(d[i], g.positions[i]);  // corners exact
}

TEST(PositionCodec, EmptyAndSinglePointGeometries) {
  codec::PositionGrid none = codec::choosePositionGrid(nullptr, 0, 64);
  EXPECT_EQ(none.cellCount(), 0u);
  EXPECT_EQ(codec::checkPositionGrid(none), "");
  GeometryData g;
  g.positions = {1e6f, -3.5f, 7.25f, 1e6f, -3.5f, 7.25f};
  codec::PositionGrid grid = gridFor(g);
  EXPECT_EQ(grid.cellCount(), 1u);
  EXPECT_EQ(roundTripPositions(g, grid), g.positions);
}

TEST(PositionCodec, FarFromTheOriginLosesNoMoreAccuracy) {
  // The same mesh at the origin and 10^6 away. Cells, offsets and the decoded
  // sums are computed in double relative to the box minimum, so the error
  // relative to the extent agrees (the far copy only adds float rounding at
  // 10^6, 1/16, small next to cells of this 10^5-wide mesh).
  for (uint32_t seed : {1u, 2u, 3u}) {
    GeometryData near = gridMesh(150, 150, 1e5, {0, 0, 0}, {false, false, false}, seed);
    GeometryData far = near;
    for (size_t i = 0; i < far.positions.size(); ++i)
      far.positions[i] = float(double(near.positions[i]) + 1e6);
    auto relError = [](const GeometryData& g) {
      codec::PositionGrid grid = gridFor(g);
      std::vector<float> d = roundTripPositions(g, grid);
      expectPositionBound(g, grid, d);
      double worst = 0;
      for (size_t i = 0; i < d.size(); ++i)
        worst = std::max(worst, std::fabs(double(d[i]) - g.positions[i]));
      return worst / 1e5;
    };
    double a = relError(near), b = relError(far);
    EXPECT_GT(a, 0);
    EXPECT_LT(b, 1.25 * a) << "origin " << a << ", 10^6 away " << b;
    EXPECT_LT(a, 1.25 * b) << "origin " << a << ", 10^6 away " << b;
  }
}

TEST(PositionCodec, RejectsCellIndexOutOfTheTable) {
  codec::PositionGrid grid;
  grid.cells = {0, 0, 0, 1, 2, 3};
  uint16_t cell[2] = {1, 2};
  uint32_t off[2] = {0, 0};
  float out[6];
  EXPECT_NE(codec::dequantizePositions(grid, cell, off, 2, out)
                .find("position cell index 2 out of range (2 cells) at vertex 1"),
            std::string::npos);
}

TEST(PositionCodec, RejectsOffsetsUsingTheReservedBits) {
  codec::PositionGrid grid;
  grid.cells = {0, 0, 0};
  uint16_t cell[1] = {0};
  for (uint32_t bad : {1u << 30, 1u << 31}) {
    uint32_t off[1] = {bad | 5};
    float out[3];
    EXPECT_NE(codec::dequantizePositions(grid, cell, off, 1, out).find("reserved bits"),
              std::string::npos);
  }
}

TEST(PositionCodec, RejectsResultsThatAreNotFiniteFloats) {
  codec::PositionGrid grid;
  grid.origin = {3e38, 0, 0};
  grid.cell = 1e38;
  grid.cells = {65534, 0, 0};
  uint16_t cell[1] = {0};
  uint32_t off[1] = {0};
  float out[3];
  EXPECT_NE(codec::dequantizePositions(grid, cell, off, 1, out).find("non-finite"),
            std::string::npos);
}

TEST(PositionCodec, RejectsMalformedGrids) {
  codec::PositionGrid ok;
  ok.cells = {0, 0, 1, 0, 1, 0};
  EXPECT_EQ(codec::checkPositionGrid(ok), "");
  codec::PositionGrid g = ok;
  g.origin.y = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(codec::checkPositionGrid(g).find("position origin"), std::string::npos);
  for (double cell : {0.0, -1.0, std::numeric_limits<double>::infinity(),
                      std::numeric_limits<double>::quiet_NaN()}) {
    g = ok;
    g.cell = cell;
    EXPECT_NE(codec::checkPositionGrid(g).find("position cell size"), std::string::npos) << cell;
  }
  g = ok;
  g.cells = {0, 1, 0, 0, 0, 1};  // decreasing
  EXPECT_NE(codec::checkPositionGrid(g).find("not strictly increasing at cell 1"),
            std::string::npos);
  g.cells = {0, 0, 1, 0, 0, 1};  // repeated
  EXPECT_NE(codec::checkPositionGrid(g).find("not strictly increasing"), std::string::npos);
  g.cells.assign(3 * (codec::kMaxCells + 1), 0);
  EXPECT_NE(codec::checkPositionGrid(g).find("65536"), std::string::npos);
}

// ---- normals -----------------------------------------------------------------

TEST(NormalCodec, EveryCodeInTheTableIsAUnitVector) {
  size_t valid = 0;
  for (uint32_t c = 0; c < 65536; ++c) {
    uint16_t code = uint16_t(c);
    float n[3];
    std::string e = codec::decodeNormals(&code, 1, n);
    EXPECT_EQ(e.empty(), codec::normalCodeValid(code));
    if (!e.empty() || code == codec::kZeroNormal) continue;
    ++valid;
    EXPECT_NEAR(std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]), 1.0, 1e-6) << c;
  }
  EXPECT_EQ(valid, 255u * 255u);
}

TEST(NormalCodec, WorstAngularErrorIsWithinTheStatedBound) {
  // 10^6 random directions plus the axes and octant diagonals and the
  // octahedron's seams, where rounding is least favourable.
  std::mt19937 rng(5);
  std::normal_distribution<double> gauss;
  std::vector<float> n;
  for (int i = 0; i < 1000000; ++i) {
    Vec3d d = normalize(Vec3d{gauss(rng), gauss(rng), gauss(rng)});
    n.insert(n.end(), {float(d.x), float(d.y), float(d.z)});
  }
  for (int a = -1; a <= 1; ++a)
    for (int b = -1; b <= 1; ++b)
      for (int c = -1; c <= 1; ++c)
        if (a || b || c) {
          Vec3d d = normalize(Vec3d{double(a), double(b), double(c)});
          n.insert(n.end(), {float(d.x), float(d.y), float(d.z)});
        }
  for (int i = 0; i <= 1000; ++i) {  // the z = 0 seam and the x = 0 plane
    double t = i / 1000.0 * 2 * M_PI;
    n.insert(n.end(), {float(std::cos(t)), float(std::sin(t)), 0.f});
    n.insert(n.end(), {0.f, float(std::cos(t)), float(std::sin(t))});
  }
  size_t count = n.size() / 3;
  std::vector<uint16_t> codes(count);
  codec::encodeNormals(n.data(), count, codes.data());
  std::vector<float> d(n.size());
  ASSERT_EQ(codec::decodeNormals(codes.data(), count, d.data()), "");
  double worst = 0, sum = 0;
  for (size_t i = 0; i < count; ++i) {
    double e = angleDegrees(&n[3 * i], &d[3 * i]);
    worst = std::max(worst, e);
    sum += e;
  }
  EXPECT_LE(worst, codec::kNormalMaxErrorDegrees);
  EXPECT_GT(worst, codec::kNormalMaxErrorDegrees * 0.8);  // the bound is not loose
  RecordProperty("worst_degrees", std::to_string(worst));
  RecordProperty("mean_degrees", std::to_string(sum / double(count)));
}

TEST(NormalCodec, LengthIsDroppedAndZeroOrNonFiniteBecomeTheZeroCode) {
  float n[] = {0, 0, 5, 0, 0, 0, kNaNf, 0, 1, 1e-40f, 0, 0, 0, -kInff, 0};
  uint16_t codes[5];
  codec::encodeNormals(n, 5, codes);
  EXPECT_EQ(codes[0], 0x0000);  // +z is the square's centre
  for (int i = 1; i < 5; ++i) EXPECT_EQ(codes[i], codec::kZeroNormal) << i;
  float d[15];
  ASSERT_EQ(codec::decodeNormals(codes, 5, d), "");
  EXPECT_EQ(d[2], 1.f);
  for (int i = 3; i < 15; ++i) EXPECT_EQ(d[i], 0.f);
}

TEST(NormalCodec, RejectsCodesNotInTheTable) {
  for (uint16_t bad : {uint16_t(0x0080), uint16_t(0x8000), uint16_t(0x7f80), uint16_t(0x8001)}) {
    uint16_t codes[2] = {0, bad};
    float d[6];
    EXPECT_NE(codec::decodeNormals(codes, 2, d).find("normal index"), std::string::npos) << bad;
    EXPECT_NE(codec::decodeNormals(codes, 2, d).find("vertex 1"), std::string::npos) << bad;
  }
}

// ---- texture coordinates -----------------------------------------------------

TEST(TexcoordCodec, ErrorIsAtMost2ToTheMinus16) {
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> off(-256, 255);
  std::uniform_real_distribution<double> frac(0, 1.9999);
  for (int trial = 0; trial < 50; ++trial) {
    int32_t base[2] = {off(rng), off(rng)};
    size_t n = 1 + rng() % 500;
    std::vector<float> uv;
    for (size_t i = 0; i < n; ++i)
      for (int a = 0; a < 2; ++a) uv.push_back(float(base[a] + frac(rng)));
    int32_t o[2];
    ASSERT_TRUE(codec::chooseTexcoordOffsets(uv.data(), n, o));
    std::vector<uint16_t> q(2 * n);
    codec::quantizeTexcoords(uv.data(), n, o, q.data());
    std::vector<float> d(2 * n);
    ASSERT_EQ(codec::dequantizeTexcoords(q.data(), n, o, d.data()), "");
    for (size_t i = 0; i < 2 * n; ++i)
      ASSERT_LE(std::fabs(double(d[i]) - uv[i]), std::ldexp(1.0, -16)) << uv[i];
  }
}

TEST(TexcoordCodec, CoordinatesOutsideTheRangeAreNotWrapped) {
  int32_t o[2];
  std::vector<float> ok = {-3.5f, 0.25f, -2.00002f, 1.2f};  // u in [-4, -2), v in [0, 2)
  ASSERT_TRUE(codec::chooseTexcoordOffsets(ok.data(), 2, o));
  EXPECT_EQ(o[0], -4);
  EXPECT_EQ(o[1], 0);
  // Spans of 2 or more, offsets past 256 and non-finite values keep floats.
  for (std::vector<float> bad :
       {std::vector<float>{0, 0, 2, 0}, std::vector<float>{0, 0.5f, 0, 2.5f},
        std::vector<float>{300, 0, 300.5f, 0}, std::vector<float>{-257.5f, 0, -257, 0},
        std::vector<float>{kNaNf, 0, 0, 0}, std::vector<float>{0, kInff, 0, 0}})
    EXPECT_FALSE(codec::chooseTexcoordOffsets(bad.data(), 2, o)) << bad[0] << " " << bad[1];
  // The widest span that fits: 65535 steps of 2^-15.
  std::vector<float> widest = {0, 0, float(65535 / 32768.0), 0};
  EXPECT_TRUE(codec::chooseTexcoordOffsets(widest.data(), 2, o));
}

TEST(TexcoordCodec, RejectsOffsetsBeyond256) {
  uint16_t q[2] = {0, 0};
  float d[2];
  int32_t o[2] = {0, 257};
  EXPECT_NE(codec::dequantizeTexcoords(q, 1, o, d).find("texcoord offset 257"), std::string::npos);
  o[1] = -257;
  EXPECT_NE(codec::dequantizeTexcoords(q, 1, o, d).find("texcoord offset"), std::string::npos);
}

// ---- meshoptimizer -----------------------------------------------------------

TEST(MeshoptCodec, VertexStreamsRoundTripExactly) {
  std::mt19937 rng(9);
  for (size_t stride : {4, 8, 12, 20, 36, 252})
    for (size_t n : {0, 1, 17, 1000}) {
      Bytes rec(n * stride);
      for (size_t i = 0; i < rec.size(); ++i) rec[i] = uint8_t(i % stride < 2 ? rng() : i / stride);
      Bytes s;
      codec::encodeVertexStream(rec.data(), n, stride, &s);
      Bytes out(n * stride);
      ASSERT_EQ(codec::decodeVertexStream(s.data(), s.size(), n, stride, out.data()), "");
      EXPECT_EQ(out, rec) << stride << " x " << n;
    }
}

TEST(MeshoptCodec, TrianglesRoundTripExactlyWithTheirCornerOrder) {
  // The index codec rotates corners; the rotation bits put them back.
  std::vector<GeometryData> meshes = {gridMesh(40, 30, 1, {}, {}, 1),
                                      randomMesh(300, 2000, 1, {}, {}, 2),
                                      randomMesh(70000, 3000, 1, {}, {}, 3)};
  GeometryData degenerate;
  degenerate.positions.resize(9);
  degenerate.indices = {0, 0, 1, 2, 1, 1, 1, 2, 2, 0, 0, 0, 2, 1, 0};
  meshes.push_back(degenerate);
  for (const GeometryData& g : meshes) {
    Bytes stream, rot;
    codec::encodeTriangles(g.indices.data(), g.indices.size(), g.vertexCount(), &stream, &rot);
    EXPECT_EQ(rot.size(), codec::rotationBytes(g.indices.size()));
    std::vector<uint32_t> out(g.indices.size());
    ASSERT_EQ(codec::decodeTriangles(stream.data(), stream.size(), rot.data(), out.size(),
                                     g.vertexCount(), out.data()),
              "");
    EXPECT_EQ(out, g.indices);
  }
}

struct EncodedTriangles {
  Bytes stream, rot;
  std::vector<uint32_t> indices;
};
EncodedTriangles sampleTriangles() {
  EncodedTriangles t;
  t.indices = gridMesh(4, 3, 1, {}, {}, 1).indices;  // 24 triangles
  codec::encodeTriangles(t.indices.data(), t.indices.size(), 20, &t.stream, &t.rot);
  return t;
}
std::string decodeSample(const EncodedTriangles& t, size_t vertices = 20) {
  std::vector<uint32_t> out(t.indices.size());
  return codec::decodeTriangles(t.stream.data(), t.stream.size(), t.rot.data(), out.size(),
                                vertices, out.data());
}

TEST(MeshoptCodec, RejectsCorruptOrTruncatedIndexStreams) {
  EncodedTriangles t = sampleTriangles();
  EXPECT_EQ(decodeSample(t), "");
  EncodedTriangles bad = t;
  bad.stream[0] ^= 0x10;  // header byte: unknown codec version
  EXPECT_NE(decodeSample(bad).find("index stream"), std::string::npos);
  bad = t;
  bad.stream.pop_back();
  EXPECT_NE(decodeSample(bad).find("index stream"), std::string::npos);
  bad = t;
  bad.stream.push_back(0);  // a byte the codec does not use
  EXPECT_NE(decodeSample(bad).find("index stream"), std::string::npos);
}

TEST(MeshoptCodec, RejectsRotation3AndUnusedRotationBits) {
  EncodedTriangles t = sampleTriangles();  // 24 triangles: 6 full bytes
  EncodedTriangles bad = t;
  bad.rot[2] |= 3 << 4;  // triangle 10
  EXPECT_NE(decodeSample(bad).find("triangle rotation 3 (of 0..2) for triangle 10"),
            std::string::npos);
  std::vector<uint32_t> idx = {0, 1, 2, 2, 1, 3, 3, 1, 0};  // 3 triangles: 2 bits unused
  Bytes s, rot;
  codec::encodeTriangles(idx.data(), idx.size(), 4, &s, &rot);
  rot[0] |= 0x40;
  std::vector<uint32_t> out(9);
  EXPECT_NE(
      codec::decodeTriangles(s.data(), s.size(), rot.data(), 9, 4, out.data()).find("unused bits"),
      std::string::npos);
}

TEST(MeshoptCodec, RejectsIndicesBeyondTheVertexCount) {
  EncodedTriangles t = sampleTriangles();
  EXPECT_NE(decodeSample(t, 19).find("index 19 out of range (19 vertices)"), std::string::npos);
}

TEST(MeshoptCodec, RejectsCountsTheStreamCannotHold) {
  EncodedTriangles t = sampleTriangles();
  std::vector<uint32_t> out(3 * 3 * t.stream.size() + 3);
  Bytes rot(codec::rotationBytes(out.size()), 0);
  EXPECT_NE(codec::decodeTriangles(t.stream.data(), t.stream.size(), rot.data(), out.size(), 20,
                                   out.data())
                .find("cannot hold"),
            std::string::npos);
  Bytes s;
  Bytes rec(64, 0);
  codec::encodeVertexStream(rec.data(), 16, 4, &s);
  Bytes big(codec::maxVertexRecords(s.size(), 4) * 4 + 4);
  EXPECT_NE(codec::decodeVertexStream(s.data(), s.size(), big.size() / 4, 4, big.data())
                .find("cannot hold"),
            std::string::npos);
}

// ---- geometry files ----------------------------------------------------------

Bytes payloadOf(const Bytes& file) {
  return Bytes(file.begin() + 20, file.end() - 4);
}
Bytes withPayload(const Bytes& file, const Bytes& payload) {
  Bytes f(file.begin(), file.begin() + 12);
  for (int i = 0; i < 8; ++i) f.push_back(uint8_t(uint64_t(payload.size()) >> (8 * i)));
  f.insert(f.end(), payload.begin(), payload.end());
  uint32_t c = crc32(f.data(), f.size());
  for (int i = 0; i < 4; ++i) f.push_back(uint8_t(c >> (8 * i)));
  return f;
}
uint64_t le(const Bytes& b, size_t at, int n) {
  uint64_t v = 0;
  for (int i = 0; i < n; ++i) v |= uint64_t(b.at(at + size_t(i))) << (8 * i);
  return v;
}
void put(Bytes& b, size_t at, uint64_t v, int n) {
  for (int i = 0; i < n; ++i) b.at(at + size_t(i)) = uint8_t(v >> (8 * i));
}
Bytes patched(const Bytes& file, size_t at, uint64_t v, int n) {
  Bytes p = payloadOf(file);
  put(p, at, v, n);
  return withPayload(file, p);
}

// Payload offsets of the quantized layouts (docs/scene-format.md).
struct QuantizedLayout {
  size_t grid, cells, table, texcoord_mode, after_header;           // after the texcoord header
  size_t cell_index, offsets, normals, colors, texcoords, indices;  // Quantized only
};
QuantizedLayout quantizedLayout(const Bytes& file) {
  Bytes p = payloadOf(file);
  uint8_t flags = p[1];
  size_t nv = le(p, 2, 4), ns = le(p, 10, 4);
  QuantizedLayout l;
  l.grid = 14 + 28 * ns;
  l.cells = l.grid + 32;
  l.table = l.cells + 4;
  l.texcoord_mode = l.table + 6 * le(p, l.cells, 4);
  l.after_header = l.texcoord_mode;
  if (flags & 4) l.after_header += p[l.texcoord_mode] == 0 ? 9 : 1;
  l.cell_index = l.after_header;
  l.offsets = l.cell_index + 2 * nv;
  l.normals = l.offsets + 4 * nv;
  l.colors = l.normals + ((flags & 1) ? 2 * nv : 0);
  l.texcoords = l.colors + ((flags & 2) ? 4 * nv : 0);
  l.indices = l.texcoords + ((flags & 4) ? (p[l.texcoord_mode] == 0 ? 4 : 8) * nv : 0);
  return l;
}

GeometryData decoded(const GeometryData& g, Encoding e) {
  return decodeGeometry(encodeGeometry(g, e), "g.bin");
}

GeometryData sample(Attribs a = {}) {
  GeometryData g = gridMesh(12, 9, 10, {1, 2, 3}, a, 21);
  g.lod_indices = {0, 1, 14, 14, 13, 0};
  return g;
}

TEST(GeometryEncodings, NamesRoundTripAndUnknownNamesAreRefused) {
  for (Encoding e : kEncodings) {
    Encoding back = Encoding::Float32;
    EXPECT_TRUE(parseEncoding(encodingName(e), &back));
    EXPECT_EQ(back, e);
  }
  Encoding e;
  EXPECT_FALSE(parseEncoding("float16", &e));
  EXPECT_FALSE(parseEncoding("", &e));
  EXPECT_STREQ(encodingName(Encoding::QuantizedMeshopt), "quantized-meshopt");
}

TEST(GeometryEncodings, DefaultIsTheFloat32Layout) {
  GeometryData g = sample();
  EXPECT_EQ(encodeGeometry(g), encodeGeometry(g, Encoding::Float32));
  EXPECT_EQ(payloadOf(encodeGeometry(g))[0], 0);
}

TEST(GeometryEncodings, LosslessEncodingsRoundTripExactly) {
  for (Encoding e : {Encoding::Float32, Encoding::Meshopt})
    for (int mask = 0; mask < 8; ++mask) {
      Attribs a{bool(mask & 1), bool(mask & 2), bool(mask & 4)};
      for (const GeometryData& g :
           {sample(a), randomMesh(70000, 500, 3, {}, a, uint32_t(mask)), GeometryData{}}) {
        EXPECT_TRUE(isLossless(e));
        EXPECT_EQ(decoded(g, e), g) << encodingName(e) << " mask " << mask;
      }
    }
}

TEST(GeometryEncodings, MeshoptKeepsNonFiniteAttributesBitForBit) {
  GeometryData g = sample();
  g.normals[4] = kNaNf;
  g.texcoords[1] = -kInff;
  Bytes f = encodeGeometry(g, Encoding::Meshopt);
  EXPECT_EQ(encodeGeometry(decodeGeometry(f, "g.bin")), encodeGeometry(g));
}

// The quantized encodings: positions within the cell bound, normals within
// the angle bound, texture coordinates within 2^-16, the rest exact.
void expectQuantizedBounds(const GeometryData& g, const GeometryData& d) {
  EXPECT_EQ(d.indices, g.indices);
  EXPECT_EQ(d.lod_indices, g.lod_indices);
  EXPECT_EQ(d.submeshes, g.submeshes);
  EXPECT_EQ(d.colors, g.colors);
  ASSERT_EQ(d.positions.size(), g.positions.size());
  expectPositionBound(g, gridFor(g), d.positions);
  ASSERT_EQ(d.normals.size(), g.normals.size());
  for (size_t v = 0; v < g.normals.size() / 3; ++v)
    ASSERT_LE(angleDegrees(&g.normals[3 * v], &d.normals[3 * v]), codec::kNormalMaxErrorDegrees);
  ASSERT_EQ(d.texcoords.size(), g.texcoords.size());
  for (size_t i = 0; i < g.texcoords.size(); ++i)
    ASSERT_LE(std::fabs(double(d.texcoords[i]) - g.texcoords[i]), std::ldexp(1.0, -16));
}

TEST(GeometryEncodings, QuantizedEncodingsKeepTheirErrorBounds) {
  std::mt19937 rng(31);
  for (Encoding e : {Encoding::Quantized, Encoding::QuantizedMeshopt})
    for (int trial = 0; trial < 16; ++trial) {
      Attribs a{bool(trial & 1), bool(trial & 2), bool(trial & 4)};
      GeometryData g = trial % 3
                           ? randomMesh(1 + rng() % 2000, rng() % 2000, 50, {5, 6, 7}, a, rng())
                           : sample(a);
      SCOPED_TRACE(std::string(encodingName(e)) + " trial " + std::to_string(trial));
      EXPECT_FALSE(isLossless(e));
      expectQuantizedBounds(g, decoded(g, e));
    }
}

TEST(GeometryEncodings, QuantizedEncodingsAreTheSameData) {
  // Both quantized layouts hold the same values; their decodings agree.
  for (int mask = 0; mask < 8; ++mask) {
    GeometryData g = sample({bool(mask & 1), bool(mask & 2), bool(mask & 4)});
    EXPECT_EQ(decoded(g, Encoding::Quantized), decoded(g, Encoding::QuantizedMeshopt)) << mask;
  }
}

TEST(GeometryEncodings, WideTexcoordsFallBackToFloatsNotWrapped) {
  GeometryData g = sample();
  g.texcoords[0] = -7.25f;  // u spans more than 2
  g.texcoords[5] = 1234.5f;
  for (Encoding e : {Encoding::Quantized, Encoding::QuantizedMeshopt}) {
    GeometryData d = decoded(g, e);
    EXPECT_EQ(d.texcoords, g.texcoords) << encodingName(e);
    EXPECT_EQ(payloadOf(encodeGeometry(g, e))[quantizedLayout(encodeGeometry(g, e)).texcoord_mode],
              1);
  }
}

TEST(GeometryEncodings, QuantizedPayloadLayoutMatchesHandEncoding) {
  // A unit square at z = 0 with normals +z and +x and texture coordinates:
  // 4 vertices, so 64 cells may be used and each corner gets its own cell of
  // 1 / 65535; the far corners lie in cell 65534 at offset 1023.
  GeometryData g;
  g.positions = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
  g.normals = {0, 0, 1, 0, 0, 1, 1, 0, 0, 0, 0, -3};
  g.texcoords = {0, 0, 1, 0, 1, 0.5f, 0.25f, 1.5f};
  g.indices = {0, 1, 2, 0, 2, 3};
  SubMesh s;
  s.index_count = 6;
  g.submeshes = {s};
  Bytes h;
  auto u = [&](uint64_t v, int n) {
    for (int i = 0; i < n; ++i) h.push_back(uint8_t(v >> (8 * i)));
  };
  auto f64 = [&](double d) {
    uint64_t b;
    std::memcpy(&b, &d, 8);
    u(b, 8);
  };
  u(1, 1);          // quantized
  u(1 | 4 | 8, 1);  // normals, texcoords, 16-bit indices
  u(4, 4), u(6, 4), u(1, 4);
  u(0, 4), u(6, 4);
  for (float d : s.diffuse) {
    uint32_t b;
    std::memcpy(&b, &d, 4);
    u(b, 4);
  }
  u(uint32_t(-1), 4);
  f64(0), f64(0), f64(0), f64(1.0 / 65535);
  u(4, 4);  // cells, sorted as (i, j, k): (0,0,0) (0,65534,0) (65534,0,0) (65534,65534,0)
  for (uint16_t c : {0, 0, 0, 0, 65534, 0, 65534, 0, 0, 65534, 65534, 0}) u(c, 2);
  u(0, 1), u(0, 4), u(0, 4);                // texcoords fixed, offsets 0 and 0
  for (uint16_t c : {0, 2, 3, 1}) u(c, 2);  // each vertex's cell
  for (uint32_t o : {0u, 1023u, 1023u | 1023u << 10, 1023u << 10}) u(o, 4);
  for (uint16_t n : {0x0000, 0x0000, 0x007f, 0x7f7f}) u(n, 2);  // +z, +z, +x, -z (a corner)
  for (uint16_t t : {0, 0, 32768, 0, 32768, 16384, 8192, 49152}) u(t, 2);
  for (uint16_t i : {0, 1, 2, 0, 2, 3}) u(i, 2);
  Bytes f = encodeGeometry(g, Encoding::Quantized);
  EXPECT_EQ(payloadOf(f), h);
  GeometryData d = decodeGeometry(f, "g.bin");
  EXPECT_EQ(d.positions, g.positions);
  EXPECT_EQ(d.texcoords, g.texcoords);
  std::vector<float> n = {0, 0, 1, 0, 0, 1, 1, 0, 0, 0, 0, -1};
  EXPECT_EQ(d.normals, n);
}

TEST(GeometryEncodings, MeshoptPayloadLayout) {
  // header | vertex stream size u32 | stream | index stream size u32 |
  // stream | rotations | lod count | lod stream size | stream | rotations.
  GeometryData g = sample();
  Bytes p = payloadOf(encodeGeometry(g, Encoding::Meshopt));
  EXPECT_EQ(p[0], 2);
  EXPECT_EQ(p[1], 1 | 2 | 4 | 16);  // no 16-bit index flag
  size_t at = 14 + 28 * 2;
  size_t vsize = le(p, at, 4);
  Bytes rec(g.vertexCount() * 36);
  ASSERT_EQ(codec::decodeVertexStream(&p[at + 4], vsize, g.vertexCount(), 36, rec.data()), "");
  float x;
  std::memcpy(&x, &rec[36 * 5 + 4], 4);  // vertex 5's y
  EXPECT_EQ(x, g.positions[16]);
  EXPECT_EQ(rec[36 * 7 + 24], g.colors[28]);
  at += 4 + vsize;
  size_t isize = le(p, at, 4);
  at += 4 + isize + codec::rotationBytes(g.indices.size());
  EXPECT_EQ(le(p, at, 4), 6u);
  at += 4;
  at += 4 + le(p, at, 4) + codec::rotationBytes(6);
  EXPECT_EQ(at, p.size());
}

// ---- rejections, every encoding ----------------------------------------------

void expectRejected(const Bytes& f, const std::string& needle) {
  std::string msg = errorOf([&] { decodeGeometry(f, "geo/000001.bin"); });
  EXPECT_NE(msg.find("geo/000001.bin"), std::string::npos) << msg;
  EXPECT_NE(msg.find(needle), std::string::npos) << "'" << msg << "' lacks '" << needle << "'";
}

TEST(GeometryEncodings, RejectsEveryTruncation) {
  for (Encoding e : kEncodings) {
    Bytes f = encodeGeometry(sample(), e);
    for (size_t n = 0; n < f.size(); ++n) {
      Bytes cut(f.begin(), f.begin() + long(n));
      ASSERT_FALSE(errorOf([&] { decodeGeometry(cut, "cut.bin"); }).empty())
          << encodingName(e) << " prefix " << n;
    }
    // And every truncated payload inside a valid container.
    Bytes p = payloadOf(f);
    for (size_t n = 0; n < p.size(); ++n)
      ASSERT_FALSE(errorOf([&] {
                     decodeGeometry(withPayload(f, Bytes(p.begin(), p.begin() + long(n))), "c");
                   }).empty())
          << encodingName(e) << " payload prefix " << n;
  }
}

TEST(GeometryEncodings, RejectsTrailingBytes) {
  for (Encoding e : kEncodings) {
    Bytes f = encodeGeometry(sample(), e);
    Bytes p = payloadOf(f);
    p.push_back(0);
    expectRejected(withPayload(f, p), "trailing");
  }
}

TEST(GeometryEncodings, RejectsUnknownEncoding) {
  Bytes f = encodeGeometry(sample(), Encoding::QuantizedMeshopt);
  for (uint8_t e : {4, 200}) expectRejected(patched(f, 0, e, 1), "encoding " + std::to_string(e));
}

TEST(GeometryEncodings, RejectsSixteenBitIndexFlagOnMeshoptIndices) {
  for (Encoding e : {Encoding::Meshopt, Encoding::QuantizedMeshopt}) {
    Bytes f = encodeGeometry(sample(), e);
    expectRejected(patched(f, 1, payloadOf(f)[1] | 8, 1), "flags");
  }
}

TEST(GeometryEncodings, RejectsCellCountBeyond65536) {
  for (Encoding e : {Encoding::Quantized, Encoding::QuantizedMeshopt}) {
    Bytes f = encodeGeometry(sample(), e);
    expectRejected(patched(f, quantizedLayout(f).cells, 65537, 4), "position cell count 65537");
  }
}

TEST(GeometryEncodings, RejectsMalformedCellTable) {
  Bytes f = encodeGeometry(sample(), Encoding::Quantized);
  QuantizedLayout l = quantizedLayout(f);
  ASSERT_GE(le(payloadOf(f), l.cells, 4), 2u);
  Bytes p = payloadOf(f);
  for (int k = 0; k < 6; ++k) std::swap(p[l.table + size_t(k)], p[l.table + 6 + size_t(k)]);
  expectRejected(withPayload(f, p), "position cell table is not strictly increasing");
  expectRejected(patched(f, l.grid + 24, 0, 8), "position cell size");
  expectRejected(patched(f, l.grid + 8, 0x7FF0000000000000ull, 8), "position origin");
}

TEST(GeometryEncodings, RejectsCellIndexOutOfRange) {
  Bytes f = encodeGeometry(sample(), Encoding::Quantized);
  QuantizedLayout l = quantizedLayout(f);
  size_t cells = le(payloadOf(f), l.cells, 4);
  expectRejected(patched(f, l.cell_index + 2 * 3, cells, 2),
                 "position cell index " + std::to_string(cells) + " out of range");
}

TEST(GeometryEncodings, RejectsReservedOffsetBits) {
  Bytes f = encodeGeometry(sample(), Encoding::Quantized);
  QuantizedLayout l = quantizedLayout(f);
  expectRejected(patched(f, l.offsets + 4 * 2 + 3, 0x40, 1), "reserved bits");
}

TEST(GeometryEncodings, RejectsNormalIndexNotInTheTable) {
  Bytes f = encodeGeometry(sample(), Encoding::Quantized);
  expectRejected(patched(f, quantizedLayout(f).normals + 2, 0x0080, 2), "normal index 0x0080");
}

TEST(GeometryEncodings, RejectsUnknownTexcoordMode) {
  for (Encoding e : {Encoding::Quantized, Encoding::QuantizedMeshopt}) {
    Bytes f = encodeGeometry(sample(), e);
    expectRejected(patched(f, quantizedLayout(f).texcoord_mode, 2, 1), "texcoord mode 2");
  }
}

TEST(GeometryEncodings, RejectsTexcoordOffsetBeyond256) {
  Bytes f = encodeGeometry(sample(), Encoding::Quantized);
  expectRejected(patched(f, quantizedLayout(f).texcoord_mode + 5, uint32_t(-300), 4),
                 "texcoord offset -300");
}

TEST(GeometryEncodings, RejectsNonFinitePositionsInEveryEncoding) {
  GeometryData g = sample({false, false, false});
  g.positions[7] = kInff;
  expectRejected(encodeGeometry(g, Encoding::Meshopt), "positions contain a non-finite value");
  // Quantized: a cell so large that the decoded sum overflows float.
  Bytes f = encodeGeometry(sample(), Encoding::Quantized);
  expectRejected(patched(f, quantizedLayout(f).grid + 24, std::bit_cast<uint64_t>(1e38), 8),
                 "non-finite");
}

// The vertex stream's size field and bytes in a meshopt layout.
size_t vertexStreamAt(const Bytes& f, Encoding e) {
  return e == Encoding::Meshopt ? 14 + 28 * le(payloadOf(f), 10, 4)
                                : quantizedLayout(f).after_header;
}

TEST(GeometryEncodings, RejectsCorruptVertexStream) {
  for (Encoding e : {Encoding::Meshopt, Encoding::QuantizedMeshopt}) {
    Bytes f = encodeGeometry(sample(), e);
    size_t at = vertexStreamAt(f, e);
    expectRejected(patched(f, at + 4, 0x00, 1), "vertex stream");  // header byte 0xa0 -> 0
  }
}

TEST(GeometryEncodings, RejectsVertexStreamSizePastTheFile) {
  for (Encoding e : {Encoding::Meshopt, Encoding::QuantizedMeshopt}) {
    Bytes f = encodeGeometry(sample(), e);
    expectRejected(patched(f, vertexStreamAt(f, e), 1u << 30, 4), "truncated: vertex stream");
  }
}

TEST(GeometryEncodings, RejectsCorruptIndexStreamAndRotations) {
  for (Encoding e : {Encoding::Meshopt, Encoding::QuantizedMeshopt}) {
    Bytes f = encodeGeometry(sample(), e);
    size_t at = vertexStreamAt(f, e);
    at += 4 + le(payloadOf(f), at, 4);  // the index stream's size
    expectRejected(patched(f, at + 4, 0x00, 1), "indices: index stream");
    size_t rot = at + 4 + le(payloadOf(f), at, 4);
    expectRejected(patched(f, rot, 0xFF, 1), "indices: triangle rotation 3");
  }
}

TEST(GeometryEncodings, RejectsNonZeroVertexPadding) {
  // Quantized records without normals carry 2 zero bytes where the normal
  // code would be.
  GeometryData g = sample({false, true, false});
  Bytes f = encodeGeometry(g, Encoding::QuantizedMeshopt);
  Bytes p = payloadOf(f);
  size_t at = vertexStreamAt(f, Encoding::QuantizedMeshopt);
  size_t size = le(p, at, 4), nv = g.vertexCount();
  Bytes rec(nv * 12);
  ASSERT_EQ(codec::decodeVertexStream(&p[at + 4], size, nv, 12, rec.data()), "");
  rec[12 * 3 + 6] = 1;
  Bytes stream;
  codec::encodeVertexStream(rec.data(), nv, 12, &stream);
  Bytes q(p.begin(), p.begin() + long(at));
  for (int i = 0; i < 4; ++i) q.push_back(uint8_t(stream.size() >> (8 * i)));
  q.insert(q.end(), stream.begin(), stream.end());
  q.insert(q.end(), p.begin() + long(at + 4 + size), p.end());
  expectRejected(withPayload(f, q), "padding of vertex 3 is not zero");
}

TEST(GeometryEncodings, RejectsCountsTheMeshoptStreamsCannotHold) {
  // Checked before allocating (formats_test checks the allocation itself).
  Bytes f = encodeGeometry(sample(), Encoding::Meshopt);
  expectRejected(patched(f, 2, 3000000, 4), "cannot hold 3000000 vertices");
  f = encodeGeometry(sample(), Encoding::QuantizedMeshopt);
  expectRejected(patched(f, 6, 3000000 * 3, 4), "cannot hold 9000000 indices");
}

}  // namespace
}  // namespace dmmr
