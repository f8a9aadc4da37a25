// Tests for classify() and cullObjects() (common/cull.h): hierarchical
// culling through random skeleton trees gives exactly what a brute-force test
// of every object against the five frustum planes gives, never drops an
// object with a point in view, and skips subtrees outside the view.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <vector>

#include "camera.h"
#include "cull.h"
#include "server_test_util.h"

namespace dmmr {
namespace {

using test::Rng;

// ---- brute-force references -------------------------------------------------

// Box against planes, corner by corner: outside when all 8 corners are behind
// one plane; inside when all are in front of every plane.
Containment bruteClassify(const Box3d& box, const Planes& planes) {
  if (!box.valid()) return Containment::Outside;
  bool inside = true;
  for (const Plane& p : planes) {
    int behind = 0;
    for (int i = 0; i < 8; ++i) behind += p.distance(box.corner(i)) < 0;
    if (behind == 8) return Containment::Outside;
    if (behind > 0) inside = false;
  }
  return inside ? Containment::Inside : Containment::Intersects;
}

bool sphereOutside(const Sphere3d& s, const Planes& planes) {
  for (const Plane& p : planes)
    if (p.distance(s.center) < -s.radius) return true;
  return false;
}

bool insideAll(const Planes& planes, Vec3d p) {
  for (const Plane& pl : planes)
    if (pl.distance(p) < 0) return false;
  return true;
}

// ---- random scenes ----------------------------------------------------------

struct World {
  std::vector<SkeletonNode> skeleton;
  std::vector<ObjectBounds> objects;
};

// An object near `centre`: a box object, or (one in three) a round one whose
// sphere is tighter than its box (the sphere's box, sometimes loose).
ObjectBounds randomObject(Rng& rng, Vec3d centre, double size) {
  ObjectBounds o;
  o.weight = uint64_t(rng.integer(0, 5000));
  if (rng.chance(1.0 / 3)) {
    o.sphere = Sphere3d{centre, rng.real(0.05, 1) * size};
    Vec3d r{o.sphere.radius, o.sphere.radius, o.sphere.radius};
    o.box = Box3d{centre - r, centre + r};
    if (rng.chance(0.5)) o.box.hi.x += rng.real(0, size);
    o.use_box = false;
  } else {
    Vec3d half{rng.real(0.02, 1) * size, rng.real(0.02, 1) * size, rng.real(0.02, 1) * size};
    o.box = Box3d{centre - half, centre + half};
    o.sphere = Sphere3d{centre, length(half)};
    o.use_box = true;
  }
  return o;
}

void buildNode(Rng& rng, World& w, uint32_t parent, int depth, Vec3d centre, double spread) {
  uint32_t index = uint32_t(w.skeleton.size());
  w.skeleton.emplace_back();
  w.skeleton[index].parent = parent;
  if (parent != kNone && (depth == 0 || rng.chance(0.15))) {
    w.skeleton[index].kind = NodeKind::Object;
    w.skeleton[index].object = uint32_t(w.objects.size());
    w.objects.push_back(randomObject(rng, centre, spread));
    w.skeleton[index].box = w.objects.back().box;
  } else {
    w.skeleton[index].kind = rng.chance(0.5) ? NodeKind::Group : NodeKind::Transform;
    // Some groups stay empty (an invalid box); the root has at least a child.
    int children = rng.integer(parent == kNone ? 1 : 0, 4);
    for (int k = 0; k < children; ++k) {
      Vec3d offset{rng.real(-1, 1), rng.real(-1, 1), rng.real(-1, 1)};
      buildNode(rng, w, index, depth - 1, centre + offset * spread, spread * 0.5);
    }
  }
  w.skeleton[index].end = uint32_t(w.skeleton.size());
}

// A random pre-order tree over about `depth` levels: correct parent and end
// links, every box enclosing its children's, object indices in shuffled
// order (so traversal order is not index order).
World randomWorld(Rng& rng, int depth, double spread) {
  World w;
  buildNode(rng, w, kNone, depth, {0, 0, 0}, spread);
  for (size_t i = w.skeleton.size(); i-- > 1;)
    w.skeleton[w.skeleton[i].parent].box.expand(w.skeleton[i].box);
  std::vector<uint32_t> perm(w.objects.size());
  std::iota(perm.begin(), perm.end(), 0u);
  rng.shuffle(perm);
  std::vector<ObjectBounds> shuffled(w.objects.size());
  for (size_t i = 0; i < perm.size(); ++i) shuffled[perm[i]] = w.objects[i];
  w.objects = shuffled;
  for (SkeletonNode& n : w.skeleton)
    if (n.kind == NodeKind::Object) n.object = perm[n.object];
  return w;
}

Camera randomCamera(Rng& rng, double spread) {
  Camera c;
  c.eye = {rng.real(-2, 2) * spread, rng.real(-2, 2) * spread, rng.real(-2, 2) * spread};
  c.rotation = rng.rotation();
  c.fovy_deg = rng.real(15, 100);
  c.aspect = rng.real(0.5, 2.5);
  c.near = rng.real(0.01, 1);
  return c;
}

// The objects a brute-force test of every object keeps: its box not outside
// the planes, and for round objects its sphere not outside either.
std::vector<uint32_t> bruteForceCull(const World& w, const Planes& planes) {
  std::vector<uint32_t> out;
  for (uint32_t i = 0; i < w.objects.size(); ++i) {
    const ObjectBounds& o = w.objects[i];
    if (bruteClassify(o.box, planes) == Containment::Outside) continue;
    if (!o.use_box && sphereOutside(o.sphere, planes)) continue;
    out.push_back(i);
  }
  return out;
}

// The nodes a hierarchical traversal must visit: those with no ancestor
// entirely outside or entirely inside the planes.
uint64_t bruteForceVisits(const World& w, const Planes& planes) {
  std::vector<Containment> c(w.skeleton.size());
  uint64_t visits = 0;
  for (size_t i = 0; i < w.skeleton.size(); ++i) {
    c[i] = bruteClassify(w.skeleton[i].box, planes);
    bool visited = true;
    for (uint32_t a = w.skeleton[i].parent; a != kNone; a = w.skeleton[a].parent)
      visited = visited && c[a] == Containment::Intersects;
    visits += visited;
  }
  return visits;
}

// ---- classify -----------------------------------------------------------------

TEST(Classify, BoxesAgainstASimpleFrustum) {
  Camera c;  // at the origin looking down -Z, 90 degrees, near 1
  c.fovy_deg = 90;
  c.near = 1;
  Planes planes = frustumPlanes(c);
  auto box = [](Vec3d centre, double h) {
    return Box3d{centre - Vec3d{h, h, h}, centre + Vec3d{h, h, h}};
  };
  EXPECT_EQ(classify(box({0, 0, -10}, 1), planes), Containment::Inside);
  EXPECT_EQ(classify(box({0, 0, -10}, 20), planes), Containment::Intersects);
  EXPECT_EQ(classify(box({0, 0, -1}, 0.5), planes), Containment::Intersects);   // near plane
  EXPECT_EQ(classify(box({9.5, 0, -10}, 1), planes), Containment::Intersects);  // right side
  EXPECT_EQ(classify(box({0, 0, 10}, 1), planes), Containment::Outside);        // behind
  EXPECT_EQ(classify(box({0, 0, -0.3}, 0.2), planes), Containment::Outside);    // before near
  EXPECT_EQ(classify(box({30, 0, -10}, 1), planes), Containment::Outside);
  EXPECT_EQ(classify(box({0, -30, -10}, 1), planes), Containment::Outside);
  EXPECT_EQ(classify(Box3d{}, planes), Containment::Outside);  // invalid
}

TEST(Classify, SpheresAgainstASimpleFrustum) {
  Camera c;
  c.fovy_deg = 90;
  c.near = 1;
  Planes planes = frustumPlanes(c);
  EXPECT_EQ(classify(Sphere3d{{0, 0, -10}, 1}, planes), Containment::Inside);
  EXPECT_EQ(classify(Sphere3d{{0, 0, -10}, 50}, planes), Containment::Intersects);
  EXPECT_EQ(classify(Sphere3d{{10, 0, -10}, 1}, planes), Containment::Intersects);
  EXPECT_EQ(classify(Sphere3d{{0, 0, 10}, 1}, planes), Containment::Outside);
  EXPECT_EQ(classify(Sphere3d{{20, 0, -10}, 1}, planes), Containment::Outside);
}

TEST(Classify, RandomBoxesAgreeWithTestingEveryCorner) {
  Rng rng(21);
  int counts[3] = {0, 0, 0};
  for (int trial = 0; trial < 20000; ++trial) {
    Camera c = randomCamera(rng, 10);
    Planes planes = frustumPlanes(c);
    Vec3d centre{rng.real(-30, 30), rng.real(-30, 30), rng.real(-30, 30)};
    Vec3d half{rng.real(0, 10), rng.real(0, 10), rng.real(0, 10)};
    Box3d box{centre - half, centre + half};
    Containment got = classify(box, planes);
    EXPECT_EQ(got, bruteClassify(box, planes)) << "trial " << trial << " " << box << " " << c;
    ++counts[int(got)];
  }
  for (int k = 0; k < 3; ++k) EXPECT_GT(counts[k], 500) << "containment " << k;
}

TEST(Classify, ASphereWithAPointInViewIsNotOutsideAndAnInsideOneHasAllPointsInView) {
  Rng rng(22);
  for (int trial = 0; trial < 3000; ++trial) {
    Camera c = randomCamera(rng, 10);
    Planes planes = frustumPlanes(c);
    Sphere3d s{{rng.real(-30, 30), rng.real(-30, 30), rng.real(-30, 30)}, rng.real(0.01, 10)};
    Containment got = classify(s, planes);
    for (int k = 0; k < 50; ++k) {
      Vec3d p = rng.inSphere(s);
      bool in = insideAll(planes, p);
      if (in) {
        EXPECT_NE(got, Containment::Outside) << "trial " << trial << " " << s;
      }
      if (got == Containment::Inside) {
        EXPECT_TRUE(in) << "trial " << trial << " " << s;
      }
    }
  }
}

// ---- cullObjects ----------------------------------------------------------------

TEST(CullObjects, RandomTreesCullExactlyAsTestingEveryObjectDoes) {
  Rng rng(23);
  uint64_t totalVisits = 0, totalNodes = 0, kept = 0, all = 0;
  for (int tree = 0; tree < 150; ++tree) {
    World w = randomWorld(rng, rng.integer(2, 7), 50);
    for (int view = 0; view < 8; ++view) {
      Camera c = randomCamera(rng, 50);
      Planes planes = frustumPlanes(c);
      std::vector<uint32_t> out;
      CullStats stats;
      cullObjects(w.skeleton, w.objects, planes, &out, &stats);
      SCOPED_TRACE(::testing::Message() << "tree " << tree << " view " << view << " "
                                        << w.skeleton.size() << " nodes " << c);
      EXPECT_TRUE(std::is_sorted(out.begin(), out.end()));
      EXPECT_EQ(std::adjacent_find(out.begin(), out.end()), out.end());
      EXPECT_EQ(out, bruteForceCull(w, planes));
      EXPECT_EQ(stats.nodes_visited, bruteForceVisits(w, planes));
      EXPECT_EQ(stats.objects, out.size());
      uint64_t triangles = 0;
      for (uint32_t o : out) triangles += w.objects[o].weight;
      EXPECT_EQ(stats.triangles, triangles);
      totalVisits += stats.nodes_visited;
      totalNodes += w.skeleton.size();
      kept += out.size();
      all += w.objects.size();
    }
  }
  // The views saw part of the scenes and the traversal skipped the rest.
  EXPECT_GT(kept, 0u);
  EXPECT_LT(kept, all);
  EXPECT_LT(totalVisits, totalNodes);
}

TEST(CullObjects, NoObjectWithAPointInViewIsDropped) {
  Rng rng(24);
  int seen = 0;
  for (int tree = 0; tree < 100; ++tree) {
    World w = randomWorld(rng, rng.integer(2, 6), 50);
    for (int view = 0; view < 10; ++view) {
      Camera c = randomCamera(rng, 50);
      std::vector<uint32_t> out;
      cullObjects(w.skeleton, w.objects, frustumPlanes(c), &out);
      for (uint32_t i = 0; i < w.objects.size(); ++i) {
        const ObjectBounds& o = w.objects[i];
        for (int k = 0; k < 40; ++k) {
          // A point of the object: in its box, and in its sphere when round.
          Vec3d p = o.use_box ? rng.inBox(o.box) : rng.inSphere(o.sphere);
          if (!o.use_box && !(p.x <= o.box.hi.x)) continue;
          if (!test::inView(c, p, 1, 1)) continue;
          ++seen;
          EXPECT_TRUE(std::binary_search(out.begin(), out.end(), i))
              << "tree " << tree << " view " << view << ": object " << i << " has point " << p
              << " in view of " << c << " but was culled";
          break;
        }
      }
    }
  }
  EXPECT_GT(seen, 1000);
}

// Two clusters far apart under their own groups; a camera looking at one
// visits the other's group node and nothing below it.
TEST(CullObjects, ASubtreeOutsideTheViewIsSkippedAfterItsRoot) {
  Rng rng(25);
  World left = randomWorld(rng, 5, 20), right = randomWorld(rng, 5, 20);
  World w;
  w.skeleton.push_back(SkeletonNode{});  // root group
  for (World* part : {&left, &right}) {
    double dx = part == &left ? -1000 : 1000;
    uint32_t base = uint32_t(w.skeleton.size()), objectBase = uint32_t(w.objects.size());
    for (SkeletonNode n : part->skeleton) {
      n.parent = n.parent == kNone ? 0 : n.parent + base;
      n.end += base;
      if (n.kind == NodeKind::Object) n.object += objectBase;
      if (n.box.valid()) n.box = Box3d{n.box.lo + Vec3d{dx, 0, 0}, n.box.hi + Vec3d{dx, 0, 0}};
      w.skeleton.push_back(n);
    }
    for (ObjectBounds o : part->objects) {
      o.box = Box3d{o.box.lo + Vec3d{dx, 0, 0}, o.box.hi + Vec3d{dx, 0, 0}};
      o.sphere.center = o.sphere.center + Vec3d{dx, 0, 0};
      w.objects.push_back(o);
    }
  }
  w.skeleton[0].end = uint32_t(w.skeleton.size());
  for (size_t i = 1; i < w.skeleton.size(); ++i)
    if (w.skeleton[i].parent == 0) w.skeleton[0].box.expand(w.skeleton[i].box);

  Camera c;  // 600 units in front of the right cluster, looking at it (-Z)
  c.eye = {1000, 0, 600};
  c.fovy_deg = 20;
  c.near = 0.1;
  Planes planes = frustumPlanes(c);
  std::vector<uint32_t> out;
  CullStats stats;
  cullObjects(w.skeleton, w.objects, planes, &out, &stats);
  EXPECT_EQ(out, bruteForceCull(w, planes));
  uint32_t leftRoot = 1, leftEnd = w.skeleton[1].end;
  ASSERT_EQ(classify(w.skeleton[leftRoot].box, planes), Containment::Outside);
  EXPECT_LE(stats.nodes_visited, w.skeleton.size() - (leftEnd - leftRoot - 1));
  for (uint32_t o : out) EXPECT_GE(o, uint32_t(left.objects.size())) << "a left object kept";
  // Everything on the right is in view and taken.
  EXPECT_EQ(out.size(), right.objects.size());
}

TEST(CullObjects, ASubtreeEntirelyInViewIsTakenWithoutVisitingIt) {
  Rng rng(26);
  World w = randomWorld(rng, 6, 10);
  Camera c;  // far back along +Z, looking at the whole scene
  c.eye = {0, 0, 500};
  c.fovy_deg = 30;
  Planes planes = frustumPlanes(c);
  ASSERT_EQ(classify(w.skeleton[0].box, planes), Containment::Inside);
  std::vector<uint32_t> out;
  CullStats stats;
  cullObjects(w.skeleton, w.objects, planes, &out, &stats);
  std::vector<uint32_t> every(w.objects.size());
  std::iota(every.begin(), every.end(), 0u);
  EXPECT_EQ(out, every);
  EXPECT_EQ(stats.nodes_visited, 1u);
}

TEST(CullObjects, AppendsAfterWhatIsAlreadyThereAndAddsToTheStats) {
  Rng rng(27);
  World w = randomWorld(rng, 5, 10);
  Camera c;
  c.eye = {0, 0, 40};
  c.fovy_deg = 40;
  Planes planes = frustumPlanes(c);
  std::vector<uint32_t> fresh;
  CullStats once;
  cullObjects(w.skeleton, w.objects, planes, &fresh, &once);
  ASSERT_FALSE(fresh.empty());

  std::vector<uint32_t> out = {99999, 3};
  CullStats stats{10, 20, 30};
  cullObjects(w.skeleton, w.objects, planes, &out, &stats);
  std::vector<uint32_t> want = {99999, 3};
  want.insert(want.end(), fresh.begin(), fresh.end());
  EXPECT_EQ(out, want);
  EXPECT_EQ(stats.nodes_visited, 10 + once.nodes_visited);
  EXPECT_EQ(stats.objects, 20 + once.objects);
  EXPECT_EQ(stats.triangles, 30 + once.triangles);
}

TEST(CullObjects, AnEmptySkeletonCullsNothing) {
  std::vector<uint32_t> out;
  CullStats stats;
  cullObjects({}, {}, frustumPlanes(Camera{}), &out, &stats);
  EXPECT_TRUE(out.empty());
  EXPECT_EQ(stats.nodes_visited, 0u);
}

// ---- shadow casters -----------------------------------------------------------

// Brute force: a box culled against the caster planes has no point from
// which a step back along -L (towards where the shadow falls) lands in view.
TEST(ShadowCasters, NoBoxThatShadowsAPointInViewIsCulled) {
  Rng rng(28);
  int culled = 0, kept_outside_view = 0, checked = 0;
  for (int trial = 0; trial < 4000; ++trial) {
    Camera c = randomCamera(rng, 10);
    Planes view = frustumPlanes(c);
    Vec3d light{rng.real(-1, 1), rng.real(-1, 1), rng.real(-1, 1)};
    if (length(light) < 0.1) continue;
    Planes casters = shadowCasterPlanes(view, light * rng.real(0.5, 3));
    Vec3d centre{rng.real(-40, 40), rng.real(-40, 40), rng.real(-40, 40)};
    Vec3d half{rng.real(0.1, 5), rng.real(0.1, 5), rng.real(0.1, 5)};
    Box3d box{centre - half, centre + half};
    bool cull = classify(box, casters) == Containment::Outside;
    if (!cull && classify(box, view) == Containment::Outside) ++kept_outside_view;
    if (!cull) continue;
    ++culled;
    for (int k = 0; k < 60; ++k) {
      Vec3d q = rng.inBox(box);
      for (double t : {0.0, 0.01, 0.1, 0.5, 1.0, 3.0, 10.0, 30.0, 100.0, 300.0, 1000.0}) {
        ++checked;
        Vec3d p = q - light * t;  // p + t L = q: q blocks p's way to the light
        ASSERT_FALSE(insideAll(view, p)) << "trial " << trial << " " << c << " box " << box
                                         << " light " << light << " shadows " << p;
      }
    }
  }
  // Not vacuous: many boxes are culled, and the sweep keeps boxes outside
  // the view (casters the frustum test alone would have dropped).
  EXPECT_GT(culled, 500);
  EXPECT_GT(kept_outside_view, 200);
  EXPECT_GT(checked, 100000);
}

TEST(ShadowCasters, ASideLightKeepsWhatLiesBetweenTheViewAndTheLight) {
  Camera c;  // at the origin, looking down -Z
  c.fovy_deg = 60;
  c.aspect = 1;
  c.near = 0.1;
  Planes casters = shadowCasterPlanes(frustumPlanes(c), {1, 0, 0});  // the light towards +X
  auto kept = [&](Vec3d centre) {
    return classify(Box3d{centre - Vec3d{0.5, 0.5, 0.5}, centre + Vec3d{0.5, 0.5, 0.5}}, casters) !=
           Containment::Outside;
  };
  EXPECT_TRUE(kept({0, 0, -10}));      // in view
  EXPECT_TRUE(kept({100, 0, -10}));    // out of view, between the view and the light
  EXPECT_FALSE(kept({-100, 0, -10}));  // on the far side: its shadow falls away from the view
  EXPECT_FALSE(kept({0, 100, -10}));   // above: its shadow runs along +X, above the view
  EXPECT_FALSE(kept({0, 0, 10}));      // behind the eye
}

}  // namespace
}  // namespace dmmr
