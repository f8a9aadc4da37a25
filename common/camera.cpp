#include "camera.h"

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

}  // namespace dmmr
