#include "camera.h"

#include <algorithm>
#include <cmath>

namespace dmmr {

std::ostream& operator<<(std::ostream& os, const Camera& c) {
  return os << "camera[eye " << c.eye << " " << c.rotation << " fovy " << c.fovy_deg << " aspect "
            << c.aspect << " near " << c.near << "]";
}

Mat4d viewRotation(const Camera& c) {
  Mat4d r = Mat4d::rotation(c.rotation);
  Mat4d t = Mat4d::identity();
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) t.at(i, j) = r.at(j, i);  // inverse rotation = transpose
  return t;
}

Mat4d viewMatrix(const Camera& c) {
  return viewRotation(c) * Mat4d::translate(-c.eye);
}

Mat4d projectionMatrix(const Camera& c) {
  double f = 1.0 / std::tan(c.fovy_deg * M_PI / 360.0);
  Mat4d p;  // zero
  p.at(0, 0) = f / c.aspect;
  p.at(1, 1) = f;
  p.at(2, 3) = c.near;
  p.at(3, 2) = -1.0;
  return p;
}

std::array<Plane, 5> frustumPlanes(const Camera& c) {
  double ty = std::tan(c.fovy_deg * M_PI / 360.0);
  double tx = ty * c.aspect;
  // Eye-space planes: inside when n.p + d >= 0 (the camera looks down -Z).
  Plane eye[5] = {{{1, 0, -tx}, 0},
                  {{-1, 0, -tx}, 0},
                  {{0, 1, -ty}, 0},
                  {{0, -1, -ty}, 0},
                  {{0, 0, -1}, -c.near}};
  Mat4d r = Mat4d::rotation(c.rotation);
  std::array<Plane, 5> out;
  for (int i = 0; i < 5; ++i) {
    double len = length(eye[i].n);
    Vec3d n = r.transformVector(eye[i].n / len);
    out[i] = {n, eye[i].d / len - dot(n, c.eye)};
  }
  return out;
}

EntryDepthPlanes entryDepthPlanes(const Box3d& box, const Camera& c) {
  return entryDepthPlanes(box, c, Mat4d::rotation(c.rotation), std::tan(c.fovy_deg * M_PI / 360.0));
}

EntryDepthPlanes entryDepthPlanes(const Box3d& box, const Camera& c, const Mat4d& r, double ty) {
  // The ray through (ndc_x, ndc_y) has eye-space direction (ndc_x tx, ndc_y ty, -1),
  // so a point at eye distance t is eye + t d with d its world direction; the
  // slab face x_i = f is reached at t = (f - eye_i) / d_i, depth near / t.
  double tx = ty * c.aspect;
  EntryDepthPlanes p;
  for (int i = 0; i < 3; ++i) {
    double e = c.eye[i], face;
    if (e < box.lo[i])
      face = box.lo[i];
    else if (e > box.hi[i])
      face = box.hi[i];
    else {
      p.k[i] = {0, 0, kNoDepthBound};
      continue;
    }
    double s = c.near / (face - e);
    p.k[i] = {s * r.at(i, 0) * tx, s * r.at(i, 1) * ty, -s * r.at(i, 2)};
  }
  return p;
}

double entryDepth(const EntryDepthPlanes& p, double ndc_x, double ndc_y) {
  double d = kNoDepthBound;
  for (const auto& k : p.k) d = std::min(d, k[0] * ndc_x + k[1] * ndc_y + k[2]);
  return d;
}

}  // namespace dmmr
