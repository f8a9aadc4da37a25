// A dmmr client (ranks 1..N). Two stages on two GL contexts and threads, as
// in the DMMR paper: visibility (occluders and occlusion queries, context 1)
// and render (the visible list into the region, context 2), fed by bounded
// queues, so that while the server plans frame i the client tests frame i-1
// and draws frame i-2.
#pragma once

#include <string>

#include "budget.h"
#include "camera.h"
#include "compress.h"
#include "gl_context.h"
#include "mpi_comm.h"
#include "raytrace.h"
#include "visibility.h"

namespace dmmr {

struct ClientOptions {
  std::string scene;
  ViewOptions view;
  ContextOptions visibility_context;  // context 1
  ContextOptions render_context;      // context 2
  VisibilityOptions visibility;
  Codec codec = Codec::LZ4;
  CacheOptions cache;
  // Heap to pre-touch once the scene is loaded (preTouchHeap): MiB, 0 none,
  // -1 auto (--pre-touch; preTouchBytes).
  int64_t pre_touch_mib = -1;
  // Flush the GL stages' drawing every this many triangles (Renderer::
  // setFlushEvery; 0: never; -1: the driver's default, defaultFlushTriangles).
  int64_t flush_triangles = -1;
  // Exact triangle culling in the GL stages (Renderer::setTriangleCull;
  // -1: the driver's default, defaultTriangleCull; 0 off; 1 on).
  int triangle_cull = -1;
  int rank = 0;  // set by runClient, for log lines
  // Benchmark mode: when set, every GL stage holds an exclusive lock on this
  // file while it works on a job (stage_turns.h), so stages run one at a time.
  std::string stage_turns;
  // Ray-trace instead of rasterising (raytrace.h): no GL context at all; the
  // render stage traces the region's objects (no occlusion culling: a ray
  // finds the nearest surface itself), their BVHs in the device level under
  // cache.gpu_budget.
  bool raytrace = false;
  RayOptions ray;
  // Threads the ray tracer traces on, the render stage's own included (0:
  // every CPU the process may use). 1 traces on the stage thread alone, so
  // that its CPU time (render_cpu_ms) is the whole cost, free of waiting
  // for a core (the benchmarks' contention-free mode).
  int ray_threads = 0;
  // Objects that reflect (mirror) or refract (glass) under ray.reflections,
  // by node name (effects.h).
  std::vector<std::string> mirror, glass;
};

// Runs until the server says Shutdown. Returns the process exit status.
int runClient(Comm& comm, const ClientOptions& opts);

}  // namespace dmmr
