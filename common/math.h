// Plain value types for geometry and cameras, in double precision.
// Conventions: column vectors, matrices stored column-major (m[col][row]),
// right-handed world; a camera looks down its local -Z with +Y up, as in OSG.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <ostream>

namespace dmmr {

struct Vec3d {
  double x = 0, y = 0, z = 0;
  constexpr Vec3d() = default;
  constexpr Vec3d(double x_, double y_, double z_) : x(x_), y(y_), z(z_) {}
  double& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
  double operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
  friend Vec3d operator+(Vec3d a, Vec3d b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
  friend Vec3d operator-(Vec3d a, Vec3d b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
  friend Vec3d operator-(Vec3d a) { return {-a.x, -a.y, -a.z}; }
  friend Vec3d operator*(Vec3d a, double s) { return {a.x * s, a.y * s, a.z * s}; }
  friend Vec3d operator*(double s, Vec3d a) { return a * s; }
  friend Vec3d operator/(Vec3d a, double s) { return {a.x / s, a.y / s, a.z / s}; }
  friend bool operator==(const Vec3d&, const Vec3d&) = default;
};
inline double dot(Vec3d a, Vec3d b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}
inline Vec3d cross(Vec3d a, Vec3d b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline double length(Vec3d a) {
  return std::sqrt(dot(a, a));
}
inline Vec3d normalize(Vec3d a) {
  return a / length(a);
}
inline Vec3d vmin(Vec3d a, Vec3d b) {
  return {std::fmin(a.x, b.x), std::fmin(a.y, b.y), std::fmin(a.z, b.z)};
}
inline Vec3d vmax(Vec3d a, Vec3d b) {
  return {std::fmax(a.x, b.x), std::fmax(a.y, b.y), std::fmax(a.z, b.z)};
}
inline bool isFinite(Vec3d a) {
  return std::isfinite(a.x) && std::isfinite(a.y) && std::isfinite(a.z);
}
std::ostream& operator<<(std::ostream& os, const Vec3d& v);

// Unit quaternion (x, y, z, w), same layout and meaning as osg::Quat.
struct Quatd {
  double x = 0, y = 0, z = 0, w = 1;
  friend bool operator==(const Quatd&, const Quatd&) = default;
};
Vec3d rotate(const Quatd& q, Vec3d v);
std::ostream& operator<<(std::ostream& os, const Quatd& q);

struct Mat4d {
  // m[c][r]: column c, row r.
  std::array<std::array<double, 4>, 4> m{};
  static Mat4d identity();
  static Mat4d translate(Vec3d t);
  static Mat4d scale(Vec3d s);
  static Mat4d rotation(const Quatd& q);
  // From 16 values in OSG's order (osg::Matrixd::ptr(), row-vector convention);
  // that memory layout equals our column-major layout for the same transform.
  static Mat4d fromOsgPtr(const double* p);
  double& at(int row, int col) { return m[col][row]; }
  double at(int row, int col) const { return m[col][row]; }
  Vec3d transformPoint(Vec3d p) const;   // assumes affine (last row 0 0 0 1)
  Vec3d transformVector(Vec3d v) const;  // linear part only
  // Largest factor by which the linear part stretches any vector (its
  // spectral norm, rounded up): a sphere's radius scales by at most this.
  double maxScale() const;
  friend Mat4d operator*(const Mat4d& a, const Mat4d& b);
  friend bool operator==(const Mat4d&, const Mat4d&) = default;
};
// Inverse of an affine matrix (last row 0 0 0 1). Returns false when singular.
bool invertAffine(const Mat4d& a, Mat4d* out);
std::ostream& operator<<(std::ostream& os, const Mat4d& m);

struct Box3d {
  Vec3d lo{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
           std::numeric_limits<double>::infinity()};
  Vec3d hi{-std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity(),
           -std::numeric_limits<double>::infinity()};
  bool valid() const { return lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z; }
  void expand(Vec3d p) {
    lo = vmin(lo, p);
    hi = vmax(hi, p);
  }
  void expand(const Box3d& b) {
    if (!b.valid()) return;
    lo = vmin(lo, b.lo);
    hi = vmax(hi, b.hi);
  }
  Vec3d center() const { return (lo + hi) * 0.5; }
  Vec3d extent() const { return hi - lo; }
  double volume() const {
    Vec3d e = extent();
    return valid() ? e.x * e.y * e.z : 0.0;
  }
  Vec3d corner(int i) const {
    return {(i & 1) ? hi.x : lo.x, (i & 2) ? hi.y : lo.y, (i & 4) ? hi.z : lo.z};
  }
  friend bool operator==(const Box3d&, const Box3d&) = default;
};
// The axis-aligned box enclosing the transformed corners of b.
Box3d transformBox(const Mat4d& m, const Box3d& b);
std::ostream& operator<<(std::ostream& os, const Box3d& b);

struct Sphere3d {
  Vec3d center;
  double radius = -1;
  bool valid() const { return radius >= 0; }
  double volume() const { return valid() ? 4.0 / 3.0 * M_PI * radius * radius * radius : 0.0; }
  friend bool operator==(const Sphere3d&, const Sphere3d&) = default;
};
std::ostream& operator<<(std::ostream& os, const Sphere3d& s);

// Plane n.p + d = 0; the positive side (n.p + d >= 0) is "inside".
struct Plane {
  Vec3d n;
  double d = 0;
  double distance(Vec3d p) const { return dot(n, p) + d; }
};

// Integer pixel rectangle, origin at the bottom-left as in GL.
struct Rect {
  int x = 0, y = 0, w = 0, h = 0;
  int x1() const { return x + w; }
  int y1() const { return y + h; }
  int64_t area() const { return int64_t(w) * h; }
  bool empty() const { return w <= 0 || h <= 0; }
  friend bool operator==(const Rect&, const Rect&) = default;
};
std::ostream& operator<<(std::ostream& os, const Rect& r);

// Whether `r` has no negative size and lies within a width x height frame,
// in 64-bit arithmetic: a peer's region near INT_MAX must fail the check,
// not overflow past it (x + w in int is undefined there).
inline bool insideFrame(const Rect& r, int width, int height) {
  return r.x >= 0 && r.y >= 0 && r.w >= 0 && r.h >= 0 && int64_t(r.x) + r.w <= width &&
         int64_t(r.y) + r.h <= height;
}

}  // namespace dmmr
