// Tests for the value types (common/math.h) and the shared camera
// (common/camera.h). Expected values are worked out by hand or computed by
// independent reference code in this file.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "camera.h"
#include "math.h"

namespace dmmr {
namespace {

// Builds a matrix from rows as written on paper.
Mat4d rows(std::initializer_list<std::initializer_list<double>> r) {
  Mat4d m;
  int i = 0;
  for (const auto& row : r) {
    int j = 0;
    for (double v : row) m.at(i, j++) = v;
    ++i;
  }
  return m;
}

void expectMatNear(const Mat4d& a, const Mat4d& b, double tol) {
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c)
      EXPECT_NEAR(a.at(r, c), b.at(r, c), tol) << "at (" << r << "," << c << ")\n"
                                               << a << "\n"
                                               << b;
}

Quatd randomUnitQuat(std::mt19937& rng) {
  std::normal_distribution<double> n(0, 1);
  Quatd q{n(rng), n(rng), n(rng), n(rng)};
  double len = std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
  return {q.x / len, q.y / len, q.z / len, q.w / len};
}

Quatd axisAngle(Vec3d axis, double deg) {
  axis = normalize(axis);
  double h = deg * M_PI / 360.0;
  return {axis.x * std::sin(h), axis.y * std::sin(h), axis.z * std::sin(h), std::cos(h)};
}

// A random affine matrix with a well-conditioned linear part.
Mat4d randomAffine(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-2, 2), t(-100, 100);
  Mat4d m = Mat4d::identity();
  for (;;) {
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) m.at(r, c) = u(rng);
    double det = m.at(0, 0) * (m.at(1, 1) * m.at(2, 2) - m.at(1, 2) * m.at(2, 1)) -
                 m.at(0, 1) * (m.at(1, 0) * m.at(2, 2) - m.at(1, 2) * m.at(2, 0)) +
                 m.at(0, 2) * (m.at(1, 0) * m.at(2, 1) - m.at(1, 1) * m.at(2, 0));
    if (std::fabs(det) > 0.1) break;
  }
  for (int r = 0; r < 3; ++r) m.at(r, 3) = t(rng);
  return m;
}

// Reference product straight from the definition (AB)_rc = sum_k A_rk B_kc.
Mat4d referenceProduct(const Mat4d& a, const Mat4d& b) {
  Mat4d r;
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) {
      long double s = 0;
      for (int k = 0; k < 4; ++k) s += (long double)a.at(i, k) * b.at(k, j);
      r.at(i, j) = double(s);
    }
  return r;
}

// ---- vectors and quaternions ------------------------------------------------------

TEST(VecTest, Basics) {
  Vec3d a{1, 2, 3}, b{-4, 5, 0.5};
  EXPECT_EQ(a + b, (Vec3d{-3, 7, 3.5}));
  EXPECT_EQ(a - b, (Vec3d{5, -3, 2.5}));
  EXPECT_EQ(dot(a, b), -4 + 10 + 1.5);
  EXPECT_EQ(cross(Vec3d{1, 0, 0}, Vec3d{0, 1, 0}), (Vec3d{0, 0, 1}));
  EXPECT_EQ(cross(a, b), (Vec3d{2 * 0.5 - 3 * 5, 3 * -4 - 1 * 0.5, 1 * 5 - 2 * -4}));
  EXPECT_EQ(length(Vec3d{3, 4, 12}), 13);
  EXPECT_FALSE(isFinite(Vec3d{0, std::numeric_limits<double>::infinity(), 0}));
}

TEST(QuatTest, RotateByKnownAngles) {
  Quatd z90 = axisAngle({0, 0, 1}, 90);
  Vec3d v = rotate(z90, {1, 0, 0});
  EXPECT_NEAR(v.x, 0, 1e-15);
  EXPECT_NEAR(v.y, 1, 1e-15);
  EXPECT_NEAR(v.z, 0, 1e-15);
  Quatd x180{1, 0, 0, 0};
  EXPECT_EQ(rotate(x180, {1, 2, 3}), (Vec3d{1, -2, -3}));
  // 120 degrees about (1,1,1) permutes the axes: x -> y -> z -> x.
  Quatd perm{0.5, 0.5, 0.5, 0.5};
  EXPECT_EQ(rotate(perm, {1, 0, 0}), (Vec3d{0, 1, 0}));
  EXPECT_EQ(rotate(perm, {0, 1, 0}), (Vec3d{0, 0, 1}));
  EXPECT_EQ(rotate(Quatd{}, {4, 5, 6}), (Vec3d{4, 5, 6}));
}

TEST(QuatTest, RotationMatrixMatchesRotate) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-10, 10);
  for (int i = 0; i < 200; ++i) {
    Quatd q = randomUnitQuat(rng);
    Mat4d m = Mat4d::rotation(q);
    Vec3d v{u(rng), u(rng), u(rng)};
    Vec3d a = m.transformVector(v), b = rotate(q, v);
    EXPECT_NEAR(length(a - b), 0, 1e-13);
    EXPECT_NEAR(length(a), length(v), 1e-12);  // rotations preserve length
    EXPECT_EQ(m.at(3, 3), 1);
    EXPECT_EQ(m.at(3, 0), 0);
    EXPECT_EQ(m.at(0, 3), 0);
  }
}

// ---- Mat4d --------------------------------------------------------------------------

TEST(Mat4Test, ConstructorsPlaceEntries) {
  EXPECT_EQ(Mat4d::translate({1, 2, 3}),
            rows({{1, 0, 0, 1}, {0, 1, 0, 2}, {0, 0, 1, 3}, {0, 0, 0, 1}}));
  EXPECT_EQ(Mat4d::scale({2, 3, 4}),
            rows({{2, 0, 0, 0}, {0, 3, 0, 0}, {0, 0, 4, 0}, {0, 0, 0, 1}}));
  // OSG stores row vectors: translation in elements 12..14.
  double osg[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 7, 8, 9, 1};
  EXPECT_EQ(Mat4d::fromOsgPtr(osg), Mat4d::translate({7, 8, 9}));
}

TEST(Mat4Test, MultiplyHandComputed) {
  Mat4d t = Mat4d::translate({1, 2, 3}), s = Mat4d::scale({2, 3, 4});
  EXPECT_EQ(t * s, rows({{2, 0, 0, 1}, {0, 3, 0, 2}, {0, 0, 4, 3}, {0, 0, 0, 1}}));
  EXPECT_EQ(s * t, rows({{2, 0, 0, 2}, {0, 3, 0, 6}, {0, 0, 4, 12}, {0, 0, 0, 1}}));
  Mat4d a = rows({{1, 2, 3, 4}, {5, 6, 7, 8}, {9, 10, 11, 12}, {13, 14, 15, 16}});
  Mat4d b = rows({{1, 0, 0, 0}, {1, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}});
  // a*b adds column 1 of a to column 0; b*a adds row 0 of a to row 1.
  EXPECT_EQ(a * b, rows({{3, 2, 3, 4}, {11, 6, 7, 8}, {19, 10, 11, 12}, {27, 14, 15, 16}}));
  EXPECT_EQ(b * a, rows({{1, 2, 3, 4}, {6, 8, 10, 12}, {9, 10, 11, 12}, {13, 14, 15, 16}}));
  EXPECT_EQ(a * Mat4d::identity(), a);
  EXPECT_EQ(Mat4d::identity() * a, a);
  // Row i of a times column j of a^T.
  Mat4d at = rows({{1, 5, 9, 13}, {2, 6, 10, 14}, {3, 7, 11, 15}, {4, 8, 12, 16}});
  EXPECT_EQ(
      a * at,
      rows({{30, 70, 110, 150}, {70, 174, 278, 382}, {110, 278, 446, 614}, {150, 382, 614, 846}}));
}

TEST(Mat4Test, MultiplyMatchesReferenceOnRandomMatrices) {
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> u(-5, 5);
  for (int n = 0; n < 100; ++n) {
    Mat4d a, b;
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) a.at(r, c) = u(rng), b.at(r, c) = u(rng);
    expectMatNear(a * b, referenceProduct(a, b), 1e-13);
  }
}

TEST(Mat4Test, TransformPointAndVector) {
  Mat4d m = rows({{0, -1, 0, 10}, {1, 0, 0, 20}, {0, 0, 2, 30}, {0, 0, 0, 1}});
  EXPECT_EQ(m.transformPoint({1, 2, 3}), (Vec3d{8, 21, 36}));
  EXPECT_EQ(m.transformVector({1, 2, 3}), (Vec3d{-2, 1, 6}));
  std::mt19937 rng(3);
  for (int i = 0; i < 50; ++i) {
    Mat4d a = randomAffine(rng), b = randomAffine(rng);
    Vec3d p{1.5, -2, 7};
    EXPECT_NEAR(length((a * b).transformPoint(p) - a.transformPoint(b.transformPoint(p))), 0,
                1e-10);
  }
}

TEST(Mat4Test, InvertAffineHandComputed) {
  Mat4d inv;
  ASSERT_TRUE(invertAffine(Mat4d::translate({1, 2, 3}), &inv));
  EXPECT_EQ(inv, Mat4d::translate({-1, -2, -3}));
  ASSERT_TRUE(invertAffine(Mat4d::scale({2, 4, 8}), &inv));
  EXPECT_EQ(inv, Mat4d::scale({0.5, 0.25, 0.125}));
  // Shear x += 2y, then translate by (1, 0, 0): inverse x = x' - 1 - 2y'.
  Mat4d shear = rows({{1, 2, 0, 1}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}});
  ASSERT_TRUE(invertAffine(shear, &inv));
  EXPECT_EQ(inv, rows({{1, -2, 0, -1}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}}));
  // A permutation with scale and translation: x' = 2z + 5, y' = x, z' = -y.
  Mat4d perm = rows({{0, 0, 2, 5}, {1, 0, 0, 0}, {0, -1, 0, 0}, {0, 0, 0, 1}});
  ASSERT_TRUE(invertAffine(perm, &inv));
  EXPECT_EQ(inv, rows({{0, 1, 0, 0}, {0, 0, -1, 0}, {0.5, 0, 0, -2.5}, {0, 0, 0, 1}}));
}

TEST(Mat4Test, InvertAffineRejectsSingular) {
  Mat4d inv = Mat4d::identity();
  EXPECT_FALSE(invertAffine(Mat4d::scale({1, 0, 1}), &inv));
  EXPECT_FALSE(invertAffine(rows({{1, 2, 3, 0}, {2, 4, 6, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}}), &inv));
  Mat4d nan = Mat4d::identity();
  nan.at(1, 1) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(invertAffine(nan, &inv));
}

TEST(Mat4Test, InvertAffineRandomProducesIdentity) {
  std::mt19937 rng(4);
  for (int i = 0; i < 500; ++i) {
    Mat4d a = randomAffine(rng), inv;
    ASSERT_TRUE(invertAffine(a, &inv));
    expectMatNear(a * inv, Mat4d::identity(), 1e-9);
    expectMatNear(inv * a, Mat4d::identity(), 1e-9);
    EXPECT_EQ(inv.at(3, 0), 0);
    EXPECT_EQ(inv.at(3, 3), 1);
  }
}

// ---- maxScale -------------------------------------------------------------------------

// Numerical max of |Av| over unit v: a dense Fibonacci sphere, then power
// iteration on A^T A from the best sample, polished in long double. Returns
// the largest |Av| seen; every sample must be <= maxScale.
double sampledMaxStretch(const Mat4d& m, double bound) {
  auto stretch = [&](Vec3d v) { return length(m.transformVector(normalize(v))); };
  double best = 0;
  Vec3d bestV{1, 0, 0};
  const int n = 20000;
  const double golden = M_PI * (3 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {
    double y = 1 - 2 * (i + 0.5) / n, r = std::sqrt(1 - y * y);
    Vec3d v{r * std::cos(golden * i), y, r * std::sin(golden * i)};
    double s = stretch(v);
    EXPECT_LE(s, bound) << "v " << v;
    if (s > best) best = s, bestV = v;
  }
  Vec3d v = bestV;
  for (int it = 0; it < 2000; ++it) {
    Vec3d w = m.transformVector(v);
    Vec3d atw{m.at(0, 0) * w.x + m.at(1, 0) * w.y + m.at(2, 0) * w.z,
              m.at(0, 1) * w.x + m.at(1, 1) * w.y + m.at(2, 1) * w.z,
              m.at(0, 2) * w.x + m.at(1, 2) * w.y + m.at(2, 2) * w.z};
    if (length(atw) == 0) break;
    v = normalize(atw);
    double s = stretch(v);
    EXPECT_LE(s, bound) << "v " << v;
    best = std::max(best, s);
  }
  return best;
}

TEST(MaxScaleTest, RotationTimesScaleIsLargestFactor) {
  std::mt19937 rng(5);
  for (int i = 0; i < 200; ++i) {
    Quatd q = randomUnitQuat(rng);
    Mat4d m = Mat4d::translate({3, -4, 5}) * Mat4d::rotation(q) * Mat4d::scale({2, 3, 5});
    double s = m.maxScale();
    EXPECT_GE(s, 5 * (1 - 1e-15)) << q;
    EXPECT_LE(s, 5 * (1 + 1e-6)) << q;
    Mat4d left = Mat4d::scale({-5, 3, 2}) * Mat4d::rotation(q);  // reflection too
    EXPECT_NEAR(left.maxScale(), 5, 5e-6);
    EXPECT_GE(left.maxScale(), 5 * (1 - 1e-15));
  }
}

TEST(MaxScaleTest, DiagonalAndUniformCases) {
  EXPECT_NEAR(Mat4d::identity().maxScale(), 1, 1e-6);
  EXPECT_GE(Mat4d::identity().maxScale(), 1);
  EXPECT_GE(Mat4d::scale({7, 7, 7}).maxScale(), 7);
  EXPECT_NEAR(Mat4d::scale({7, 7, 7}).maxScale(), 7, 7e-6);
  EXPECT_GE(Mat4d::scale({-9, 1, 2}).maxScale(), 9);
  EXPECT_NEAR(Mat4d::scale({-9, 1, 2}).maxScale(), 9, 9e-6);
  EXPECT_GE(Mat4d::scale({1e-3, 2e-3, 0}).maxScale(), 2e-3);
  EXPECT_NEAR(Mat4d::scale({1e-3, 2e-3, 0}).maxScale(), 2e-3, 2e-9);
  Mat4d zero;
  EXPECT_EQ(zero.maxScale(), 0);
}

TEST(MaxScaleTest, ShearMatchesSampledMaximum) {
  // x += k y: singular values sqrt((k^2 + 2 +- k sqrt(k^2 + 4)) / 2), 1.
  for (double k : {0.5, 1.0, 3.0, 10.0}) {
    Mat4d shear = rows({{1, k, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}});
    double s = shear.maxScale();
    double exact = std::sqrt((k * k + 2 + k * std::sqrt(k * k + 4)) / 2);
    EXPECT_NEAR(s, exact, exact * 1e-6) << k;
    double sampled = sampledMaxStretch(shear, s);
    EXPECT_LE(std::fabs(s - sampled), 1e-6 * sampled) << "k " << k;
  }
}

TEST(MaxScaleTest, RandomMatricesMatchSampledMaximum) {
  std::mt19937 rng(6);
  std::uniform_real_distribution<double> u(-3, 3);
  for (int i = 0; i < 60; ++i) {
    Mat4d m = Mat4d::identity();
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) m.at(r, c) = u(rng);
    double s = m.maxScale();
    double sampled = sampledMaxStretch(m, s);
    EXPECT_LE(std::fabs(s - sampled), 1e-6 * sampled) << m;
  }
}

// Largest singular value of the 3x3 part by cyclic Jacobi on A^T A in long
// double: an independent reference accurate far beyond double precision.
long double referenceSpectralNorm(const Mat4d& m) {
  long double a[3][3];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      a[i][j] = 0;
      for (int k = 0; k < 3; ++k) a[i][j] += (long double)m.at(k, i) * m.at(k, j);
    }
  for (int sweep = 0; sweep < 60; ++sweep) {
    long double off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
    long double diag = a[0][0] * a[0][0] + a[1][1] * a[1][1] + a[2][2] * a[2][2];
    if (off <= diag * 1e-40L) break;
    for (int p = 0; p < 2; ++p)
      for (int q = p + 1; q < 3; ++q) {
        if (a[p][q] == 0) continue;
        long double theta = (a[q][q] - a[p][p]) / (2 * a[p][q]);
        long double t = (theta >= 0 ? 1 : -1) / (fabsl(theta) + sqrtl(theta * theta + 1));
        long double c = 1 / sqrtl(t * t + 1), sn = t * c;
        for (int k = 0; k < 3; ++k) {  // columns p, q
          long double kp = a[k][p], kq = a[k][q];
          a[k][p] = c * kp - sn * kq;
          a[k][q] = sn * kp + c * kq;
        }
        for (int k = 0; k < 3; ++k) {  // rows p, q
          long double pk = a[p][k], qk = a[q][k];
          a[p][k] = c * pk - sn * qk;
          a[q][k] = sn * pk + c * qk;
        }
      }
  }
  return sqrtl(std::max({a[0][0], a[1][1], a[2][2], 0.0L}));
}

TEST(MaxScaleTest, ReferenceSpectralNormIsAccurate) {
  std::mt19937 rng(70);
  for (int i = 0; i < 100; ++i) {
    Mat4d m = Mat4d::rotation(randomUnitQuat(rng)) * Mat4d::scale({2, 3, 5 + i * 0.01}) *
              Mat4d::rotation(randomUnitQuat(rng));
    EXPECT_NEAR(double(referenceSpectralNorm(m)), 5 + i * 0.01, 1e-13);
  }
}

// Regression: with the two largest singular values within ~1e-8 of each
// other, the closed-form eigenvalue lost precision in acos near -1 and came
// out up to ~4e-9 (relative) too small, more than the 1e-9 it was rounded up
// by, so maxScale fell below the spectral norm.
TEST(MaxScaleTest, NeverBelowSpectralNormWhenLargestSingularValuesNearlyCoincide) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(1, 10);
  for (int decade = -14; decade <= -2; ++decade) {
    for (int i = 0; i < 3000; ++i) {
      double e = std::pow(10.0, decade) * u(rng);
      double third = (i % 4) * 1.5;
      Mat4d m = Mat4d::rotation(randomUnitQuat(rng)) * Mat4d::scale({5, 5 * (1 - e), third}) *
                Mat4d::rotation(randomUnitQuat(rng));
      long double ref = referenceSpectralNorm(m);
      double s = m.maxScale();
      ASSERT_GE((long double)s, ref * (1 - 1e-15L))
          << "separation " << e << " third " << third << " short by " << double((ref - s) / ref);
      ASSERT_LE(s, 5 * (1 + 1e-6));
    }
  }
}

TEST(MaxScaleTest, NeverBelowSpectralNormOnRandomMatrices) {
  std::mt19937 rng(71);
  std::uniform_real_distribution<double> u(-3, 3);
  for (int i = 0; i < 20000; ++i) {
    Mat4d m;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) m.at(r, c) = u(rng) * std::pow(10.0, (i % 9) - 4);
    long double ref = referenceSpectralNorm(m);
    double s = m.maxScale();
    ASSERT_GE((long double)s, ref * (1 - 1e-15L)) << m;
    ASSERT_LE((long double)s, ref * (1 + 1e-6L)) << m;
  }
}

// ---- boxes --------------------------------------------------------------------------

TEST(BoxTest, ExpandAndQueries) {
  Box3d b;
  EXPECT_FALSE(b.valid());
  EXPECT_EQ(b.volume(), 0);
  b.expand(Vec3d{1, 2, 3});
  EXPECT_TRUE(b.valid());
  b.expand(Vec3d{-1, 4, 3});
  EXPECT_EQ(b.lo, (Vec3d{-1, 2, 3}));
  EXPECT_EQ(b.hi, (Vec3d{1, 4, 3}));
  EXPECT_EQ(b.volume(), 0);
  b.expand(Box3d{});  // an empty box changes nothing
  EXPECT_EQ(b.hi, (Vec3d{1, 4, 3}));
  b.expand(Box3d{{0, 0, 0}, {0, 0, 10}});
  EXPECT_EQ(b.volume(), 2 * 4 * 10);
  EXPECT_EQ(b.center(), (Vec3d{0, 2, 5}));
  EXPECT_EQ(b.corner(0), b.lo);
  EXPECT_EQ(b.corner(7), b.hi);
  EXPECT_EQ(b.corner(5), (Vec3d{1, 0, 10}));
}

TEST(BoxTest, TransformBoxEnclosesTransformedCornersTightly) {
  std::mt19937 rng(8);
  std::uniform_real_distribution<double> u(-50, 50), e(0, 20), f(0, 1);
  for (int i = 0; i < 300; ++i) {
    Mat4d m = randomAffine(rng);
    Box3d b;
    b.lo = {u(rng), u(rng), u(rng)};
    b.hi = b.lo + Vec3d{e(rng), e(rng), e(rng)};
    if (i % 10 == 0) b.hi = b.lo;  // a point
    Box3d t = transformBox(m, b);
    ASSERT_TRUE(t.valid());
    Vec3d lo{1e300, 1e300, 1e300}, hi = -lo;
    for (int c = 0; c < 8; ++c) {
      Vec3d p = m.transformPoint(b.corner(c));
      lo = vmin(lo, p), hi = vmax(hi, p);
    }
    EXPECT_EQ(t.lo, lo);
    EXPECT_EQ(t.hi, hi);
    // Points inside the box map inside the transformed box.
    for (int k = 0; k < 20; ++k) {
      Vec3d p = b.lo + Vec3d{f(rng) * (b.hi.x - b.lo.x), f(rng) * (b.hi.y - b.lo.y),
                             f(rng) * (b.hi.z - b.lo.z)};
      Vec3d q = m.transformPoint(p);
      for (int a = 0; a < 3; ++a) {
        EXPECT_GE(q[a], t.lo[a] - 1e-9);
        EXPECT_LE(q[a], t.hi[a] + 1e-9);
      }
    }
  }
  EXPECT_FALSE(transformBox(Mat4d::identity(), Box3d{}).valid());
}

TEST(BoxTest, TransformBoxRotation) {
  // 90 degrees about z maps [0,1]x[0,2]x[0,3] to [-2,0]x[0,1]x[0,3].
  Box3d b{{0, 0, 0}, {1, 2, 3}};
  Box3d t = transformBox(Mat4d::rotation(axisAngle({0, 0, 1}, 90)), b);
  EXPECT_NEAR(t.lo.x, -2, 1e-15);
  EXPECT_NEAR(t.hi.x, 0, 1e-15);
  EXPECT_NEAR(t.lo.y, 0, 1e-15);
  EXPECT_NEAR(t.hi.y, 1, 1e-15);
  EXPECT_NEAR(t.hi.z, 3, 1e-15);
}

// ---- camera -----------------------------------------------------------------------------

// Clip coordinates of world point p: full 4x4 product (the projection is not affine).
std::array<double, 4> clip(const Mat4d& m, Vec3d p) {
  std::array<double, 4> r{};
  for (int i = 0; i < 4; ++i)
    r[size_t(i)] = m.at(i, 0) * p.x + m.at(i, 1) * p.y + m.at(i, 2) * p.z + m.at(i, 3);
  return r;
}

Camera randomCamera(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-100, 100), fov(20, 120), asp(0.3, 3), nr(0.01, 2);
  Camera c;
  c.eye = {u(rng), u(rng), u(rng)};
  c.rotation = randomUnitQuat(rng);
  c.fovy_deg = fov(rng);
  c.aspect = asp(rng);
  c.near = nr(rng);
  return c;
}

TEST(CameraTest, ViewMatrixMovesEyeToOriginLookingDownMinusZ) {
  std::mt19937 rng(9);
  for (int i = 0; i < 100; ++i) {
    Camera c = randomCamera(rng);
    Mat4d v = viewMatrix(c);
    EXPECT_NEAR(length(v.transformPoint(c.eye)), 0, 1e-12);
    Vec3d ahead = c.eye + rotate(c.rotation, {0, 0, -1}) * 3.0;
    EXPECT_NEAR(length(v.transformPoint(ahead) - Vec3d{0, 0, -3}), 0, 1e-12);
    Vec3d up = c.eye + rotate(c.rotation, {0, 1, 0});
    EXPECT_NEAR(length(v.transformPoint(up) - Vec3d{0, 1, 0}), 0, 1e-12);
    // The rotation part alone ignores translation.
    Vec3d d = rotate(c.rotation, {1, 0, 0});
    EXPECT_NEAR(length(viewRotation(c).transformVector(d) - Vec3d{1, 0, 0}), 0, 1e-14);
    Mat4d inv;
    ASSERT_TRUE(invertAffine(v, &inv));
    EXPECT_NEAR(length(inv.transformPoint({0, 0, 0}) - c.eye), 0, 1e-12);
  }
}

TEST(CameraTest, ProjectionIsReversedZInfinite) {
  Camera c;
  c.fovy_deg = 90;
  c.aspect = 2;
  c.near = 0.5;
  Mat4d p = projectionMatrix(c);
  auto depth = [&](Vec3d e) {
    auto k = clip(p, e);
    return k[2] / k[3];
  };
  EXPECT_DOUBLE_EQ(depth({0, 0, -0.5}), 1.0);  // near plane
  EXPECT_DOUBLE_EQ(depth({0, 0, -1}), 0.5);    // near / distance
  EXPECT_DOUBLE_EQ(depth({3, -2, -5}), 0.1);   // independent of x and y
  EXPECT_GT(depth({0, 0, -1e12}), 0);
  EXPECT_LT(depth({0, 0, -1e12}), 1e-12);
  EXPECT_GT(depth({0, 0, -0.25}), 1);  // nearer than near: clipped
  EXPECT_GT(clip(p, {0, 0, -3})[3], 0);
  EXPECT_LT(clip(p, {0, 0, 3})[3], 0);  // behind the camera
  // fovy 90: y = distance is the top edge; aspect 2: x = 2 * distance the right edge.
  auto k = clip(p, {2 * 4, 4, -4});
  EXPECT_DOUBLE_EQ(k[0] / k[3], 1.0);
  EXPECT_DOUBLE_EQ(k[1] / k[3], 1.0);
  k = clip(p, {-2, -1, -2});
  EXPECT_DOUBLE_EQ(k[0] / k[3], -0.5);
  EXPECT_DOUBLE_EQ(k[1] / k[3], -0.5);
}

TEST(CameraTest, FrustumPlanesAgreeWithProjection) {
  std::mt19937 rng(10);
  std::uniform_real_distribution<double> u(-1, 1);
  int inside = 0, outside = 0;
  for (int ci = 0; ci < 50; ++ci) {
    Camera c = randomCamera(rng);
    Mat4d pv = projectionMatrix(c) * viewMatrix(c);
    auto planes = frustumPlanes(c);
    double ty = std::tan(c.fovy_deg * M_PI / 360), tx = ty * c.aspect;
    std::uniform_real_distribution<double> dist(-0.5 * c.near, 40 * c.near);
    for (int i = 0; i < 2000; ++i) {
      // Points around the frustum in eye space, then into world space.
      double d = dist(rng);
      Vec3d e{u(rng) * 1.3 * tx * std::fabs(d) + u(rng) * 0.1, u(rng) * 1.3 * ty * std::fabs(d),
              -d};
      Vec3d w = c.eye + rotate(c.rotation, e);
      auto k = clip(pv, w);
      double minDist = 1e300;
      for (const Plane& pl : planes) {
        EXPECT_NEAR(length(pl.n), 1, 1e-12);
        minDist = std::min(minDist, pl.distance(w));
      }
      double scale = std::max(1.0, length(e));
      const double m = 1e-9;
      if (k[3] > 0) {
        double x = k[0] / k[3], y = k[1] / k[3], z = k[2] / k[3];
        if (std::fabs(x) <= 1 - m && std::fabs(y) <= 1 - m && z > 0 && z <= 1 - m) {
          ++inside;
          EXPECT_GE(minDist, -1e-9 * scale) << c << " eye-space " << e;
          continue;
        }
        if (std::fabs(x) >= 1 + 1e-6 || std::fabs(y) >= 1 + 1e-6 || z >= 1 + 1e-6) {
          ++outside;
          EXPECT_LT(minDist, 0) << c << " eye-space " << e;
        }
      } else if (k[3] < -m) {  // behind the eye
        ++outside;
        EXPECT_LT(minDist, 0) << c << " eye-space " << e;
      }
    }
  }
  EXPECT_GT(inside, 10000);
  EXPECT_GT(outside, 10000);
}

TEST(CameraTest, FrustumPlanesKnownCamera) {
  // Identity rotation at (0,0,10): looks toward -Z. fovy 90, aspect 1, near 1.
  Camera c{{0, 0, 10}, {}, 90, 1, 1};
  auto pl = frustumPlanes(c);
  double h = std::sqrt(0.5);
  // left: x >= z_eye... normal (1, 0, -1)/sqrt2 through the eye.
  EXPECT_NEAR(pl[0].n.x, h, 1e-15);
  EXPECT_NEAR(pl[0].n.z, -h, 1e-15);
  EXPECT_NEAR(pl[0].distance({0, 0, 10}), 0, 1e-12);
  EXPECT_NEAR(pl[4].distance({0, 0, 9}), 0, 1e-12);  // near plane at distance 1
  EXPECT_NEAR(pl[4].distance({0, 0, 0}), 9, 1e-12);
  EXPECT_NEAR(pl[1].distance({5, 0, 0}), h * 5, 1e-12);  // 10 deep, 5 right of centre
  EXPECT_NEAR(pl[2].distance({0, -11, 0}), -h, 1e-12);   // just below the bottom
}

TEST(CameraTest, CameraAtUsesImageAspect) {
  ControlPoint p{0, {1, 2, 3}, {0, 0, 0, 1}};
  Camera c = cameraAt(p, 1920, 1080, 60, 0.25);
  EXPECT_EQ(c.eye, p.position);
  EXPECT_EQ(c.rotation, p.rotation);
  EXPECT_DOUBLE_EQ(c.aspect, 1920.0 / 1080.0);
  EXPECT_EQ(c.fovy_deg, 60);
  EXPECT_EQ(c.near, 0.25);
}

// The ray through (ndc_x, ndc_y) in world space: the eye and a direction whose
// eye-space z is -1, so a point at parameter t is at eye distance t.
Vec3d rayDirection(const Camera& c, double ndc_x, double ndc_y) {
  double ty = std::tan(c.fovy_deg * M_PI / 360.0), tx = ty * c.aspect;
  return rotate(c.rotation, Vec3d{ndc_x * tx, ndc_y * ty, -1});
}

// Slab test, written independently of entryDepthPlanes: the eye distance at
// which the ray enters the box, or -1 when it never does.
double rayEntry(const Box3d& b, Vec3d o, Vec3d d) {
  double t0 = 0, t1 = std::numeric_limits<double>::infinity();
  for (int i = 0; i < 3; ++i) {
    if (d[i] == 0) {
      if (o[i] < b.lo[i] || o[i] > b.hi[i]) return -1;
      continue;
    }
    double a = (b.lo[i] - o[i]) / d[i], e = (b.hi[i] - o[i]) / d[i];
    t0 = std::max(t0, std::min(a, e));
    t1 = std::min(t1, std::max(a, e));
  }
  return t0 <= t1 ? t0 : -1;
}

TEST(EntryDepthTest, MatchesRaySlabEntryOnRandomCamerasAndBoxes) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> pos(-50, 50), size(0.01, 20), ndc(-1, 1), fov(10, 120);
  int hits = 0, misses = 0;
  for (int trial = 0; trial < 4000; ++trial) {
    Camera c{{pos(rng), pos(rng), pos(rng)},
             randomUnitQuat(rng),
             fov(rng),
             0.5 + ndc(rng) * 0.4 + 1,
             0.01};
    Vec3d lo{pos(rng), pos(rng), pos(rng)};
    Box3d b{lo, lo + Vec3d{size(rng), size(rng), size(rng)}};
    bool inside = b.lo.x <= c.eye.x && c.eye.x <= b.hi.x && b.lo.y <= c.eye.y &&
                  c.eye.y <= b.hi.y && b.lo.z <= c.eye.z && c.eye.z <= b.hi.z;
    if (inside) continue;
    EntryDepthPlanes p = entryDepthPlanes(b, c);
    // Half the rays aim at a point of the box (when it is in front), so that
    // hits and misses are both common.
    double x = ndc(rng), y = ndc(rng);
    Vec3d aim = viewMatrix(c).transformPoint(b.center() + Vec3d{ndc(rng), ndc(rng), ndc(rng)} *
                                                              (length(b.extent()) * 0.5));
    if (trial % 2 == 0 && aim.z < 0) {
      double ty = std::tan(c.fovy_deg * M_PI / 360.0), tx = ty * c.aspect;
      x = aim.x / -aim.z / tx;
      y = aim.y / -aim.z / ty;
    }
    double t = rayEntry(b, c.eye, rayDirection(c, x, y));
    double d = entryDepth(p, x, y);
    if (t > 0) {
      ++hits;
      EXPECT_NEAR(d, c.near / t, 1e-9 * c.near / t) << "trial " << trial << " " << c;
    } else {
      ++misses;
      // A miss: either some slab is never entered (bound <= 0, the fragment
      // dies) or the slabs' entries do not overlap; either way no point of
      // the box lies on the ray, so any bound is sound.
      EXPECT_TRUE(std::isfinite(d));
    }
  }
  EXPECT_GT(hits, 300);
  EXPECT_GT(misses, 300);
}

TEST(EntryDepthTest, BoundsEveryPointOfTheBoxOnTheRay) {
  // What the shaders' clamp rests on: a point of the box seen through a
  // pixel is never in front of (deeper-valued than) the entry depth there.
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> pos(-30, 30), size(0.1, 10), unit(0, 1);
  for (int trial = 0; trial < 2000; ++trial) {
    Camera c{{pos(rng), pos(rng), pos(rng)}, randomUnitQuat(rng), 60, 1.5, 0.05};
    Vec3d lo{pos(rng), pos(rng), pos(rng)};
    Box3d b{lo, lo + Vec3d{size(rng), size(rng), size(rng)}};
    Vec3d q{b.lo.x + unit(rng) * (b.hi.x - b.lo.x), b.lo.y + unit(rng) * (b.hi.y - b.lo.y),
            b.lo.z + unit(rng) * (b.hi.z - b.lo.z)};
    Vec3d e = viewMatrix(c).transformPoint(q);
    if (-e.z <= c.near) continue;  // behind the camera or before the near plane
    double ty = std::tan(c.fovy_deg * M_PI / 360.0), tx = ty * c.aspect;
    double x = e.x / -e.z / tx, y = e.y / -e.z / ty;
    EXPECT_LE(c.near / -e.z, entryDepth(entryDepthPlanes(b, c), x, y) * (1 + 1e-12))
        << "trial " << trial;
  }
}

TEST(EntryDepthTest, EyeInsideASlabSetsNoBoundForThatAxis) {
  Camera c{{0, 0, 0}, Quatd{}, 90, 1, 1};  // looking down -Z
  Box3d b{{-1, -1, -10}, {1, 1, -5}};      // the eye is inside the x and y slabs
  EntryDepthPlanes p = entryDepthPlanes(b, c);
  EXPECT_EQ(p.k[0], (std::array<double, 3>{0, 0, kNoDepthBound}));
  EXPECT_EQ(p.k[1], (std::array<double, 3>{0, 0, kNoDepthBound}));
  // Entered at z = -5 everywhere: depth near / 5.
  EXPECT_DOUBLE_EQ(entryDepth(p, 0, 0), 0.2);
  EXPECT_DOUBLE_EQ(entryDepth(p, 0.9, -0.7), 0.2);
  // Inside the box: no bound at all.
  EXPECT_EQ(entryDepth(entryDepthPlanes(Box3d{{-1, -1, -1}, {1, 1, 1}}, c), 0.3, 0.3),
            kNoDepthBound);
}

}  // namespace
}  // namespace dmmr

namespace dmmr {

TEST(InsideFrame, AcceptsRegionsWithinTheFrameUpToItsEdges) {
  EXPECT_TRUE(insideFrame(Rect{0, 0, 640, 480}, 640, 480));
  EXPECT_TRUE(insideFrame(Rect{639, 479, 1, 1}, 640, 480));
  EXPECT_TRUE(insideFrame(Rect{640, 480, 0, 0}, 640, 480));  // empty, at the corner
}

TEST(InsideFrame, RejectsRegionsOutsideOrNegative) {
  EXPECT_FALSE(insideFrame(Rect{-1, 0, 10, 10}, 640, 480));
  EXPECT_FALSE(insideFrame(Rect{0, 0, 641, 10}, 640, 480));
  EXPECT_FALSE(insideFrame(Rect{0, 475, 10, 6}, 640, 480));
  EXPECT_FALSE(insideFrame(Rect{0, 0, -5, 10}, 640, 480));
}

// x + w near INT_MAX: in int it overflows (undefined; in practice it wraps
// negative and passed the server's old `x1() > width` check).
TEST(InsideFrame, RejectsRegionsWhoseEndOverflowsInt) {
  constexpr int kMax = std::numeric_limits<int>::max();
  EXPECT_FALSE(insideFrame(Rect{kMax - 10, 0, 100, 1}, 640, 480));
  EXPECT_FALSE(insideFrame(Rect{0, kMax, 1, kMax}, 640, 480));
  EXPECT_FALSE(insideFrame(Rect{kMax, kMax, kMax, kMax}, 640, 480));
  EXPECT_FALSE(insideFrame(Rect{10, 10, kMax, 1}, 640, 480));
}

}  // namespace dmmr
