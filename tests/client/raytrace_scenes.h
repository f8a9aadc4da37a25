// Hand-made scenes for the ray tracer's tests (raytrace_test.cpp,
// raytrace_raster_test.cpp): meshes built directly as GeometryData, cameras
// aimed at a point, and the analytic ray maths the tests predict pixels with.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "camera.h"
#include "formats.h"
#include "math.h"

namespace dmmr::rtscenes {

inline SubMesh submesh(uint32_t first, uint32_t count, float r, float g, float b,
                       int32_t texture = -1) {
  SubMesh s;
  s.first_index = first;
  s.index_count = count;
  s.diffuse[0] = r;
  s.diffuse[1] = g;
  s.diffuse[2] = b;
  s.diffuse[3] = 1.f;
  s.texture = texture;
  return s;
}

// The box [lo, hi]: 6 faces of 4 vertices, outward normals (or none), faces
// wound counter-clockwise seen from outside, one submesh in colour (r, g, b).
// With `colours`, each vertex gets a colour from its corner, so shading
// varies across faces.
inline GeometryData box(Vec3d lo, Vec3d hi, float r, float g, float b, bool normals = true,
                        bool colours = false) {
  GeometryData m;
  // Each face: its normal axis and sign; corners in counter-clockwise order.
  const int axes[6] = {0, 0, 1, 1, 2, 2};
  const int signs[6] = {-1, 1, -1, 1, -1, 1};
  for (int f = 0; f < 6; ++f) {
    int a = axes[f], u = (a + 1) % 3, v = (a + 2) % 3;
    int s = signs[f];
    double uv[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    uint32_t base = uint32_t(m.vertexCount());
    for (int k = 0; k < 4; ++k) {
      // For a negative face, swap the direction of u so the winding flips.
      double cu = s > 0 ? uv[k][0] : uv[k][1], cv = s > 0 ? uv[k][1] : uv[k][0];
      Vec3d p;
      p[a] = s > 0 ? hi[a] : lo[a];
      p[u] = lo[u] + cu * (hi[u] - lo[u]);
      p[v] = lo[v] + cv * (hi[v] - lo[v]);
      m.positions.insert(m.positions.end(), {float(p.x), float(p.y), float(p.z)});
      if (normals) {
        float n[3] = {0, 0, 0};
        n[a] = float(s);
        m.normals.insert(m.normals.end(), {n[0], n[1], n[2]});
      }
      if (colours)
        m.colors.insert(m.colors.end(), {uint8_t(p.x > (lo.x + hi.x) / 2 ? 255 : 120),
                                         uint8_t(p.y > (lo.y + hi.y) / 2 ? 255 : 90),
                                         uint8_t(p.z > (lo.z + hi.z) / 2 ? 230 : 60), 255});
    }
    m.indices.insert(m.indices.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
  }
  m.submeshes = {submesh(0, uint32_t(m.indices.size()), r, g, b)};
  return m;
}

// A quad in the plane z = 0 over [x0, x1] x [y0, y1], normal +Z, texture
// coordinates from (s0, t0) at (x0, y0) to (s1, t1) at (x1, y1).
inline GeometryData quad(double x0, double x1, double y0, double y1, float r, float g, float b,
                         int32_t texture = -1, float s0 = 0, float s1 = 1, float t0 = 0,
                         float t1 = 1) {
  GeometryData m;
  m.positions = {float(x0), float(y0), 0, float(x1), float(y0), 0,
                 float(x1), float(y1), 0, float(x0), float(y1), 0};
  m.normals = {0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1};
  if (texture >= 0) m.texcoords = {s0, t0, s1, t0, s1, t1, s0, t1};
  m.indices = {0, 1, 2, 0, 2, 3};
  m.submeshes = {submesh(0, 6, r, g, b, texture)};
  return m;
}

// An n x n grid of 2 n^2 triangles over [0, 1]^2 with a bumpy height (for
// memory measurements; no normals).
inline GeometryData grid(int n) {
  GeometryData m;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      double x = double(i) / n, y = double(j) / n;
      m.positions.insert(m.positions.end(),
                         {float(x), float(y), float(0.05 * std::sin(17 * x) * std::cos(13 * y))});
    }
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      uint32_t a = uint32_t(j * (n + 1) + i), b = a + 1, c = a + uint32_t(n + 1), d = c + 1;
      m.indices.insert(m.indices.end(), {a, b, d, a, d, c});
    }
  m.submeshes = {submesh(0, uint32_t(m.indices.size()), 0.7f, 0.7f, 0.7f)};
  return m;
}

// The rotation taking the camera's -Z to `forward` with +Y towards `up`.
inline Quatd lookRotation(Vec3d forward, Vec3d up) {
  Vec3d z = normalize(-forward);
  Vec3d x = normalize(cross(up, z));
  Vec3d y = cross(z, x);
  // Rotation matrix columns x, y, z; to a quaternion (Shepperd's method).
  double m[3][3] = {{x.x, y.x, z.x}, {x.y, y.y, z.y}, {x.z, y.z, z.z}};  // m[row][col]
  double tr = m[0][0] + m[1][1] + m[2][2];
  Quatd q;
  if (tr > 0) {
    double s = std::sqrt(tr + 1.0) * 2;
    q = {(m[2][1] - m[1][2]) / s, (m[0][2] - m[2][0]) / s, (m[1][0] - m[0][1]) / s, 0.25 * s};
  } else if (m[0][0] > m[1][1] && m[0][0] > m[2][2]) {
    double s = std::sqrt(1.0 + m[0][0] - m[1][1] - m[2][2]) * 2;
    q = {0.25 * s, (m[0][1] + m[1][0]) / s, (m[0][2] + m[2][0]) / s, (m[2][1] - m[1][2]) / s};
  } else if (m[1][1] > m[2][2]) {
    double s = std::sqrt(1.0 + m[1][1] - m[0][0] - m[2][2]) * 2;
    q = {(m[0][1] + m[1][0]) / s, 0.25 * s, (m[1][2] + m[2][1]) / s, (m[0][2] - m[2][0]) / s};
  } else {
    double s = std::sqrt(1.0 + m[2][2] - m[0][0] - m[1][1]) * 2;
    q = {(m[0][2] + m[2][0]) / s, (m[1][2] + m[2][1]) / s, 0.25 * s, (m[1][0] - m[0][1]) / s};
  }
  return q;
}

inline Camera lookAt(Vec3d eye, Vec3d target, int width, int height, Vec3d up = {0, 0, 1},
                     double fovy = 45, double near = 0.05) {
  return Camera{eye, lookRotation(target - eye, up), fovy, double(width) / height, near};
}

// The world direction of the ray through pixel (x, y)'s centre (y from the
// bottom row), the ray tracer's and the rasteriser's sample point.
inline Vec3d pixelRay(const Camera& c, int width, int height, int x, int y) {
  double ty = std::tan(c.fovy_deg * M_PI / 360.0), tx = ty * c.aspect;
  Vec3d d{((x + 0.5) / width * 2 - 1) * tx, ((y + 0.5) / height * 2 - 1) * ty, -1};
  return rotate(c.rotation, d);
}

// Where the ray o + t d (t > 0) enters `b`, or +inf when it misses.
inline double rayBox(Vec3d o, Vec3d d, const Box3d& b) {
  double t0 = 0, t1 = std::numeric_limits<double>::infinity();
  for (int i = 0; i < 3; ++i) {
    if (d[i] == 0) {
      if (o[i] < b.lo[i] || o[i] > b.hi[i]) return std::numeric_limits<double>::infinity();
      continue;
    }
    double a = (b.lo[i] - o[i]) / d[i], c = (b.hi[i] - o[i]) / d[i];
    t0 = std::max(t0, std::min(a, c));
    t1 = std::min(t1, std::max(a, c));
  }
  return t0 <= t1 ? t0 : std::numeric_limits<double>::infinity();
}

inline Box3d makeBox(Vec3d lo, Vec3d hi) {
  Box3d b;
  b.lo = lo;
  b.hi = hi;
  return b;
}

inline Box3d grow(const Box3d& b, double m) {
  return makeBox(b.lo - Vec3d{m, m, m}, b.hi + Vec3d{m, m, m});
}

// GL's UNORM8 value of a float colour channel.
inline int unorm8(double v) {
  return int(std::min(std::max(v, 0.0), 1.0) * 255 + 0.5);
}

}  // namespace dmmr::rtscenes
