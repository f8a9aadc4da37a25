// Hierarchical frustum culling through the skeleton. Pure: plain data in,
// object indices out; no MPI, no GL.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "camera.h"
#include "formats.h"

namespace dmmr {

// The planes of a (sub-)frustum, inside when distance >= 0.
using Planes = std::array<Plane, 5>;

// Shadow casters of a directional light: planes that every object able to
// block the way from a point inside `view` towards the light (direction
// `to_light`, world space, any length) is not entirely outside. A box B
// shadows P when P + t L lies in B for some t >= 0, that is when P lies in B
// swept along -L. That swept volume is outside the plane (n, d) when B is and
// n . L >= 0 (sweeping only moves it further out); against a plane with
// n . L < 0 it always reaches the inside. So those planes are dropped
// (replaced by one no point is outside). Conservative: culling with the
// result (cullObjects) keeps every caster, and some objects that are not.
Planes shadowCasterPlanes(const Planes& view, Vec3d to_light);

enum class Containment { Outside, Intersects, Inside };
Containment classify(const Box3d& box, const Planes& planes);
Containment classify(const Sphere3d& s, const Planes& planes);

struct CullStats {
  uint64_t nodes_visited = 0;
  uint64_t objects = 0;
  uint64_t triangles = 0;
};

// Appends to `out`, in ascending order, every object whose bounding volume
// (box, and sphere where it is the tighter one) is not entirely outside the
// planes. Subtrees whose box is outside are skipped; subtrees entirely inside
// are taken without further tests. Conservative: nothing that can show is
// dropped.
void cullObjects(const std::vector<SkeletonNode>& skeleton,
                 const std::vector<ObjectBounds>& objects, const Planes& planes,
                 std::vector<uint32_t>* out, CullStats* stats = nullptr);

}  // namespace dmmr
