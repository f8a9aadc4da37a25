// dmmr-reference: the brute-force ground truth. Renders every frame of a
// walkthrough in one process, every object, no culling at all, with the
// drawing code the clients use.
#pragma once

#include <string>

#include "budget.h"
#include "camera.h"
#include "gl_context.h"

namespace dmmr {

struct ReferenceOptions {
  std::string scene;
  std::string walkthrough;
  std::string out;    // frames land here as frame_NNNNNN.png
  std::string stats;  // optional CSV: frame, frame_ms, draw_ms, objects, triangles
  ViewOptions view;
  ContextOptions context;
  bool progress = true;
  // Also render an object-id frame per frame and add to the stats the
  // exactly visible set: objects owning at least one pixel, and their
  // triangles (the lower bound any culling can reach), and floor_ms, the
  // time to draw and read back the frame from that set alone.
  bool exact_visible = false;
  // The same geometry cache as the clients' (one GPU level); unlimited by
  // default, so every geometry is uploaded once and kept.
  CacheOptions cache;
  // As ClientOptions::pre_touch_mib (--pre-touch), so that brute force is
  // measured under the same memory policy.
  int64_t pre_touch_mib = -1;
  // Resume an interrupted run: render frames from this one on; the stats
  // CSV keeps the rows of the frames before it.
  uint32_t from_frame = 0;
  // Renderer::setFlushEvery (-1, the default: the driver's, as the clients
  // draw, so that brute force and culling are compared drawn the same way;
  // 0: never). The floor (exact_visible) is drawn with the driver's default
  // whatever this says.
  int64_t flush_triangles = -1;
};

// Throws Error on bad input; frames already written stay on disk. An
// unreadable geometry file is warned about and its objects skipped, as the
// clients do, so that both render the same frames.
void runReference(const ReferenceOptions& opts);

}  // namespace dmmr
