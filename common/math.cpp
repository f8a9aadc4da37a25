#include "math.h"

#include <algorithm>

namespace dmmr {

std::ostream& operator<<(std::ostream& os, const Vec3d& v) {
  return os << "(" << v.x << ", " << v.y << ", " << v.z << ")";
}
std::ostream& operator<<(std::ostream& os, const Quatd& q) {
  return os << "quat(" << q.x << ", " << q.y << ", " << q.z << ", " << q.w << ")";
}
std::ostream& operator<<(std::ostream& os, const Box3d& b) {
  return os << "box[" << b.lo << " - " << b.hi << "]";
}
std::ostream& operator<<(std::ostream& os, const Sphere3d& s) {
  return os << "sphere[" << s.center << " r=" << s.radius << "]";
}
std::ostream& operator<<(std::ostream& os, const Rect& r) {
  return os << "rect[" << r.x << "," << r.y << " " << r.w << "x" << r.h << "]";
}
std::ostream& operator<<(std::ostream& os, const Mat4d& m) {
  os << "mat[";
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) os << m.at(r, c) << (c < 3 ? " " : "");
    os << (r < 3 ? "; " : "]");
  }
  return os;
}

Vec3d rotate(const Quatd& q, Vec3d v) {
  // v' = v + 2w (u x v) + 2 u x (u x v), u = (x, y, z).
  Vec3d u{q.x, q.y, q.z};
  Vec3d t = cross(u, v) * 2.0;
  return v + t * q.w + cross(u, t);
}

Mat4d Mat4d::identity() {
  Mat4d r;
  for (int i = 0; i < 4; ++i) r.m[i][i] = 1;
  return r;
}
Mat4d Mat4d::translate(Vec3d t) {
  Mat4d r = identity();
  r.m[3][0] = t.x;
  r.m[3][1] = t.y;
  r.m[3][2] = t.z;
  return r;
}
Mat4d Mat4d::scale(Vec3d s) {
  Mat4d r = identity();
  r.m[0][0] = s.x;
  r.m[1][1] = s.y;
  r.m[2][2] = s.z;
  return r;
}
Mat4d Mat4d::rotation(const Quatd& q) {
  Mat4d r = identity();
  Vec3d cols[3] = {rotate(q, {1, 0, 0}), rotate(q, {0, 1, 0}), rotate(q, {0, 0, 1})};
  for (int c = 0; c < 3; ++c)
    for (int k = 0; k < 3; ++k) r.m[c][k] = cols[c][k];
  return r;
}
Mat4d Mat4d::fromOsgPtr(const double* p) {
  Mat4d r;
  for (int c = 0; c < 4; ++c)
    for (int k = 0; k < 4; ++k) r.m[c][k] = p[c * 4 + k];
  return r;
}
Vec3d Mat4d::transformPoint(Vec3d p) const {
  return {m[0][0] * p.x + m[1][0] * p.y + m[2][0] * p.z + m[3][0],
          m[0][1] * p.x + m[1][1] * p.y + m[2][1] * p.z + m[3][1],
          m[0][2] * p.x + m[1][2] * p.y + m[2][2] * p.z + m[3][2]};
}
Vec3d Mat4d::transformVector(Vec3d v) const {
  return {m[0][0] * v.x + m[1][0] * v.y + m[2][0] * v.z,
          m[0][1] * v.x + m[1][1] * v.y + m[2][1] * v.z,
          m[0][2] * v.x + m[1][2] * v.y + m[2][2] * v.z};
}
double Mat4d::maxScale() const {
  // Spectral norm of the 3x3 part: sqrt of the largest eigenvalue of A^T A,
  // in closed form for symmetric 3x3 matrices, nudged up to stay conservative.
  // The closed form loses precision in acos near -1, when the two largest
  // eigenvalues nearly coincide: it then returns up to ~1e-8 too little.
  double a[3][3];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      double s = 0;
      for (int k = 0; k < 3; ++k) s += at(k, i) * at(k, j);
      a[i][j] = s;
    }
  double p1 = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
  double q = (a[0][0] + a[1][1] + a[2][2]) / 3;
  double p2 = (a[0][0] - q) * (a[0][0] - q) + (a[1][1] - q) * (a[1][1] - q) +
              (a[2][2] - q) * (a[2][2] - q) + 2 * p1;
  double top;
  if (p2 <= 1e-30 * q * q) {
    top = std::max({a[0][0], a[1][1], a[2][2]});
  } else {
    double p = std::sqrt(p2 / 6);
    double b[3][3];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) b[i][j] = (a[i][j] - (i == j ? q : 0)) / p;
    double det = b[0][0] * (b[1][1] * b[2][2] - b[1][2] * b[2][1]) -
                 b[0][1] * (b[1][0] * b[2][2] - b[1][2] * b[2][0]) +
                 b[0][2] * (b[1][0] * b[2][1] - b[1][1] * b[2][0]);
    double phi = std::acos(std::clamp(det / 2, -1.0, 1.0)) / 3;
    top = q + 2 * p * std::cos(phi);
  }
  return std::sqrt(std::max(top, 0.0)) * (1 + 1e-7);
}

Mat4d operator*(const Mat4d& a, const Mat4d& b) {
  Mat4d r;
  for (int c = 0; c < 4; ++c)
    for (int k = 0; k < 4; ++k) {
      double s = 0;
      for (int i = 0; i < 4; ++i) s += a.m[i][k] * b.m[c][i];
      r.m[c][k] = s;
    }
  return r;
}

bool invertAffine(const Mat4d& a, Mat4d* out) {
  // Inverse of the 3x3 block by cofactors, then the translation.
  auto A = [&](int r, int c) { return a.at(r, c); };
  double c00 = A(1, 1) * A(2, 2) - A(1, 2) * A(2, 1);
  double c01 = A(1, 2) * A(2, 0) - A(1, 0) * A(2, 2);
  double c02 = A(1, 0) * A(2, 1) - A(1, 1) * A(2, 0);
  double det = A(0, 0) * c00 + A(0, 1) * c01 + A(0, 2) * c02;
  if (det == 0 || !std::isfinite(det)) return false;
  double inv = 1.0 / det;
  Mat4d r = Mat4d::identity();
  r.at(0, 0) = c00 * inv;
  r.at(0, 1) = (A(0, 2) * A(2, 1) - A(0, 1) * A(2, 2)) * inv;
  r.at(0, 2) = (A(0, 1) * A(1, 2) - A(0, 2) * A(1, 1)) * inv;
  r.at(1, 0) = c01 * inv;
  r.at(1, 1) = (A(0, 0) * A(2, 2) - A(0, 2) * A(2, 0)) * inv;
  r.at(1, 2) = (A(0, 2) * A(1, 0) - A(0, 0) * A(1, 2)) * inv;
  r.at(2, 0) = c02 * inv;
  r.at(2, 1) = (A(0, 1) * A(2, 0) - A(0, 0) * A(2, 1)) * inv;
  r.at(2, 2) = (A(0, 0) * A(1, 1) - A(0, 1) * A(1, 0)) * inv;
  Vec3d t{A(0, 3), A(1, 3), A(2, 3)};
  Vec3d nt = -r.transformVector(t);
  r.at(0, 3) = nt.x;
  r.at(1, 3) = nt.y;
  r.at(2, 3) = nt.z;
  *out = r;
  return true;
}

Box3d transformBox(const Mat4d& m, const Box3d& b) {
  Box3d r;
  if (!b.valid()) return r;
  for (int i = 0; i < 8; ++i) r.expand(m.transformPoint(b.corner(i)));
  return r;
}

}  // namespace dmmr
