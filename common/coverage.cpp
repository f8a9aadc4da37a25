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
  out->x.resize(count);
  out->y.resize(count);
  out->radius.resize(count);
  const Mat4d& m = t.object_to_eye;
  const Mat4d& p = t.projection;
  const double half_w = 0.5 * t.width, half_h = 0.5 * t.height;
  const double snap = std::ldexp(1.0, -std::max(0, t.subpixel_bits));
  const double inf = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < count; ++i) {
    const double v[3] = {positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]};
    // Eye position and, per row, the float error bound of the GPU's product.
    double e[4], de[4];
    for (int r = 0; r < 4; ++r) {
      double sum = m.at(r, 3), mag = std::fabs(m.at(r, 3));
      for (int c = 0; c < 3; ++c) {
        sum += m.at(r, c) * v[c];
        mag += std::fabs(m.at(r, c) * v[c]);
      }
      e[r] = sum;
      de[r] = kDot * mag;
    }
    // Clip x, y, w, with the eye error carried through the projection.
    double c[3], dc[3];
    const int rows[3] = {0, 1, 3};
    for (int k = 0; k < 3; ++k) {
      double sum = 0, mag = 0, carried = 0;
      for (int r = 0; r < 4; ++r) {
        double a = p.at(rows[k], r);
        sum += a * e[r];
        mag += std::fabs(a) * (std::fabs(e[r]) + de[r]);
        carried += std::fabs(a) * de[r];
      }
      c[k] = sum;
      dc[k] = carried + kDot * mag;
    }
    const double w = c[2], dw = dc[2];
    if (!(w > 2 * dw) || !(w > 0) || !std::isfinite(w)) {
      out->x[i] = out->y[i] = 0;
      out->radius[i] = inf;
      continue;
    }
    const double nx = c[0] / w, ny = c[1] / w;
    // The quotient's error from both operands' and its own rounding, then
    // the viewport transform's.
    const double dnx = (dc[0] + std::fabs(nx) * dw) / (w - dw) + 2 * kU * std::fabs(nx);
    const double dny = (dc[1] + std::fabs(ny) * dw) / (w - dw) + 2 * kU * std::fabs(ny);
    const double dx = dnx * half_w + 4 * kU * (std::fabs(nx) + 1) * half_w;
    const double dy = dny * half_h + 4 * kU * (std::fabs(ny) + 1) * half_h;
    out->x[i] = (nx + 1) * half_w;
    out->y[i] = (ny + 1) * half_h;
    // Twice the bound, then a whole snapping step (rounding moves a vertex
    // by half a step, truncation by up to one).
    const double radius = 2 * std::max(dx, dy) + snap;
    out->radius[i] = std::isfinite(out->x[i]) && std::isfinite(out->y[i]) ? radius : inf;
  }
}

size_t keepCoveringTriangles(const uint32_t* indices, size_t count, const WindowVertices& v,
                             Rect scissor, uint32_t* out) {
  const size_t n = v.size();
  // Pixel centres i + 0.5 for columns i in [x0, x1], rows likewise.
  const double x0 = scissor.x, x1 = double(scissor.x1()) - 1;
  const double y0 = scissor.y, y1 = double(scissor.y1()) - 1;
  size_t kept = 0;
  for (size_t t = 0; t + 2 < count; t += 3) {
    const uint32_t a = indices[t], b = indices[t + 1], c = indices[t + 2];
    bool keep = true;
    if (a < n && b < n && c < n) {
      const double r = std::max({v.radius[a], v.radius[b], v.radius[c]});
      const double lx = std::min({v.x[a], v.x[b], v.x[c]}) - r;
      const double hx = std::max({v.x[a], v.x[b], v.x[c]}) + r;
      const double ly = std::min({v.y[a], v.y[b], v.y[c]}) - r;
      const double hy = std::max({v.y[a], v.y[b], v.y[c]}) + r;
      // The first and last centre columns and rows within the widened box
      // and the scissor; written so that NaN (an infinite radius) keeps.
      const double cx0 = std::max(std::ceil(lx - 0.5), x0),
                   cx1 = std::min(std::floor(hx - 0.5), x1);
      const double cy0 = std::max(std::ceil(ly - 0.5), y0),
                   cy1 = std::min(std::floor(hy - 0.5), y1);
      keep = !(cx0 > cx1 || cy0 > cy1);
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
