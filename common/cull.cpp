#include "cull.h"

#include <algorithm>

namespace dmmr {

Planes shadowCasterPlanes(const Planes& view, Vec3d to_light) {
  Planes out = view;
  for (Plane& p : out)
    if (dot(p.n, to_light) < 0) p = Plane{{0, 0, 0}, 1};
  return out;
}

Containment classify(const Box3d& box, const Planes& planes) {
  if (!box.valid()) return Containment::Outside;
  bool inside = true;
  Vec3d c = box.center(), e = box.extent() * 0.5;
  for (const Plane& p : planes) {
    double d = p.distance(c);
    double r = std::fabs(p.n.x) * e.x + std::fabs(p.n.y) * e.y + std::fabs(p.n.z) * e.z;
    if (d < -r) return Containment::Outside;
    if (d < r) inside = false;
  }
  return inside ? Containment::Inside : Containment::Intersects;
}

Containment classify(const Sphere3d& s, const Planes& planes) {
  bool inside = true;
  for (const Plane& p : planes) {
    double d = p.distance(s.center);
    if (d < -s.radius) return Containment::Outside;
    if (d < s.radius) inside = false;
  }
  return inside ? Containment::Inside : Containment::Intersects;
}

void cullObjects(const std::vector<SkeletonNode>& skeleton,
                 const std::vector<ObjectBounds>& objects, const Planes& planes,
                 std::vector<uint32_t>* out, CullStats* stats) {
  size_t first = out->size();
  CullStats local;
  auto take = [&](uint32_t object) {
    out->push_back(object);
    ++local.objects;
    local.triangles += objects[object].weight;
  };
  uint32_t i = 0, n = uint32_t(skeleton.size());
  while (i < n) {
    const SkeletonNode& node = skeleton[i];
    ++local.nodes_visited;
    Containment c = classify(node.box, planes);
    if (c == Containment::Outside) {
      i = node.end;
      continue;
    }
    if (node.kind == NodeKind::Object) {
      const ObjectBounds& o = objects[node.object];
      if (c == Containment::Inside || o.use_box ||
          classify(o.sphere, planes) != Containment::Outside)
        take(node.object);
      i = node.end;
      continue;
    }
    if (c == Containment::Inside) {  // the whole subtree is in
      for (uint32_t k = i + 1; k < node.end; ++k)
        if (skeleton[k].kind == NodeKind::Object) take(skeleton[k].object);
      i = node.end;
      continue;
    }
    ++i;  // descend into the children
  }
  // Pre-order usually yields ascending indices already (the preprocessor
  // numbers objects in traversal order).
  if (!std::is_sorted(out->begin() + long(first), out->end()))
    std::sort(out->begin() + long(first), out->end());
  if (stats) {
    stats->nodes_visited += local.nodes_visited;
    stats->objects += local.objects;
    stats->triangles += local.triangles;
  }
}

}  // namespace dmmr
