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
  double divide_ms = 0;   // footprints and division
  double project_ms = 0;  // the footprints alone (part of divide_ms)
};

// Plans frames of one scene. Keeps a compact copy of what projection needs
// (each object's tight box and weight, 56 bytes instead of the whole bounds
// record), because projecting 10^5 objects a frame is bound by memory traffic.
class FramePlanner {
 public:
  explicit FramePlanner(const Scene& scene);
  FramePlan plan(const Camera& camera, int width, int height, int clients) const;

 private:
  // Footprints of the `visible` objects, in the same order (those covering no
  // pixel left out); computed on up to 8 threads for large lists.
  std::vector<Footprint> footprints(const std::vector<uint32_t>& visible, const Camera& camera,
                                    int width, int height) const;
  struct Projected {
    Box3d box;
    uint64_t weight;
  };
  const Scene& scene_;
  std::vector<Projected> boxes_;
};

// One-off convenience: builds a planner and plans one frame.
FramePlan planFrame(const Scene& scene, const Camera& camera, int width, int height, int clients);

}  // namespace dmmr
