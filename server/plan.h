// One frame's work on the server, without MPI: frustum culling, footprints,
// division into one region and object list per client.
#pragma once

#include <vector>

#include "cull.h"
#include "divide.h"
#include "scene.h"

namespace dmmr {

struct FramePlan {
  std::vector<Region> regions;  // one per client, tiling the frame
  uint64_t objects_in_frustum = 0;
  uint64_t triangles_in_frustum = 0;
  double cull_ms = 0;
  double divide_ms = 0;  // footprints and division
};

FramePlan planFrame(const Scene& scene, const Camera& camera, int width, int height, int clients);

}  // namespace dmmr
