// Exact triangle culling (common/coverage.h): a dropped triangle must cover
// no pixel centre however a GPU's float arithmetic places it. The property
// test rasterises every triangle the way a GL driver may (float transforms
// in two summation orders, with and without FMA, vertices snapped by
// rounding or by truncation) and checks that none the culling dropped
// covers a centre, on fixed-seed random scenes with scales, rotations and
// positions far from the origin; and that the culling drops most of what
// it may, so that it is not vacuously safe.
#include <gtest/gtest.h>

#include <cmath>
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
size_t keptOf(const std::vector<float>& positions, Rect scissor = {0, 0, 100, 100},
              std::vector<uint32_t> indices = {0, 1, 2}) {
  WindowVertices v = project(positions);
  std::vector<uint32_t> out(indices.size());
  return keepCoveringTriangles(indices.data(), indices.size(), v, scissor, out.data()) / 3;
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
