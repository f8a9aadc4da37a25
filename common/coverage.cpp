#include "coverage.h"

#include <algorithm>
#include <cmath>
#include <limits>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#define DMMR_COVERAGE_AVX2 1
#else
#define DMMR_COVERAGE_AVX2 0
#endif

namespace dmmr {

namespace {

// Float's unit roundoff. A float sum of n products of float-rounded factors
// is off by at most about (n + 1) u times the sum of the terms' magnitudes,
// whatever the order or contraction (FMA); 8 u covers the 4-term dot
// products of a vertex transform with room to spare.
constexpr double kU = 1.0 / (1 << 24);
constexpr double kDot = 8 * kU;

// What projectVertices needs of a draw: the transform in double, the error
// bounds of its clip coordinates (one for all the vertices) and the
// viewport.
struct Projector {
  double m[4][4];  // object to eye, by rows
  double p[3][4];  // the projection's x, y and w rows
  double dc[3];    // the clip x, y and w errors
  double half_w, half_h, snap;
};

// The largest finite magnitude of each coordinate (x, y, z) of `count`
// vertices, 0 where none is finite.
void largestMagnitudes(const float* positions, size_t count, float big[3]) {
  big[0] = big[1] = big[2] = 0;
  const float top = std::numeric_limits<float>::max();
  for (size_t i = 0; i < count; ++i)
    for (int k = 0; k < 3; ++k) {
      const float a = std::fabs(positions[3 * i + size_t(k)]);
      big[k] = a > big[k] && a <= top ? a : big[k];
    }
}

#if DMMR_COVERAGE_AVX2
// largestMagnitudes eight vertices (24 floats, three registers) at a time:
// a maximum does not depend on the order, so the result is the same.
__attribute__((target("avx2"))) void largestMagnitudesAvx2(const float* positions, size_t count,
                                                           float big[3]) {
  const __m256 sign = _mm256_set1_ps(-0.0f);
  const __m256 top = _mm256_set1_ps(std::numeric_limits<float>::max());
  __m256 acc[3] = {_mm256_setzero_ps(), _mm256_setzero_ps(), _mm256_setzero_ps()};
  size_t i = 0;
  for (; i + 8 <= count; i += 8)
    for (int r = 0; r < 3; ++r) {
      const __m256 a = _mm256_andnot_ps(sign, _mm256_loadu_ps(positions + 3 * i + 8 * size_t(r)));
      // a <= top fails for infinities and NaN, which then count as 0.
      acc[r] = _mm256_max_ps(acc[r], _mm256_and_ps(a, _mm256_cmp_ps(a, top, _CMP_LE_OQ)));
    }
  largestMagnitudes(positions + 3 * i, count - i, big);
  alignas(32) float lanes[24];
  for (int r = 0; r < 3; ++r) _mm256_store_ps(lanes + 8 * r, acc[r]);
  for (int f = 0; f < 24; ++f) big[f % 3] = std::max(big[f % 3], lanes[f]);
}
#endif

// `big`: largestMagnitudes of the draw's vertices.
Projector projectorFor(const float big[3], const WindowTransform& t) {
  Projector P;
  double am[4][4], ap[3][4];  // the magnitudes
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) {
      P.m[r][c] = t.object_to_eye.at(r, c);
      am[r][c] = std::fabs(P.m[r][c]);
    }
  const int rows[3] = {0, 1, 3};
  for (int k = 0; k < 3; ++k)
    for (int r = 0; r < 4; ++r) {
      P.p[k][r] = t.projection.at(rows[k], r);
      ap[k][r] = std::fabs(P.p[k][r]);
    }
  // A clip coordinate's error: its row's magnitudes times the eye errors
  // (kDot times each eye row's sum of term magnitudes) carried through, plus
  // its own dot product's rounding (kDot times its terms' magnitudes, each
  // at most the eye row's sum plus its error): kDot (2 + kDot) times the
  // projection row's magnitudes applied to the eye rows' sums.
  const double k_clip = kDot * (2 + kDot);
  // One bound for all the vertices, from their largest coordinate
  // magnitudes (finite ones: a non-finite vertex is kept apart below): a
  // vertex's own would be at most as large, and the error it bounds is far
  // under the snapping step either way, so the radius hardly grows while
  // each vertex is spared half of its arithmetic.
  double mag[4];
  for (int r = 0; r < 4; ++r)
    mag[r] = am[r][0] * big[0] + am[r][1] * big[1] + am[r][2] * big[2] + am[r][3];
  for (int k = 0; k < 3; ++k)
    P.dc[k] =
        k_clip * (ap[k][0] * mag[0] + ap[k][1] * mag[1] + ap[k][2] * mag[2] + ap[k][3] * mag[3]);
  P.half_w = 0.5 * t.width;
  P.half_h = 0.5 * t.height;
  P.snap = std::ldexp(1.0, -std::max(0, t.subpixel_bits));
  return P;
}

// Projects the vertices [i0, i1) into o[i0, i1).
void projectRange(const float* positions, size_t i0, size_t i1, const Projector& P,
                  WindowVertex* o) {
  const double dw = P.dc[2];
  const float inf = std::numeric_limits<float>::infinity();
  for (size_t i = i0; i < i1; ++i) {
    const double x = positions[3 * i], y = positions[3 * i + 1], z = positions[3 * i + 2];
    double e[4];
    for (int r = 0; r < 4; ++r) e[r] = P.m[r][0] * x + P.m[r][1] * y + P.m[r][2] * z + P.m[r][3];
    double c[3];
    for (int k = 0; k < 3; ++k)
      c[k] = P.p[k][0] * e[0] + P.p[k][1] * e[1] + P.p[k][2] * e[2] + P.p[k][3] * e[3];
    const double w = c[2];
    const double inv = 1 / w, nx = c[0] * inv, ny = c[1] * inv;
    const double anx = std::fabs(nx), any = std::fabs(ny);
    // The quotient's error from both operands' and its own rounding, then
    // the viewport transform's. 1 / (w - dw) <= (1 + 2 dw / w) / w where
    // w > 2 dw (checked below; otherwise the vertex is kept apart).
    const double inv_low = inv * (1 + 2 * dw * inv);
    const double dnx = (P.dc[0] + anx * dw) * inv_low + 2 * kU * anx;
    const double dny = (P.dc[1] + any * dw) * inv_low + 2 * kU * any;
    const double dx = (dnx + 4 * kU * (anx + 1)) * P.half_w;
    const double dy = (dny + 4 * kU * (any + 1)) * P.half_h;
    const double wx = (nx + 1) * P.half_w, wy = (ny + 1) * P.half_h;
    // Twice the bound, a whole snapping step (rounding moves a vertex by
    // half a step, truncation by up to one), and the rounding of the
    // position to float; the radius itself rounded up.
    double radius = 2 * (dx < dy ? dy : dx) + P.snap + (std::fabs(wx) + std::fabs(wy)) * 0x1p-23;
    radius *= 1 + 0x1p-20;
    WindowVertex v{float(wx), float(wy), float(radius), 0.f};
    // w > 2 dw is false for NaN too.
    if (!(w > 2 * dw) || !std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.radius))
      v = {0.f, 0.f, inf, 0.f};
    o[i] = v;
  }
}

#if DMMR_COVERAGE_AVX2
// projectRange four vertices at a time: the same double operations in the
// same order (this target has no FMA to contract them), so the same
// vertices, bit for bit; the last count % 4 by projectRange.
__attribute__((target("avx2"))) inline __m256d all(double d) {
  return _mm256_set1_pd(d);
}
__attribute__((target("avx2"))) void projectAvx2(const float* positions, size_t count,
                                                 const Projector& P, WindowVertex* o) {
  const __m256d dw = all(P.dc[2]), dcx = all(P.dc[0]), dcy = all(P.dc[1]);
  const __m256d one = all(1), two = all(2), two_dw = all(2 * P.dc[2]);
  const __m256d u2 = all(2 * kU), u4 = all(4 * kU), half_w = all(P.half_w), half_h = all(P.half_h),
                snap = all(P.snap), ulp23 = all(0x1p-23), grow = all(1 + 0x1p-20), sign = all(-0.0);
  const __m128 finite = _mm_set1_ps(std::numeric_limits<float>::max());
  const __m128 sign_f = _mm_set1_ps(-0.0f);
  const __m256i low_halves = _mm256_setr_epi32(0, 2, 4, 6, 0, 2, 4, 6);  // 64-bit masks to 32
  size_t i = 0;
  for (; i + 4 <= count; i += 4) {
    const float* q = positions + 3 * i;
    const __m256d x = _mm256_cvtps_pd(_mm_setr_ps(q[0], q[3], q[6], q[9]));
    const __m256d y = _mm256_cvtps_pd(_mm_setr_ps(q[1], q[4], q[7], q[10]));
    const __m256d z = _mm256_cvtps_pd(_mm_setr_ps(q[2], q[5], q[8], q[11]));
    __m256d e[4];
    for (int r = 0; r < 4; ++r)
      e[r] = _mm256_add_pd(_mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(all(P.m[r][0]), x),
                                                       _mm256_mul_pd(all(P.m[r][1]), y)),
                                         _mm256_mul_pd(all(P.m[r][2]), z)),
                           all(P.m[r][3]));
    __m256d c[3];
    for (int k = 0; k < 3; ++k)
      c[k] = _mm256_add_pd(_mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(all(P.p[k][0]), e[0]),
                                                       _mm256_mul_pd(all(P.p[k][1]), e[1])),
                                         _mm256_mul_pd(all(P.p[k][2]), e[2])),
                           _mm256_mul_pd(all(P.p[k][3]), e[3]));
    const __m256d w = c[2];
    const __m256d inv = _mm256_div_pd(one, w);
    const __m256d nx = _mm256_mul_pd(c[0], inv), ny = _mm256_mul_pd(c[1], inv);
    const __m256d anx = _mm256_andnot_pd(sign, nx), any = _mm256_andnot_pd(sign, ny);
    const __m256d inv_low = _mm256_mul_pd(inv, _mm256_add_pd(one, _mm256_mul_pd(two_dw, inv)));
    const __m256d dnx = _mm256_add_pd(
        _mm256_mul_pd(_mm256_add_pd(dcx, _mm256_mul_pd(anx, dw)), inv_low), _mm256_mul_pd(u2, anx));
    const __m256d dny = _mm256_add_pd(
        _mm256_mul_pd(_mm256_add_pd(dcy, _mm256_mul_pd(any, dw)), inv_low), _mm256_mul_pd(u2, any));
    const __m256d dx =
        _mm256_mul_pd(_mm256_add_pd(dnx, _mm256_mul_pd(u4, _mm256_add_pd(anx, one))), half_w);
    const __m256d dy =
        _mm256_mul_pd(_mm256_add_pd(dny, _mm256_mul_pd(u4, _mm256_add_pd(any, one))), half_h);
    const __m256d wx = _mm256_mul_pd(_mm256_add_pd(nx, one), half_w);
    const __m256d wy = _mm256_mul_pd(_mm256_add_pd(ny, one), half_h);
    // max(dy, dx) is dy > dx ? dy : dx, as the scalar dx < dy ? dy : dx.
    __m256d radius = _mm256_add_pd(
        _mm256_add_pd(_mm256_mul_pd(two, _mm256_max_pd(dy, dx)), snap),
        _mm256_mul_pd(_mm256_add_pd(_mm256_andnot_pd(sign, wx), _mm256_andnot_pd(sign, wy)),
                      ulp23));
    radius = _mm256_mul_pd(radius, grow);
    const __m128 fx = _mm256_cvtpd_ps(wx), fy = _mm256_cvtpd_ps(wy), fr = _mm256_cvtpd_ps(radius);
    // Kept apart: w > 2 dw false (NaN too), or a float not finite (NaN
    // fails the comparison as well).
    const __m128 front = _mm_castsi128_ps(_mm256_castsi256_si128(_mm256_permutevar8x32_epi32(
        _mm256_castpd_si256(_mm256_cmp_pd(w, two_dw, _CMP_GT_OQ)), low_halves)));
    const __m128 ok =
        _mm_and_ps(front, _mm_and_ps(_mm_cmple_ps(_mm_andnot_ps(sign_f, fx), finite),
                                     _mm_and_ps(_mm_cmple_ps(_mm_andnot_ps(sign_f, fy), finite),
                                                _mm_cmple_ps(_mm_andnot_ps(sign_f, fr), finite))));
    __m128 v0 = _mm_and_ps(fx, ok), v1 = _mm_and_ps(fy, ok);
    __m128 v2 = _mm_or_ps(_mm_and_ps(ok, fr),
                          _mm_andnot_ps(ok, _mm_set1_ps(std::numeric_limits<float>::infinity())));
    __m128 v3 = _mm_setzero_ps();
    _MM_TRANSPOSE4_PS(v0, v1, v2, v3);
    _mm_storeu_ps(&o[i].x, v0);
    _mm_storeu_ps(&o[i + 1].x, v1);
    _mm_storeu_ps(&o[i + 2].x, v2);
    _mm_storeu_ps(&o[i + 3].x, v3);
  }
  projectRange(positions, i, count, P, o);
}
#endif

}  // namespace

namespace detail {
void projectVerticesScalar(const float* positions, size_t count, const WindowTransform& t,
                           WindowVertices* out) {
  out->resize(count);
  float big[3];
  largestMagnitudes(positions, count, big);
  projectRange(positions, 0, count, projectorFor(big, t), out->data());
}
#if DMMR_COVERAGE_AVX2
void projectVerticesAvx2(const float* positions, size_t count, const WindowTransform& t,
                         WindowVertices* out) {
  out->resize(count);
  float big[3];
  largestMagnitudesAvx2(positions, count, big);
  projectAvx2(positions, count, projectorFor(big, t), out->data());
}
#endif
}  // namespace detail

void projectVertices(const float* positions, size_t count, const WindowTransform& t,
                     WindowVertices* out) {
#if DMMR_COVERAGE_AVX2
  if (detail::haveAvx2()) return detail::projectVerticesAvx2(positions, count, t, out);
#endif
  detail::projectVerticesScalar(positions, count, t, out);
}

namespace {
// floor(t) for |t| < 2^30 (a double's truncation of a positive value), or
// one more where t lies within 2^-23 below an integer (t + 2^30 rounds up
// to it); never less.
inline int64_t floorSmall(double t) {
  constexpr double k = 1 << 30;
  return int64_t(t + k) - int64_t(k);
}
inline float minf(float a, float b) {
  return b < a ? b : a;
}
inline float maxf(float a, float b) {
  return a < b ? b : a;
}
inline float min3(float a, float b, float c) {
  return minf(minf(a, b), c);
}
inline float max3(float a, float b, float c) {
  return maxf(maxf(a, b), c);
}

// Whether the triangle, each vertex moved by up to r (finite) along each
// axis, can cover a pixel centre (i + 0.5, j + 0.5) for i in [cx0, cx1], j
// in [cy0, cy1]. At a centre p it covers, the moved triangle's three edge
// functions have one sign (or are 0: any tie rule). Moving an edge's ends
// a, b by da, db changes its function (b - a) x (p - a) by
// (db - da) x (p - a) - (b - a) x da - (db - da) x da, and u x d is at most
// |u|_1 r for d within r on each axis: at most
// r (2 |p - a|_1 + |b - a|_1 + 4 r) in all. Both windings are tried, so a
// triangle whose winding the error could flip is decided as either. The
// double arithmetic's own rounding (relative 2^-52 of products whose
// factors the margin's terms bound) is covered by the margin's last
// factor and term.
bool reachesACentre(const WindowVertex& a, const WindowVertex& b, const WindowVertex& c, double r,
                    int64_t cx0, int64_t cx1, int64_t cy0, int64_t cy1) {
  const WindowVertex* vs[3] = {&a, &b, &c};
  double ex[3], ey[3], len[3];
  for (int e = 0; e < 3; ++e) {
    const WindowVertex &p = *vs[e], &q = *vs[(e + 1) % 3];
    ex[e] = double(q.x) - p.x;
    ey[e] = double(q.y) - p.y;
    len[e] = std::fabs(ex[e]) + std::fabs(ey[e]) + 4 * r;
  }
  for (int64_t j = cy0; j <= cy1; ++j)
    for (int64_t i = cx0; i <= cx1; ++i) {
      const double px = double(i) + 0.5, py = double(j) + 0.5;
      bool pos = true, neg = true;
      for (int e = 0; e < 3; ++e) {
        const double fx = px - vs[e]->x, fy = py - vs[e]->y;
        const double f = ex[e] * fy - ey[e] * fx;
        const double slack =
            r * (2 * (std::fabs(fx) + std::fabs(fy)) + len[e]) * (1 + 0x1p-20) + 0x1p-40;
        pos = pos && f >= -slack;
        neg = neg && f <= slack;
      }
      if (pos || neg) return true;
    }
  return false;
}

// The scissor's pixel centres i + 0.5 for columns i in [x0, x1], rows
// likewise, and the clamp applied to a box first: a pixel beyond the scissor
// on each side, which keeps every centre it held there and the arithmetic
// small.
struct Centres {
  int64_t x0, x1, y0, y1;
  float lox, hix, loy, hiy;
  explicit Centres(Rect s)
      : x0(s.x),
        x1(int64_t(s.x) + s.w - 1),
        y0(s.y),
        y1(int64_t(s.y) + s.h - 1),
        lox(float(x0 - 2)),
        hix(float(x1 + 3)),
        loy(float(y0 - 2)),
        hiy(float(y1 + 3)) {}
};

// keepCoveringTriangles over the triangles starting at indices [t0, t1),
// appending to out from out[kept]; returns the new kept.
size_t keepRange(const uint32_t* indices, size_t t0, size_t t1, const WindowVertex* v, size_t n,
                 const Centres& s, uint32_t* out, size_t kept) {
  for (size_t t = t0; t + 2 < t1; t += 3) {
    const uint32_t a = indices[t], b = indices[t + 1], c = indices[t + 2];
    bool keep = true;
    if (a < n && b < n && c < n) {
      // By value, so that min and max compile to minss and maxss, not to
      // branches on the data.
      const WindowVertex va = v[a], vb = v[b], vc = v[c];
      // Finite positions; a radius of +inf widens the box to the clamp.
      const float r = max3(va.radius, vb.radius, vc.radius);
      const float lx = maxf(min3(va.x, vb.x, vc.x) - r, s.lox);
      const float hx = minf(max3(va.x, vb.x, vc.x) + r, s.hix);
      const float ly = maxf(min3(va.y, vb.y, vc.y) - r, s.loy);
      const float hy = minf(max3(va.y, vb.y, vc.y) + r, s.hiy);
      // The first centre column at or right of lx: ceil(lx - 0.5); the last
      // at or left of hx: floor(hx - 0.5). Computed in double; floorSmall's
      // rounding can only add a column or row, never lose one.
      const int64_t cx0 = std::max(-floorSmall(0.5 - double(lx)), s.x0);
      const int64_t cx1 = std::min(floorSmall(double(hx) - 0.5), s.x1);
      const int64_t cy0 = std::max(-floorSmall(0.5 - double(ly)), s.y0);
      const int64_t cy1 = std::min(floorSmall(double(hy) - 0.5), s.y1);
      keep = cx0 <= cx1 && cy0 <= cy1;
      // A box with few centres: kept only if the triangle itself can reach
      // one. The box test alone keeps about twice the triangles of a dense
      // mesh that cover a centre (skullmesh4: 319k triangles a frame
      // submitted, 150k with this test; docs/benchmarks.md).
      if (keep && (cx1 - cx0 + 1) * (cy1 - cy0 + 1) <= kExactCentres)
        keep = reachesACentre(va, vb, vc, double(r), cx0, cx1, cy0, cy1);
    }
    if (keep) {
      out[kept] = a;
      out[kept + 1] = b;
      out[kept + 2] = c;
      kept += 3;
    }
  }
  return kept;
}

}  // namespace

namespace detail {

size_t keepCoveringTrianglesScalar(const uint32_t* indices, size_t count, const WindowVertices& v,
                                   Rect scissor, uint32_t* out) {
  return keepRange(indices, 0, count, v.data(), v.size(), Centres(scissor), out, 0);
}

#if DMMR_COVERAGE_AVX2

namespace {

// floorSmall on four doubles: t + 2^30 rounded, then floored, less 2^30.
__attribute__((target("avx2"))) inline __m256d floorSmall4(__m256d t) {
  const __m256d k = _mm256_set1_pd(1 << 30);
  return _mm256_sub_pd(_mm256_floor_pd(_mm256_add_pd(t, k)), k);
}

// The lower (h 0) or upper (h 1) four floats of eight.
__attribute__((target("avx2"))) inline __m128 halfOf(__m256 f, int h) {
  return h == 0 ? _mm256_castps256_ps128(f) : _mm256_extractf128_ps(f, 1);
}

// Four triangles of a batch, in double lanes: their corners and radius.
struct Tris4 {
  __m256d x[3], y[3], r;
};

// keepRange's box test on four triangles whose boxes (widened and clamped,
// in float) are lx..hx, ly..hy: the centre ranges, in double (small
// integers, exact), and the lanes whose box holds a centre, whose box holds
// one alone, and whose holds two to kExactCentres.
struct Boxes4 {
  __m256d cx0, cx1, cy0, cy1;
  int nonempty, one, few;
};
__attribute__((target("avx2"))) inline Boxes4 boxes4(__m128 lx, __m128 hx, __m128 ly, __m128 hy,
                                                     const Centres& s) {
  const __m256d half = _mm256_set1_pd(0.5), one = _mm256_set1_pd(1);
  const __m256d zero = _mm256_setzero_pd();
  Boxes4 b;
  b.cx0 = _mm256_max_pd(_mm256_sub_pd(zero, floorSmall4(_mm256_sub_pd(half, _mm256_cvtps_pd(lx)))),
                        _mm256_set1_pd(double(s.x0)));
  b.cx1 = _mm256_min_pd(floorSmall4(_mm256_sub_pd(_mm256_cvtps_pd(hx), half)),
                        _mm256_set1_pd(double(s.x1)));
  b.cy0 = _mm256_max_pd(_mm256_sub_pd(zero, floorSmall4(_mm256_sub_pd(half, _mm256_cvtps_pd(ly)))),
                        _mm256_set1_pd(double(s.y0)));
  b.cy1 = _mm256_min_pd(floorSmall4(_mm256_sub_pd(_mm256_cvtps_pd(hy), half)),
                        _mm256_set1_pd(double(s.y1)));
  const __m256d ne = _mm256_and_pd(_mm256_cmp_pd(b.cx0, b.cx1, _CMP_LE_OQ),
                                   _mm256_cmp_pd(b.cy0, b.cy1, _CMP_LE_OQ));
  // The product of two counts up to 2^30 rounds, but stays above
  // kExactCentres whenever the exact one does.
  const __m256d centres = _mm256_mul_pd(_mm256_add_pd(_mm256_sub_pd(b.cx1, b.cx0), one),
                                        _mm256_add_pd(_mm256_sub_pd(b.cy1, b.cy0), one));
  b.nonempty = _mm256_movemask_pd(ne);
  b.one = _mm256_movemask_pd(_mm256_and_pd(ne, _mm256_cmp_pd(centres, one, _CMP_EQ_OQ)));
  b.few = _mm256_movemask_pd(_mm256_and_pd(
              ne, _mm256_cmp_pd(centres, _mm256_set1_pd(double(kExactCentres)), _CMP_LE_OQ))) &
          ~b.one;
  return b;
}

// reachesACentre for four triangles each at its one centre (cx0, cy0): the
// same operations in the same order on the same doubles (this target has
// no FMA to contract them), so the same answers. Returns the lanes' mask.
__attribute__((target("avx2"))) inline int reachesTheCentre4(const Tris4& t, const Boxes4& b) {
  const __m256d half = _mm256_set1_pd(0.5), sign = _mm256_set1_pd(-0.0);
  const __m256d two = _mm256_set1_pd(2), four = _mm256_set1_pd(4);
  const __m256d grow = _mm256_set1_pd(1 + 0x1p-20), tiny = _mm256_set1_pd(0x1p-40);
  const __m256d px = _mm256_add_pd(b.cx0, half), py = _mm256_add_pd(b.cy0, half);
  __m256d pos = _mm256_castsi256_pd(_mm256_set1_epi64x(-1)), neg = pos;
  for (int e = 0; e < 3; ++e) {
    const int q = (e + 1) % 3;
    const __m256d ex = _mm256_sub_pd(t.x[q], t.x[e]), ey = _mm256_sub_pd(t.y[q], t.y[e]);
    const __m256d len =
        _mm256_add_pd(_mm256_add_pd(_mm256_andnot_pd(sign, ex), _mm256_andnot_pd(sign, ey)),
                      _mm256_mul_pd(four, t.r));
    const __m256d fx = _mm256_sub_pd(px, t.x[e]), fy = _mm256_sub_pd(py, t.y[e]);
    const __m256d f = _mm256_sub_pd(_mm256_mul_pd(ex, fy), _mm256_mul_pd(ey, fx));
    const __m256d l1 = _mm256_add_pd(_mm256_andnot_pd(sign, fx), _mm256_andnot_pd(sign, fy));
    const __m256d slack = _mm256_add_pd(
        _mm256_mul_pd(_mm256_mul_pd(t.r, _mm256_add_pd(_mm256_mul_pd(two, l1), len)), grow), tiny);
    pos = _mm256_and_pd(pos, _mm256_cmp_pd(f, _mm256_xor_pd(slack, sign), _CMP_GE_OQ));
    neg = _mm256_and_pd(neg, _mm256_cmp_pd(f, slack, _CMP_LE_OQ));
  }
  return _mm256_movemask_pd(_mm256_or_pd(pos, neg));
}

}  // namespace

bool haveAvx2() {
  static const bool have = __builtin_cpu_supports("avx2");
  return have;
}

__attribute__((target("avx2"))) size_t keepCoveringTrianglesAvx2(const uint32_t* indices,
                                                                 size_t count,
                                                                 const WindowVertices& vertices,
                                                                 Rect scissor, uint32_t* out) {
  const WindowVertex* v = vertices.data();
  const size_t n = vertices.size();
  const Centres s(scissor);
  // An invalid lane reads vertex 0, and the indices are compared as 32-bit
  // lanes: 0 < n < 2^31.
  if (n == 0 || n >= (size_t(1) << 31)) return keepRange(indices, 0, count, v, n, s, out, 0);
  const __m256i flip = _mm256_set1_epi32(INT32_MIN);  // unsigned order as signed
  const __m256i limit = _mm256_xor_si256(_mm256_set1_epi32(int32_t(n)), flip);
  // Eight triangles' 24 indices, a0 b0 c0 a1 ...: blended from the three
  // loads so that each lane holds its triangle's corner, then put in order.
  const __m256i order_a = _mm256_setr_epi32(0, 3, 6, 1, 4, 7, 2, 5);
  const __m256i order_b = _mm256_setr_epi32(1, 4, 7, 2, 5, 0, 3, 6);
  const __m256i order_c = _mm256_setr_epi32(2, 5, 0, 3, 6, 1, 4, 7);
  const __m256 lox = _mm256_set1_ps(s.lox), hix = _mm256_set1_ps(s.hix);
  const __m256 loy = _mm256_set1_ps(s.loy), hiy = _mm256_set1_ps(s.hiy);
  size_t kept = 0, t = 0;
  for (; t + 24 <= count; t += 24) {
    const __m256i m0 = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(indices + t));
    const __m256i m1 = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(indices + t + 8));
    const __m256i m2 = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(indices + t + 16));
    const __m256i ia = _mm256_permutevar8x32_epi32(
        _mm256_blend_epi32(_mm256_blend_epi32(m0, m1, 0x92), m2, 0x24), order_a);
    const __m256i ib = _mm256_permutevar8x32_epi32(
        _mm256_blend_epi32(_mm256_blend_epi32(m0, m1, 0x24), m2, 0x49), order_b);
    const __m256i ic = _mm256_permutevar8x32_epi32(
        _mm256_blend_epi32(_mm256_blend_epi32(m0, m1, 0x49), m2, 0x92), order_c);
    const __m256i valid =
        _mm256_and_si256(_mm256_cmpgt_epi32(limit, _mm256_xor_si256(ia, flip)),
                         _mm256_and_si256(_mm256_cmpgt_epi32(limit, _mm256_xor_si256(ib, flip)),
                                          _mm256_cmpgt_epi32(limit, _mm256_xor_si256(ic, flip))));
    // Invalid lanes read vertex 0.
    alignas(32) uint32_t id[3][8];
    _mm256_store_si256(reinterpret_cast<__m256i*>(id[0]), _mm256_and_si256(ia, valid));
    _mm256_store_si256(reinterpret_cast<__m256i*>(id[1]), _mm256_and_si256(ib, valid));
    _mm256_store_si256(reinterpret_cast<__m256i*>(id[2]), _mm256_and_si256(ic, valid));
    // Each corner's eight vertices (x, y, radius, unused), two to a
    // register, transposed into x, y and radius lanes.
    __m256 x[3], y[3], rv[3];
    for (int k = 0; k < 3; ++k) {
      __m256 q[4];
      for (int l = 0; l < 4; ++l)
        q[l] = _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(&v[id[k][l]].x)),
                                    _mm_loadu_ps(&v[id[k][l + 4]].x), 1);
      const __m256 lo01 = _mm256_unpacklo_ps(q[0], q[1]), lo23 = _mm256_unpacklo_ps(q[2], q[3]);
      const __m256 hi01 = _mm256_unpackhi_ps(q[0], q[1]), hi23 = _mm256_unpackhi_ps(q[2], q[3]);
      x[k] = _mm256_shuffle_ps(lo01, lo23, 0x44);
      y[k] = _mm256_shuffle_ps(lo01, lo23, 0xee);
      rv[k] = _mm256_shuffle_ps(hi01, hi23, 0x44);
    }
    // As keepRange, in float: min and max differ from its minf and maxf
    // only in the sign of a zero, which the subtraction of r > 0 erases.
    const __m256 r = _mm256_max_ps(_mm256_max_ps(rv[0], rv[1]), rv[2]);
    const __m256 lx =
        _mm256_max_ps(_mm256_sub_ps(_mm256_min_ps(_mm256_min_ps(x[0], x[1]), x[2]), r), lox);
    const __m256 hx =
        _mm256_min_ps(_mm256_add_ps(_mm256_max_ps(_mm256_max_ps(x[0], x[1]), x[2]), r), hix);
    const __m256 ly =
        _mm256_max_ps(_mm256_sub_ps(_mm256_min_ps(_mm256_min_ps(y[0], y[1]), y[2]), r), loy);
    const __m256 hy =
        _mm256_min_ps(_mm256_add_ps(_mm256_max_ps(_mm256_max_ps(y[0], y[1]), y[2]), r), hiy);
    const int invalid = ~_mm256_movemask_ps(_mm256_castsi256_ps(valid)) & 0xff;
    int keep = invalid;
    for (int h = 0; h < 2; ++h) {
      const Boxes4 b = boxes4(halfOf(lx, h), halfOf(hx, h), halfOf(ly, h), halfOf(hy, h), s);
      const int lanes = ~(invalid >> 4 * h) & 0xf;
      int half_keep = b.nonempty & ~(b.one | b.few);
      if (b.one & lanes) {
        Tris4 tri;
        for (int k = 0; k < 3; ++k) {
          tri.x[k] = _mm256_cvtps_pd(halfOf(x[k], h));
          tri.y[k] = _mm256_cvtps_pd(halfOf(y[k], h));
        }
        tri.r = _mm256_cvtps_pd(halfOf(r, h));
        half_keep |= b.one & reachesTheCentre4(tri, b);
      }
      // Two to kExactCentres centres (rarer): the portable test, lane by lane.
      if (int few = b.few & lanes) {
        alignas(32) double c[4][4];
        alignas(16) float rs[4];
        _mm256_store_pd(c[0], b.cx0), _mm256_store_pd(c[1], b.cx1);
        _mm256_store_pd(c[2], b.cy0), _mm256_store_pd(c[3], b.cy1);
        _mm_store_ps(rs, halfOf(r, h));
        for (; few; few &= few - 1) {
          const int k = __builtin_ctz(unsigned(few));
          const uint32_t* tri = indices + t + 3 * size_t(4 * h + k);
          if (reachesACentre(v[tri[0]], v[tri[1]], v[tri[2]], double(rs[k]), int64_t(c[0][k]),
                             int64_t(c[1][k]), int64_t(c[2][k]), int64_t(c[3][k])))
            half_keep |= 1 << k;
        }
      }
      keep |= (half_keep & lanes) << 4 * h;
    }
    while (keep) {
      const int k = __builtin_ctz(unsigned(keep));
      keep &= keep - 1;
      const uint32_t* tri = indices + t + 3 * size_t(k);
      out[kept] = tri[0];
      out[kept + 1] = tri[1];
      out[kept + 2] = tri[2];
      kept += 3;
    }
  }
  return keepRange(indices, t, count, v, n, s, out, kept);
}

#else

bool haveAvx2() {
  return false;
}
size_t keepCoveringTrianglesAvx2(const uint32_t* indices, size_t count, const WindowVertices& v,
                                 Rect scissor, uint32_t* out) {
  return keepCoveringTrianglesScalar(indices, count, v, scissor, out);
}
void projectVerticesAvx2(const float* positions, size_t count, const WindowTransform& t,
                         WindowVertices* out) {
  projectVerticesScalar(positions, count, t, out);
}

#endif  // DMMR_COVERAGE_AVX2

}  // namespace detail

size_t keepCoveringTriangles(const uint32_t* indices, size_t count, const WindowVertices& v,
                             Rect scissor, uint32_t* out) {
#if DMMR_COVERAGE_AVX2
  if (detail::haveAvx2()) return detail::keepCoveringTrianglesAvx2(indices, count, v, scissor, out);
#endif
  return detail::keepCoveringTrianglesScalar(indices, count, v, scissor, out);
}

}  // namespace dmmr
