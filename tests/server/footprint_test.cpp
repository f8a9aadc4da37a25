// Tests for footprint() (server/divide.h): an object's pixel footprint holds
// every pixel its bounds project to through the shared camera's matrices
// (projectionMatrix * viewMatrix), also when the bounds cross the near plane,
// and is the same far from the origin. Random cameras and boxes come from
// fixed seeds.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "camera.h"
#include "divide.h"
#include "server_test_util.h"

namespace dmmr {
namespace {

using test::Rng;

struct View {
  Camera camera;
  int width = 0, height = 0;
};

View randomView(Rng& rng) {
  static const int sizes[][2] = {{640, 480}, {1024, 1024}, {203, 157}, {300, 900}, {7, 3}};
  const int* s = sizes[rng.integer(0, 4)];
  View v;
  v.width = s[0];
  v.height = s[1];
  v.camera.eye = {rng.real(-20, 20), rng.real(-20, 20), rng.real(-20, 20)};
  v.camera.rotation = rng.rotation();
  v.camera.fovy_deg = rng.real(20, 100);
  v.camera.aspect = double(v.width) / v.height;
  v.camera.near = rng.real(0.01, 2);
  return v;
}

// A world-space point from eye-space coordinates (the camera looks down -Z).
Vec3d fromEye(const Camera& c, Vec3d eye) {
  return c.eye + rotate(c.rotation, eye);
}

ObjectBounds boxBounds(Vec3d centre, Vec3d half, uint64_t weight = 1) {
  ObjectBounds o;
  o.box = Box3d{centre - half, centre + half};
  o.sphere = Sphere3d{centre, length(half)};
  o.use_box = true;
  o.weight = weight;
  return o;
}

// The footprint holds the pixel of window position (x, y), kept inside the
// frame (positions off the frame count at its nearest edge pixel).
::testing::AssertionResult holds(const Footprint& f, const test::Projected& q, int width,
                                 int height) {
  int px = test::pixelOf(q.x, width), py = test::pixelOf(q.y, height);
  if (px >= f.x0 && px < f.x1 && py >= f.y0 && py < f.y1) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << f << " misses the point at window (" << q.x << ", " << q.y
                                       << "), pixel (" << px << ", " << py << ")";
}

// Footprint `inner` lies within `outer`.
bool within(const Footprint& inner, const Footprint& outer) {
  return inner.x0 >= outer.x0 && inner.x1 <= outer.x1 && inner.y0 >= outer.y0 &&
         inner.y1 <= outer.y1;
}

TEST(Footprint, ABoxStraightAheadCoversItsProjectionPlusAOnePixelMargin) {
  Camera camera;  // at the origin looking down -Z
  camera.fovy_deg = 90;
  camera.aspect = 1;
  camera.near = 0.5;
  // The near face (1.1 units either side, 10 away, tan 45 = 1) spans window
  // 44.5..55.5 of 100: pixels 44..55 and, with the margin, 43..56.
  ObjectBounds o = boxBounds({0, 0, -11}, {1.1, 1.1, 1}, 77);
  Footprint f;
  ASSERT_TRUE(footprint(o, 3, camera, 100, 100, &f));
  Footprint want;
  want.object = 3;
  want.x0 = 43;
  want.x1 = 57;
  want.y0 = 43;
  want.y1 = 57;
  want.weight = 77;
  EXPECT_EQ(f, want);
}

TEST(Footprint, EveryCornerOfABoxInFrontLiesInsideTheFootprint) {
  Rng rng(11);
  int tested = 0, dropped = 0;
  for (int trial = 0; trial < 4000; ++trial) {
    View v = randomView(rng);
    const Camera& c = v.camera;
    double depth = rng.real(c.near, 60);
    double ty = std::tan(c.fovy_deg * M_PI / 360), tx = ty * c.aspect;
    // Centres mostly in view, some beside it.
    Vec3d centre = fromEye(c, {rng.real(-1.5, 1.5) * tx * depth, rng.real(-1.5, 1.5) * ty * depth,
                               -depth - rng.real(0, 5)});
    Vec3d half{rng.real(0.001, 4), rng.real(0.001, 4), rng.real(0.001, 4)};
    ObjectBounds o = boxBounds(centre, half);
    std::vector<test::Projected> corners;
    bool allInFront = true;
    for (int i = 0; i < 8; ++i) {
      corners.push_back(test::project(c, o.box.corner(i), v.width, v.height));
      allInFront = allInFront && corners.back().w >= c.near;
    }
    if (!allInFront) continue;
    ++tested;
    Footprint f;
    if (!footprint(o, uint32_t(trial), c, v.width, v.height, &f)) {
      // Dropped only when every corner lies beyond one edge of the frame.
      auto all = [&](auto pred) { return std::all_of(corners.begin(), corners.end(), pred); };
      EXPECT_TRUE(
          all([](auto& q) { return q.x < 0; }) || all([&](auto& q) { return q.x > v.width; }) ||
          all([](auto& q) { return q.y < 0; }) || all([&](auto& q) { return q.y > v.height; }))
          << "trial " << trial << ": " << o.box << " seen by " << c << " gave no footprint";
      ++dropped;
      continue;
    }
    EXPECT_EQ(f.object, uint32_t(trial));
    EXPECT_TRUE(f.x0 >= 0 && f.x0 < f.x1 && f.x1 <= v.width && f.y0 >= 0 && f.y0 < f.y1 &&
                f.y1 <= v.height)
        << f << " for a " << v.width << "x" << v.height << " frame";
    double xmin = INFINITY, xmax = -INFINITY, ymin = INFINITY, ymax = -INFINITY;
    for (const test::Projected& q : corners) {
      EXPECT_TRUE(holds(f, q, v.width, v.height)) << "trial " << trial;
      xmin = std::min(xmin, q.x);
      xmax = std::max(xmax, q.x);
      ymin = std::min(ymin, q.y);
      ymax = std::max(ymax, q.y);
    }
    // And it is tight: no more than the promised pixel of margin (plus one
    // for rounding) beyond the corners' projection.
    EXPECT_GE(f.x0, std::max(0.0, std::floor(xmin) - 2)) << "trial " << trial << " " << f;
    EXPECT_LE(f.x1, std::min(double(v.width), std::ceil(xmax) + 2)) << "trial " << trial;
    EXPECT_GE(f.y0, std::max(0.0, std::floor(ymin) - 2)) << "trial " << trial << " " << f;
    EXPECT_LE(f.y1, std::min(double(v.height), std::ceil(ymax) + 2)) << "trial " << trial;
  }
  EXPECT_GT(tested, 2000);
  EXPECT_GT(dropped, 0);  // some boxes beside the view were tried
  EXPECT_LT(dropped, tested / 2);
}

TEST(Footprint, ABoxCrossingTheNearPlaneCoversEveryPointInFrontOfIt) {
  Rng rng(12);
  int tested = 0;
  for (int trial = 0; trial < 1000; ++trial) {
    View v = randomView(rng);
    const Camera& c = v.camera;
    // Eye-space centre at about the near distance, extents reaching behind
    // the eye and well beside the view.
    Vec3d centreEye{rng.real(-3, 3), rng.real(-3, 3), -c.near + rng.real(-1, 1)};
    Vec3d halfEye{rng.real(0.01, 3), rng.real(0.01, 3), rng.real(0.01, 3)};
    // World box enclosing the rotated eye-space box.
    Box3d box;
    for (int i = 0; i < 8; ++i) {
      Vec3d e{(i & 1) ? halfEye.x : -halfEye.x, (i & 2) ? halfEye.y : -halfEye.y,
              (i & 4) ? halfEye.z : -halfEye.z};
      box.expand(fromEye(c, centreEye + e));
    }
    ObjectBounds o = boxBounds(box.center(), box.extent() * 0.5);
    Footprint f;
    bool has = footprint(o, 0, c, v.width, v.height, &f);
    int front = 0;
    for (int k = 0; k < 300; ++k) {
      Vec3d p = k < 8 ? o.box.corner(k) : rng.inBox(o.box);
      test::Projected q = test::project(c, p, v.width, v.height);
      if (q.w < c.near) continue;
      ++front;
      if (test::inView(c, p, v.width, v.height)) {
        ASSERT_TRUE(has) << "trial " << trial << ": a point of " << o.box << " is in view";
      }
      if (has) {
        EXPECT_TRUE(holds(f, q, v.width, v.height)) << "trial " << trial << " point " << p;
      }
    }
    tested += front > 0;
  }
  EXPECT_GT(tested, 500);
}

TEST(Footprint, ABoxEntirelyBehindTheCameraOrBeforeTheNearPlaneHasNone) {
  Rng rng(13);
  for (int trial = 0; trial < 1000; ++trial) {
    View v = randomView(rng);
    const Camera& c = v.camera;
    // Every corner at eye z > -near: behind the eye or between it and the
    // near plane. The world box must enclose the eye-space box, so keep the
    // eye-space box a little away from the plane.
    double h = rng.real(0.001, 0.2) * c.near;
    Vec3d centreEye{rng.real(-5, 5), rng.real(-5, 5),
                    trial % 2 ? rng.real(0, 20) : -c.near + 2 * h * 1.8};
    Box3d box;
    for (int i = 0; i < 8; ++i)
      box.expand(
          fromEye(c, centreEye + Vec3d{(i & 1) ? h : -h, (i & 2) ? h : -h, (i & 4) ? h : -h}));
    ObjectBounds o = boxBounds(box.center(), box.extent() * 0.5);
    bool anyInFront = false;
    for (int i = 0; i < 8; ++i)
      anyInFront = anyInFront || test::project(c, o.box.corner(i), 1, 1).w >= c.near;
    if (anyInFront) continue;  // the world box reached the near plane after all
    Footprint f;
    EXPECT_FALSE(footprint(o, 0, c, v.width, v.height, &f)) << "trial " << trial << " " << f;
  }
}

TEST(Footprint, AnInvalidBoxOrOneBesideTheViewHasNone) {
  Camera camera;
  camera.fovy_deg = 60;
  Footprint f;
  ObjectBounds empty;  // default box is invalid
  EXPECT_FALSE(footprint(empty, 0, camera, 64, 64, &f));
  EXPECT_FALSE(footprint(boxBounds({100, 0, -10}, {1, 1, 1}), 0, camera, 64, 64, &f));
  EXPECT_FALSE(footprint(boxBounds({0, -100, -10}, {1, 1, 1}), 0, camera, 64, 64, &f));
  EXPECT_TRUE(footprint(boxBounds({0, 0, -10}, {1, 1, 1}), 0, camera, 64, 64, &f));
}

TEST(Footprint, ATighterSphereShrinksTheFootprintButStillCoversTheObject) {
  Rng rng(14);
  int shrunk = 0;
  for (int trial = 0; trial < 1000; ++trial) {
    View v = randomView(rng);
    const Camera& c = v.camera;
    double depth = rng.real(c.near + 6, 60);
    double ty = std::tan(c.fovy_deg * M_PI / 360), tx = ty * c.aspect;
    Sphere3d s{
        fromEye(c, {rng.real(-0.8, 0.8) * tx * depth, rng.real(-0.8, 0.8) * ty * depth, -depth}),
        rng.real(0.1, 5)};
    // The object is the sphere cut by an axis-aligned plane through or above
    // its centre. Its box is the sphere's box clipped to the cut and, being
    // loose, grown along another axis; both the box and the sphere enclose
    // the object and together they are tighter than either.
    ObjectBounds o;
    Vec3d r{s.radius, s.radius, s.radius};
    o.box = Box3d{s.center - r, s.center + r};
    int axis = rng.integer(0, 2);
    o.box.hi[axis] = s.center[axis] + rng.real(0, 1) * s.radius;
    o.box.lo[(axis + 1) % 3] -= rng.real(0, 3);
    o.sphere = s;
    o.use_box = false;
    o.weight = 9;
    Footprint f, ofBox, ofSphereBox;
    ASSERT_TRUE(footprint(o, 1, c, v.width, v.height, &f)) << "trial " << trial;
    ASSERT_TRUE(footprint(boxBounds(o.box.center(), o.box.extent() * 0.5), 1, c, v.width, v.height,
                          &ofBox));
    ASSERT_TRUE(footprint(boxBounds(s.center, r), 1, c, v.width, v.height, &ofSphereBox));
    EXPECT_TRUE(within(f, ofBox)) << f << " vs box " << ofBox;
    EXPECT_TRUE(within(f, ofSphereBox)) << f << " vs sphere's box " << ofSphereBox;
    shrunk += f != ofBox;
    for (int k = 0; k < 100; ++k) {
      Vec3d p = rng.inSphere(s);
      if (p[axis] > o.box.hi[axis]) continue;
      EXPECT_TRUE(holds(f, test::project(c, p, v.width, v.height), v.width, v.height))
          << "trial " << trial << " point " << p;
    }
  }
  EXPECT_GT(shrunk, 0);
}

TEST(Footprint, FarFromTheOriginTheFootprintIsTheSameAsAtTheOrigin) {
  Rng rng(15);
  const Vec3d far{1e7, -1e7, 1e7};
  int compared = 0;
  for (int trial = 0; trial < 4000; ++trial) {
    View v = randomView(rng);
    const Camera& c = v.camera;
    double depth = rng.real(c.near + 5, 60);
    double ty = std::tan(c.fovy_deg * M_PI / 360), tx = ty * c.aspect;
    Vec3d centre = fromEye(c, {rng.real(-1, 1) * tx * depth, rng.real(-1, 1) * ty * depth, -depth});
    Vec3d half{rng.real(0.01, 4), rng.real(0.01, 4), rng.real(0.01, 4)};
    ObjectBounds o = boxBounds(centre, half, 5);
    Camera moved = c;
    moved.eye = c.eye + far;
    ObjectBounds o2 = boxBounds(centre + far, half, 5);
    Footprint a, b;
    bool ha = footprint(o, 2, c, v.width, v.height, &a);
    bool hb = footprint(o2, 2, moved, v.width, v.height, &b);
    ASSERT_EQ(ha, hb) << "trial " << trial;
    if (ha) {
      EXPECT_EQ(a, b) << "trial " << trial;
    }
    compared += ha;
  }
  EXPECT_GT(compared, 3000);
}

}  // namespace
}  // namespace dmmr
