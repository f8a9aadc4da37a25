#include "coverage.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace dmmr {

namespace {

// Float's unit roundoff. A float sum of n products of float-rounded factors
// is off by at most about (n + 1) u times the sum of the terms' magnitudes,
// whatever the order or contraction (FMA); 8 u covers the 4-term dot
// products of a vertex transform with room to spare.
constexpr double kU = 1.0 / (1 << 24);
constexpr double kDot = 8 * kU;

}  // namespace

void projectVertices(const float* positions, size_t count, const WindowTransform& t,
                     WindowVertices* out) {
  out->resize(count);
  double m[4][4], am[4][4];  // object to eye, by rows, and its magnitudes
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) {
      m[r][c] = t.object_to_eye.at(r, c);
      am[r][c] = std::fabs(m[r][c]);
    }
  double p[3][4], ap[3][4];  // the projection's x, y and w rows
  const int rows[3] = {0, 1, 3};
  for (int k = 0; k < 3; ++k)
    for (int r = 0; r < 4; ++r) {
      p[k][r] = t.projection.at(rows[k], r);
      ap[k][r] = std::fabs(p[k][r]);
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
  float big[3] = {0, 0, 0};
  const float top = std::numeric_limits<float>::max();
  for (size_t i = 0; i < count; ++i)
    for (int k = 0; k < 3; ++k) {
      const float a = std::fabs(positions[3 * i + size_t(k)]);
      big[k] = a > big[k] && a <= top ? a : big[k];
    }
  double mag[4];
  for (int r = 0; r < 4; ++r)
    mag[r] = am[r][0] * big[0] + am[r][1] * big[1] + am[r][2] * big[2] + am[r][3];
  double dc[3];
  for (int k = 0; k < 3; ++k)
    dc[k] =
        k_clip * (ap[k][0] * mag[0] + ap[k][1] * mag[1] + ap[k][2] * mag[2] + ap[k][3] * mag[3]);
  const double dw = dc[2];
  const double half_w = 0.5 * t.width, half_h = 0.5 * t.height;
  const double snap = std::ldexp(1.0, -std::max(0, t.subpixel_bits));
  const float inf = std::numeric_limits<float>::infinity();
  WindowVertex* o = out->data();
  for (size_t i = 0; i < count; ++i) {
    const double x = positions[3 * i], y = positions[3 * i + 1], z = positions[3 * i + 2];
    double e[4];
    for (int r = 0; r < 4; ++r) e[r] = m[r][0] * x + m[r][1] * y + m[r][2] * z + m[r][3];
    double c[3];
    for (int k = 0; k < 3; ++k)
      c[k] = p[k][0] * e[0] + p[k][1] * e[1] + p[k][2] * e[2] + p[k][3] * e[3];
    const double w = c[2];
    const double inv = 1 / w, nx = c[0] * inv, ny = c[1] * inv;
    const double anx = std::fabs(nx), any = std::fabs(ny);
    // The quotient's error from both operands' and its own rounding, then
    // the viewport transform's. 1 / (w - dw) <= (1 + 2 dw / w) / w where
    // w > 2 dw (checked below; otherwise the vertex is kept apart).
    const double inv_low = inv * (1 + 2 * dw * inv);
    const double dnx = (dc[0] + anx * dw) * inv_low + 2 * kU * anx;
    const double dny = (dc[1] + any * dw) * inv_low + 2 * kU * any;
    const double dx = (dnx + 4 * kU * (anx + 1)) * half_w;
    const double dy = (dny + 4 * kU * (any + 1)) * half_h;
    const double wx = (nx + 1) * half_w, wy = (ny + 1) * half_h;
    // Twice the bound, a whole snapping step (rounding moves a vertex by
    // half a step, truncation by up to one), and the rounding of the
    // position to float; the radius itself rounded up.
    double radius = 2 * (dx < dy ? dy : dx) + snap + (std::fabs(wx) + std::fabs(wy)) * 0x1p-23;
    radius *= 1 + 0x1p-20;
    WindowVertex v{float(wx), float(wy), float(radius), 0.f};
    // w > 2 dw is false for NaN too.
    if (!(w > 2 * dw) || !std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.radius))
      v = {0.f, 0.f, inf, 0.f};
    o[i] = v;
  }
}

namespace {
// floor(t) for |t| < 2^30 (a double's truncation of a positive value).
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
}  // namespace

size_t keepCoveringTriangles(const uint32_t* indices, size_t count, const WindowVertices& v,
                             Rect scissor, uint32_t* out) {
  const size_t n = v.size();
  // Pixel centres i + 0.5 for columns i in [x0, x1], rows likewise. A box
  // is first clamped to a pixel beyond the scissor on each side, which
  // keeps every centre it held there and the arithmetic small.
  const int64_t x0 = scissor.x, x1 = int64_t(scissor.x) + scissor.w - 1;
  const int64_t y0 = scissor.y, y1 = int64_t(scissor.y) + scissor.h - 1;
  const float lox = float(x0 - 2), hix = float(x1 + 3), loy = float(y0 - 2), hiy = float(y1 + 3);
  size_t kept = 0;
  for (size_t t = 0; t + 2 < count; t += 3) {
    const uint32_t a = indices[t], b = indices[t + 1], c = indices[t + 2];
    bool keep = true;
    if (a < n && b < n && c < n) {
      // By value, so that min and max compile to minss and maxss, not to
      // branches on the data.
      const WindowVertex va = v[a], vb = v[b], vc = v[c];
      // Finite positions; a radius of +inf widens the box to the clamp.
      const float r = max3(va.radius, vb.radius, vc.radius);
      const float lx = maxf(min3(va.x, vb.x, vc.x) - r, lox);
      const float hx = minf(max3(va.x, vb.x, vc.x) + r, hix);
      const float ly = maxf(min3(va.y, vb.y, vc.y) - r, loy);
      const float hy = minf(max3(va.y, vb.y, vc.y) + r, hiy);
      // The first centre column at or right of lx: ceil(lx - 0.5); the last
      // at or left of hx: floor(hx - 0.5). Computed in double: exact.
      const int64_t cx0 = std::max(-floorSmall(0.5 - double(lx)), x0);
      const int64_t cx1 = std::min(floorSmall(double(hx) - 0.5), x1);
      const int64_t cy0 = std::max(-floorSmall(0.5 - double(ly)), y0);
      const int64_t cy1 = std::min(floorSmall(double(hy) - 0.5), y1);
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

}  // namespace dmmr
