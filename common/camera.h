// The camera every renderer shares: a perspective view with reversed-Z and an
// infinite far plane, so depth precision holds from centimetres to kilometres.
#pragma once

#include <array>

#include "math.h"
#include "walkthrough.h"

namespace dmmr {

struct Camera {
  Vec3d eye;
  Quatd rotation;        // camera-to-world rotation (looks down local -Z)
  double fovy_deg = 45;  // vertical field of view
  double aspect = 1;     // width / height
  double near = 0.1;     // near plane distance (> 0)
  friend bool operator==(const Camera&, const Camera&) = default;
};
std::ostream& operator<<(std::ostream& os, const Camera& c);

// Camera rotation only (no translation): world-to-eye for directions. The
// translation stays separate so that object positions can be made camera
// relative in double before any float conversion.
Mat4d viewRotation(const Camera& c);
// Full world-to-eye matrix.
Mat4d viewMatrix(const Camera& c);
// Reversed-Z infinite perspective for a [0,1] clip range (glClipControl
// GL_ZERO_TO_ONE): depth = near / distance, 1 at the near plane, 0 at infinity.
Mat4d projectionMatrix(const Camera& c);

// World-space frustum planes (left, right, bottom, top, near); the far plane is
// at infinity and omitted. Points on the inside have distance >= 0.
std::array<Plane, 5> frustumPlanes(const Camera& c);

// The depth (near / eye distance, as the projection writes it) at which the
// ray through a point of the image first enters `box`, as three linear
// functions of the point's normalised device coordinates, one per world axis:
// depth_i = k[i][0] * ndc_x + k[i][1] * ndc_y + k[i][2]. Along a ray the box
// is entered where the last of the three slabs is, so the entry depth is the
// smallest of the three (entryDepth). An axis whose slab holds the eye sets no
// bound (0, 0, kNoDepthBound). A value <= 0 means the ray never enters that
// slab, so it misses the box. Renderers clamp each fragment's depth to this
// bound (see draw.h), which makes "a box lies in front of what it encloses"
// hold for every fragment the rasteriser makes, slivers included.
struct EntryDepthPlanes {
  std::array<std::array<double, 3>, 3> k{};
  friend bool operator==(const EntryDepthPlanes&, const EntryDepthPlanes&) = default;
};
inline constexpr double kNoDepthBound = 1e30;
// `box` valid; the eye may be anywhere (inside on every axis: no bound at all).
EntryDepthPlanes entryDepthPlanes(const Box3d& box, const Camera& c);
// The same with the camera-to-world rotation (Mat4d::rotation(c.rotation))
// and tan(fovy / 2) worked out by the caller, once for many boxes.
EntryDepthPlanes entryDepthPlanes(const Box3d& box, const Camera& c, const Mat4d& camera_to_world,
                                  double tan_half_fovy);
double entryDepth(const EntryDepthPlanes& p, double ndc_x, double ndc_y);

}  // namespace dmmr

namespace dmmr {
// Image and camera settings every renderer of a run must share.
struct ViewOptions {
  int width = 1024;
  int height = 1024;
  double fovy_deg = 45;
  double near = 0;  // 0: the scene's default (see defaultNear in scene.h)
};

// The camera for one walkthrough control point and an image size.
inline Camera cameraAt(const ControlPoint& p, int width, int height, double fovy_deg, double near) {
  return Camera{p.position, p.rotation, fovy_deg, double(width) / double(height), near};
}
}  // namespace dmmr
