// Exact triangle culling (common/coverage.h): a dropped triangle must cover
// no pixel centre however a GPU's float arithmetic places it. The property
// test rasterises every triangle the way a GL driver may (float transforms
// in two summation orders, with and without FMA, vertices snapped by
// rounding or by truncation) and checks that none the culling dropped
// covers a centre, on fixed-seed random scenes with scales, rotations and
// positions far from the origin; and that the culling drops most of what
// it may, so that it is not vacuously safe.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include "camera.h"
#include "coverage.h"

using namespace dmmr;

namespace {

// The renderer's composition (draw.cpp): camera-relative in double.
Mat4d objectToEye(const Camera& cam, const Mat4d& object_to_world) {
  Mat4d rel = object_to_world;
  for (int i = 0; i < 3; ++i) rel.at(i, 3) -= cam.eye[i];
  return viewRotation(cam) * rel;
}

// One way a GPU may compute a vertex's window position.
struct Arith {
  bool reverse = false;   // summation order
  bool fma = false;       // contracted multiply-adds
  bool truncate = false;  // snapping by truncation instead of rounding
};

float dot4(const float* row, const float* v, Arith a) {
  if (a.fma) {
    float s = 0;
    for (int k = 0; k < 4; ++k)
      s = std::fma(row[a.reverse ? 3 - k : k], v[a.reverse ? 3 - k : k], s);
    return s;
  }
  float s = 0;
  for (int k = 0; k < 4; ++k) s += row[a.reverse ? 3 - k : k] * v[a.reverse ? 3 - k : k];
  return s;
}

// The snapped window position in sub-pixel units (1 / 2^bits), or false
// when w <= 0.
bool gpuWindow(const Mat4d& mv, const Mat4d& proj, const float* p, int width, int height, int bits,
               Arith a, int64_t* sx, int64_t* sy) {
  float m[4][4], q[4][4];
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) m[r][c] = float(mv.at(r, c)), q[r][c] = float(proj.at(r, c));
  float v[4] = {p[0], p[1], p[2], 1.f}, e[4], clip[4];
  for (int r = 0; r < 4; ++r) e[r] = dot4(m[r], v, a);
  for (int r = 0; r < 4; ++r) clip[r] = dot4(q[r], e, a);
  if (!(clip[3] > 0)) return false;
  float nx = clip[0] / clip[3], ny = clip[1] / clip[3];
  float wx = nx * (0.5f * float(width)) + 0.5f * float(width);
  float wy = ny * (0.5f * float(height)) + 0.5f * float(height);
  double scale = std::ldexp(1.0, bits);
  auto snap = [&](float f) {
    double s = double(f) * scale;
    return int64_t(a.truncate ? std::floor(s) : std::nearbyint(s));
  };
  *sx = snap(wx);
  *sy = snap(wy);
  return true;
}

// Whether the snapped triangle covers a pixel centre of `scissor` (edges
// inclusive: a superset of any tie rule).
bool coversCentre(const int64_t x[3], const int64_t y[3], int bits, Rect scissor) {
  const int64_t one = int64_t(1) << bits, half = one / 2;
  int64_t lx = std::min({x[0], x[1], x[2]}), hx = std::max({x[0], x[1], x[2]});
  int64_t ly = std::min({y[0], y[1], y[2]}), hy = std::max({y[0], y[1], y[2]});
  // Centres (i + 1/2) in the box, within the scissor.
  int64_t i0 = std::max<int64_t>(
      scissor.x, (lx - half + one - 1) >= 0 ? (lx - half + one - 1) / one : -((half - lx) / one));
  int64_t i1 = std::min<int64_t>(
      scissor.x1() - 1, (hx - half) >= 0 ? (hx - half) / one : -((half - hx + one - 1) / one));
  int64_t j0 = std::max<int64_t>(
      scissor.y, (ly - half + one - 1) >= 0 ? (ly - half + one - 1) / one : -((half - ly) / one));
  int64_t j1 = std::min<int64_t>(
      scissor.y1() - 1, (hy - half) >= 0 ? (hy - half) / one : -((half - hy + one - 1) / one));
  for (int64_t j = j0; j <= j1; ++j)
    for (int64_t i = i0; i <= i1; ++i) {
      int64_t cx = i * one + half, cy = j * one + half;
      bool pos = true, neg = true;
      for (int k = 0; k < 3; ++k) {
        int l = (k + 1) % 3;
        __int128 e = __int128(x[l] - x[k]) * (cy - y[k]) - __int128(y[l] - y[k]) * (cx - x[k]);
        pos = pos && e >= 0;
        neg = neg && e <= 0;
      }
      if (pos || neg) return true;
    }
  return false;
}

struct Scenario {
  Camera cam;
  Mat4d object_to_world;
  int width, height, bits;
  Rect scissor;
  std::vector<float> positions;
  std::vector<uint32_t> indices;
};

// Tiny triangles (a few hundredths of a pixel to a few pixels) scattered in
// front of a camera far from the origin, in an object scaled and rotated.
Scenario randomScenario(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0, 1);
  Scenario s;
  s.width = 40 + int(u(rng) * 400);
  s.height = 30 + int(u(rng) * 300);
  s.bits = u(rng) < 0.5 ? 8 : 4;
  int sx = int(u(rng) * s.width * 0.5), sy = int(u(rng) * s.height * 0.5);
  s.scissor = {sx, sy, 1 + int(u(rng) * (s.width - sx - 1)), 1 + int(u(rng) * (s.height - sy - 1))};
  double far = std::pow(10.0, u(rng) * 6);  // up to a million units from the origin
  s.cam.eye = {far * (u(rng) - 0.5), far * (u(rng) - 0.5), far * (u(rng) - 0.5)};
  Vec3d axis{u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5};
  double angle = u(rng) * 6.28;
  Vec3d n = axis / length(axis);
  s.cam.rotation = Quatd{std::cos(angle / 2), n.x * std::sin(angle / 2), n.y * std::sin(angle / 2),
                         n.z * std::sin(angle / 2)};
  s.cam.fovy_deg = 20 + u(rng) * 70;
  s.cam.aspect = double(s.width) / s.height;
  s.cam.near = 0.01 + u(rng);
  // The object: a scale, a rotation, placed 2-50 units ahead of the eye.
  double scale = std::pow(10.0, u(rng) * 4 - 2);
  double dist = 2 + u(rng) * 48;
  Mat4d cam_rot = Mat4d::rotation(s.cam.rotation);
  Vec3d ahead = cam_rot.transformVector({0, 0, -dist});
  Quatd q{u(rng), u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5};
  double ql = std::sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z);
  q = {q.w / ql, q.x / ql, q.y / ql, q.z / ql};
  s.object_to_world = Mat4d::translate(s.cam.eye + ahead) * Mat4d::rotation(q) *
                      Mat4d::scale({scale, scale, scale});
  // Triangles in the object's frame: their size in pixels is about
  // edge / scale ... chosen from the frame's pixel size at that distance.
  double pixel = 2 * dist * std::tan(s.cam.fovy_deg * M_PI / 360) / s.height / scale;
  double spread = dist * 0.8 / scale;
  const int tris = 400;
  for (int t = 0; t < tris; ++t) {
    double cx = (u(rng) - 0.5) * spread, cy = (u(rng) - 0.5) * spread, cz = (u(rng) - 0.5) * spread;
    double size = pixel * std::pow(10.0, u(rng) * 2.2 - 1.7);  // 0.02 to 3 pixels
    for (int k = 0; k < 3; ++k) {
      s.positions.push_back(float(cx + (u(rng) - 0.5) * size));
      s.positions.push_back(float(cy + (u(rng) - 0.5) * size));
      s.positions.push_back(float(cz + (u(rng) - 0.5) * size));
      s.indices.push_back(uint32_t(3 * t + k));
    }
  }
  return s;
}

}  // namespace

TEST(Coverage, NoDroppedTriangleCoversAPixelCentreUnderAnyFloatArithmetic) {
  std::mt19937_64 rng(20261205);
  uint64_t dropped = 0, uncovered = 0, total = 0;
  const Arith ways[] = {{false, false, false},
                        {true, false, false},
                        {false, true, false},
                        {true, true, true},
                        {false, false, true}};
  for (int trial = 0; trial < 300; ++trial) {
    Scenario s = randomScenario(rng);
    Mat4d mv = objectToEye(s.cam, s.object_to_world), proj = projectionMatrix(s.cam);
    WindowVertices v;
    projectVertices(s.positions.data(), s.positions.size() / 3,
                    {mv, proj, s.width, s.height, s.bits}, &v);
    std::vector<uint32_t> kept(s.indices.size());
    size_t n = keepCoveringTriangles(s.indices.data(), s.indices.size(), v, s.scissor, kept.data());
    ASSERT_EQ(n % 3, 0u);
    std::vector<bool> is_kept(s.indices.size() / 3, false);
    for (size_t k = 0; k < n; k += 3) is_kept[kept[k] / 3] = true;  // vertex 3t is triangle t's
    for (size_t t = 0; t < is_kept.size(); ++t) {
      bool covers = false;
      for (const Arith& a : ways) {
        int64_t x[3], y[3];
        bool front = true;
        for (int k = 0; k < 3; ++k)
          front = front && gpuWindow(mv, proj, &s.positions[3 * s.indices[3 * t + k]], s.width,
                                     s.height, s.bits, a, &x[k], &y[k]);
        covers = covers || !front || coversCentre(x, y, s.bits, s.scissor);
      }
      ++total;
      uncovered += !covers;
      dropped += !is_kept[t];
      ASSERT_TRUE(is_kept[t] || !covers)
          << "trial " << trial << ": triangle " << t << " covers a pixel centre but was dropped";
    }
  }
  // Most triangles here cover no centre, and the culling finds nearly all.
  EXPECT_GT(uncovered, total / 3);
  // (98.9% with the centre-by-centre edge test, 90% with the box alone.)
  EXPECT_GE(double(dropped), 0.97 * double(uncovered)) << dropped << " of " << uncovered;
}

namespace {

// A 100x100 frame seen by a camera at the origin looking down -Z, 90
// degrees: a point (x, y, -1) lands at window ((x + 1) * 50, (y + 1) * 50).
WindowVertices project(const std::vector<float>& positions, int bits = 8) {
  Camera cam;
  cam.fovy_deg = 90;
  cam.near = 0.1;
  WindowVertices v;
  projectVertices(positions.data(), positions.size() / 3,
                  {objectToEye(cam, Mat4d::identity()), projectionMatrix(cam), 100, 100, bits}, &v);
  return v;
}
// The eye-space point at window (wx, wy), depth 1.
std::vector<float> at(double wx, double wy) {
  return {float(wx / 50 - 1), float(wy / 50 - 1), -1.f};
}
std::vector<float> triangle(std::vector<float> a, const std::vector<float>& b,
                            const std::vector<float>& c) {
  a.insert(a.end(), b.begin(), b.end());
  a.insert(a.end(), c.begin(), c.end());
  return a;
}
// Triangles kept, by keepCoveringTriangles; where the CPU has AVX2, the
// same list repeated eight times (one batch of the AVX2 path, which a short
// list never reaches) must keep eight times as many.
size_t keptOf(const std::vector<float>& positions, Rect scissor = {0, 0, 100, 100},
              std::vector<uint32_t> indices = {0, 1, 2}) {
  WindowVertices v = project(positions);
  std::vector<uint32_t> out(indices.size());
  const size_t kept = keepCoveringTriangles(indices.data(), indices.size(), v, scissor, out.data());
  if (detail::haveAvx2()) {
    std::vector<uint32_t> eight, out8(8 * indices.size());
    for (int k = 0; k < 8; ++k) eight.insert(eight.end(), indices.begin(), indices.end());
    EXPECT_EQ(
        detail::keepCoveringTrianglesAvx2(eight.data(), eight.size(), v, scissor, out8.data()),
        8 * kept);
  }
  return kept / 3;
}

}  // namespace

TEST(Coverage, DropsATinyTriangleBetweenPixelCentres) {
  EXPECT_EQ(keptOf(triangle(at(10.1, 10.1), at(10.3, 10.1), at(10.1, 10.4))), 0u);
}

TEST(Coverage, KeepsATriangleReachingAPixelCentre) {
  EXPECT_EQ(keptOf(triangle(at(10.1, 10.1), at(10.95, 10.1), at(10.1, 10.95))), 1u);
  // A vertex just short of the centre (10.5, 10.5): within the error radius,
  // kept.
  EXPECT_EQ(keptOf(triangle(at(10.499, 10.499), at(10.1, 10.3), at(10.3, 10.1))), 1u);
}

TEST(Coverage, KeepsATriangleWhoseEdgeMissesACentreByLessThanTheErrorRadius) {
  // The left edge, x = 10.501, passes 0.001 pixels right of (10.5, 10.5);
  // either winding.
  EXPECT_EQ(keptOf(triangle(at(10.501, 9.9), at(10.501, 11.1), at(10.9, 10.5))), 1u);
  EXPECT_EQ(keptOf(triangle(at(10.501, 9.9), at(10.9, 10.5), at(10.501, 11.1))), 1u);
}

TEST(Coverage, DropsATriangleWhoseBoxButNotItselfHoldsACentre) {
  // The box reaches (10.5, 10.5); the hypotenuse passes 0.28 pixels short.
  EXPECT_EQ(keptOf(triangle(at(10.1, 10.1), at(10.499, 10.1), at(10.1, 10.499))), 0u);
  // The centre lies 0.07 pixels outside the edge y = x - 0.1, either winding.
  EXPECT_EQ(keptOf(triangle(at(10.3, 10.2), at(10.9, 10.2), at(10.9, 10.8))), 0u);
  EXPECT_EQ(keptOf(triangle(at(10.3, 10.2), at(10.9, 10.8), at(10.9, 10.2))), 0u);
  // A box of more than kExactCentres centres is kept on the box test: this
  // sliver's box holds 3 x 3 centres, and it passes 0.07 pixels or more
  // from each of the three on its diagonal.
  EXPECT_EQ(keptOf(triangle(at(10.1, 10.0), at(12.9, 12.8), at(12.9, 12.85))), 1u);
}

TEST(Coverage, DropsATriangleOutsideTheScissor) {
  auto big = triangle(at(10, 10), at(30, 10), at(10, 30));
  EXPECT_EQ(keptOf(big, {0, 0, 100, 100}), 1u);
  EXPECT_EQ(keptOf(big, {40, 0, 60, 100}), 0u);
  EXPECT_EQ(keptOf(big, {20, 20, 60, 60}), 1u);  // the box meets it, the triangle does not: kept
}

TEST(Coverage, DropsEverythingForAnEmptyScissor) {
  EXPECT_EQ(keptOf(triangle(at(10, 10), at(30, 10), at(10, 30)), {5, 5, 0, 10}), 0u);
}

TEST(Coverage, KeepsATriangleWithAVertexBehindTheEye) {
  // Projected, the vertex behind the eye would put the box anywhere.
  EXPECT_EQ(keptOf(triangle(at(10.1, 10.1), at(10.3, 10.1), {0.f, 0.f, 1.f})), 1u);
  EXPECT_EQ(keptOf(triangle(at(10.1, 10.1), at(10.3, 10.1), {0.f, 0.f, 0.f})), 1u);
}

TEST(Coverage, KeepsATriangleWithAnIndexPastTheVertices) {
  EXPECT_EQ(
      keptOf(triangle(at(10.1, 10.1), at(10.3, 10.1), at(10.1, 10.4)), {0, 0, 100, 100}, {0, 1, 3}),
      1u);
}

TEST(Coverage, KeepsATriangleWithANonFinitePosition) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  EXPECT_EQ(keptOf(triangle(at(10.1, 10.1), at(10.3, 10.1), {nan, 0.f, -1.f})), 1u);
  EXPECT_EQ(keptOf(triangle(at(10.1, 10.1), at(10.3, 10.1), {inf, 0.f, -1.f})), 1u);
}

TEST(Coverage, KeepsTheOrderOfTheTrianglesKept) {
  auto a = triangle(at(10, 10), at(30, 10), at(10, 30));
  auto tiny = triangle(at(50.1, 50.1), at(50.3, 50.1), at(50.1, 50.3));
  auto b = triangle(at(60, 60), at(80, 60), at(60, 80));
  std::vector<float> all = a;
  all.insert(all.end(), tiny.begin(), tiny.end());
  all.insert(all.end(), b.begin(), b.end());
  WindowVertices v = project(all);
  std::vector<uint32_t> in = {6, 7, 8, 3, 4, 5, 0, 1, 2}, out(9);
  ASSERT_EQ(keepCoveringTriangles(in.data(), in.size(), v, {0, 0, 100, 100}, out.data()), 6u);
  EXPECT_EQ(std::vector<uint32_t>(out.begin(), out.begin() + 6),
            (std::vector<uint32_t>{6, 7, 8, 0, 1, 2}));
}

TEST(Coverage, AFewerSubPixelBitsWidenTheRadius) {
  auto v8 = project(at(10.2, 10.2), 8), v4 = project(at(10.2, 10.2), 4);
  EXPECT_GT(v4[0].radius, v8[0].radius);
  EXPECT_GE(v4[0].radius, 1.0 / 16);
  EXPECT_LT(v8[0].radius, 1.0 / 64);
}

namespace {

// Window vertices as projectVertices makes them, chosen to meet the
// arithmetic's edges: positions on and a rounding step off half-integers
// (pixel centres) and integers, tiny and large radii, +inf radii (a vertex
// not safely in front), and positions up to 2^21 pixels from the origin.
WindowVertices hardVertices(std::mt19937_64& rng, size_t n) {
  std::uniform_real_distribution<double> u(0, 1);
  const float inf = std::numeric_limits<float>::infinity();
  WindowVertices v(n);
  double ox = 0, oy = 0;
  for (size_t i = 0; i < n; ++i) {
    if (i % 64 == 0) {  // clusters, each around its own spot
      const double far = std::pow(2.0, u(rng) * 21);
      ox = std::floor((u(rng) - 0.5) * far), oy = std::floor((u(rng) - 0.5) * far);
    }
    auto coord = [&](double o) {
      double c = o + std::floor(u(rng) * 6);
      const double kind = u(rng);
      if (kind < 0.3)
        c += 0.5;  // on a centre
      else if (kind < 0.5)
        c = std::nextafter(float(c + 0.5), inf);  // a float step off it
      else if (kind < 0.6)
        c = std::nextafter(float(c + 0.5), -inf);
      else
        c += u(rng);
      return float(c);
    };
    const double kind = u(rng);
    const float radius = kind < 0.03  ? inf
                         : kind < 0.5 ? float(std::ldexp(1.0, -int(4 + u(rng) * 20)))
                                      : float(u(rng) * 0.6);
    v[i] = radius == inf ? WindowVertex{0.f, 0.f, inf, 0.f}
                         : WindowVertex{coord(ox), coord(oy), radius, 0.f};
  }
  return v;
}

}  // namespace

TEST(Coverage, TheAvx2PathKeepsExactlyWhatTheScalarLoopKeeps) {
  if (!detail::haveAvx2()) GTEST_SKIP() << "this CPU has no AVX2";
  std::mt19937_64 rng(20261206);
  std::uniform_real_distribution<double> u(0, 1);
  size_t kept_total = 0, total = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const size_t n = 1 + size_t(u(rng) * 300);
    WindowVertices v = hardVertices(rng, n);
    // Triangles of nearby vertices (as in a mesh), some with an index past
    // the vertices, some past 2^31; a count that is no multiple of 24.
    const size_t tris = size_t(u(rng) * 200);
    std::vector<uint32_t> indices;
    for (size_t t = 0; t < tris; ++t) {
      const size_t first = size_t(u(rng) * double(n));
      for (int k = 0; k < 3; ++k) {
        uint32_t i = uint32_t(std::min(n - 1, first + size_t(u(rng) * 3)));
        const double odd = u(rng);
        if (odd < 0.01)
          i = uint32_t(n + size_t(u(rng) * 3));
        else if (odd < 0.015)
          i = 0x80000000u + uint32_t(u(rng) * 5);
        indices.push_back(i);
      }
    }
    // Scissors near a cluster's spot (an infinite-radius vertex sits at
    // the origin), some a single pixel or empty.
    const WindowVertex& spot = v[size_t(u(rng) * double(n))];
    const Rect scissor{int(std::floor(double(spot.x))) - int(u(rng) * 4),
                       int(std::floor(double(spot.y))) - int(u(rng) * 4), int(u(rng) * 9),
                       int(u(rng) * 9)};
    std::vector<uint32_t> a(indices.size() + 1, 7u), b(indices.size() + 1, 7u);
    const size_t na =
        detail::keepCoveringTrianglesScalar(indices.data(), indices.size(), v, scissor, a.data());
    const size_t nb =
        detail::keepCoveringTrianglesAvx2(indices.data(), indices.size(), v, scissor, b.data());
    ASSERT_EQ(na, nb) << "trial " << trial;
    ASSERT_EQ(a, b) << "trial " << trial;  // the same triangles, and nothing written past them
    kept_total += na / 3;
    total += tris;
  }
  // Not vacuous: both some kept and some dropped.
  EXPECT_GT(kept_total, total / 20) << kept_total << " of " << total;
  EXPECT_LT(kept_total, total - total / 20) << kept_total << " of " << total;
}

namespace {

// Whether the AVX2 path keeps the triangle (0, 1, 2) of `v`, given eight
// times in one batch: all or none of the copies, or the test fails.
bool avx2Keeps(const WindowVertices& v, Rect scissor) {
  std::vector<uint32_t> eight, out(24);
  for (int k = 0; k < 8; ++k) eight.insert(eight.end(), {0, 1, 2});
  const size_t kept = detail::keepCoveringTrianglesAvx2(eight.data(), 24, v, scissor, out.data());
  EXPECT_TRUE(kept == 0 || kept == 24) << kept;
  return kept == 24;
}
bool scalarKeeps(const WindowVertices& v, Rect scissor) {
  const uint32_t tri[3] = {0, 1, 2};
  uint32_t out[3];
  return detail::keepCoveringTrianglesScalar(tri, 3, v, scissor, out) == 3;
}

}  // namespace

// Where the decision flips as the error radius grows float by float (the
// edge test's slack, the box's reach past a centre, the floor's rounding
// just above a half-integer), both paths flip at the same float.
TEST(Coverage, TheAvx2PathFlipsAtTheSameRadiusAsTheScalarLoop) {
  if (!detail::haveAvx2()) GTEST_SKIP() << "this CPU has no AVX2";
  std::mt19937_64 rng(1206);
  std::uniform_real_distribution<double> u(0, 1);
  int flips = 0;
  for (int trial = 0; trial < 300; ++trial) {
    // A triangle within a few pixels of the centre (0.5, 0.5) or, with a
    // 2x2 scissor, of four centres; its corners on a 2^-24 grid near them.
    const Rect scissor = trial % 3 == 0 ? Rect{0, 0, 2, 2} : Rect{0, 0, 1, 1};
    WindowVertices v(3);
    for (auto& w : v) {
      const double spread = u(rng) < 0.5 ? 1e-6 : 3;
      w.x = float(0.5 + std::ldexp(std::round((u(rng) - 0.5) * spread * 0x1p24), -24));
      w.y = float(0.5 + std::ldexp(std::round((u(rng) - 0.5) * spread * 0x1p24), -24));
    }
    auto keeps = [&](uint32_t bits, bool avx2) {
      for (auto& w : v) w.radius = std::bit_cast<float>(bits);
      return avx2 ? avx2Keeps(v, scissor) : scalarKeeps(v, scissor);
    };
    // The smallest radius the scalar loop keeps, between 2^-40 and 4.
    uint32_t lo = std::bit_cast<uint32_t>(0x1p-40f), hi = std::bit_cast<uint32_t>(4.f);
    if (keeps(lo, false) || !keeps(hi, false)) continue;
    while (hi - lo > 1) {
      const uint32_t mid = lo + (hi - lo) / 2;
      (keeps(mid, false) ? hi : lo) = mid;
    }
    ++flips;
    for (uint32_t b = hi - 40; b <= hi + 40; ++b)
      ASSERT_EQ(keeps(b, true), keeps(b, false))
          << "trial " << trial << ", radius " << std::bit_cast<float>(b) << " (flip at "
          << std::bit_cast<float>(hi) << ")";
  }
  EXPECT_GT(flips, 150);
}

// The AVX2 projection gives the portable loop's window vertices bit for bit,
// on random scenes (far from the origin, scaled, rotated) mixed with
// vertices behind, at and barely in front of the eye, and non-finite ones.
TEST(Coverage, TheAvx2ProjectionEqualsThePortableOneBitForBit) {
  if (!detail::haveAvx2()) GTEST_SKIP() << "this CPU has no AVX2";
  std::mt19937_64 rng(61206);
  std::uniform_real_distribution<double> u(0, 1);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  size_t apart = 0, total = 0;
  for (int trial = 0; trial < 200; ++trial) {
    Scenario s = randomScenario(rng);
    Mat4d mv = objectToEye(s.cam, s.object_to_world), proj = projectionMatrix(s.cam);
    // Odd vertices in the object's frame: the eye itself, points near the
    // eye plane, far behind, and non-finite coordinates.
    Mat4d to_object;
    ASSERT_TRUE(invertAffine(mv, &to_object));
    auto eye_point = [&](double x, double y, double z) {
      const Vec3d p = to_object.transformPoint({x, y, z});
      s.positions.insert(s.positions.end(), {float(p.x), float(p.y), float(p.z)});
    };
    for (int k = 0; k < 20; ++k) {
      const double z = std::ldexp(u(rng) - 0.5, -int(u(rng) * 30));
      eye_point((u(rng) - 0.5) * 10, (u(rng) - 0.5) * 10, z);
    }
    eye_point(0, 0, 0);
    s.positions.insert(s.positions.end(), {nan, 0.f, 0.f, inf, 1.f, 1.f, 0.f, -inf, 2.f});
    const size_t count = s.positions.size() / 3 - size_t(u(rng) * 4);  // no multiple of 4
    const WindowTransform t{mv, proj, s.width, s.height, s.bits};
    WindowVertices a, b;
    detail::projectVerticesScalar(s.positions.data(), count, t, &a);
    detail::projectVerticesAvx2(s.positions.data(), count, t, &b);
    ASSERT_EQ(a.size(), b.size());
    ASSERT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(WindowVertex)), 0)
        << "trial " << trial;
    for (const WindowVertex& w : a) apart += w.radius == inf;
    total += count;
  }
  // Both kinds of vertex were compared.
  EXPECT_GT(apart, 200u);
  EXPECT_LT(apart, total / 4);
}
