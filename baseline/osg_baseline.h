// dmmr-osgviewer: OpenSceneGraph's own single-node path, the baseline of the
// benchmarks. The original model is rendered by osgViewer, optionally with
// osg::OcclusionQueryNode inserted above the groups (as OSG's
// osgocclusionquery example does), headless through an OSMesa compatibility
// context, along the walkthrough and with the camera every dmmr renderer uses.
#pragma once

#include <cstdint>
#include <osg/Matrixd>
#include <osg/Node>
#include <string>

#include "camera.h"
#include "walkthrough.h"

namespace dmmr {

// The settings of the OcclusionQueryNodes that insertOcclusionQueries adds.
struct OcclusionSettings {
  // A node gets a query when the geometry below it has more vertices than
  // this (the osgocclusionquery example's occluder threshold, 5000); smaller
  // subgraphs are just drawn.
  uint32_t min_vertices = 5000;
  // Samples a query box must pass for its children to be drawn: more than
  // this many. OSG's default is 500; 0 (one sample suffices) matches dmmr's
  // exact setting.
  uint32_t visibility_threshold = 0;
  // Frames between two queries of a node; the last result stands in between.
  // OSG's default is 5; 1 queries every frame.
  uint32_t query_frame_count = 1;
};

// Inserts an osg::OcclusionQueryNode above every group (geodes included)
// whose subgraph has more than min_vertices vertices and that has no such
// node below it (no nesting), one per parent, as OSG's osgocclusionquery
// example does; the root itself (no parent) gets none. Subgraphs shared by
// several parents (instances) are handled once and get one node per parent,
// since a query's result belongs to one placement. OcclusionQueryNodes
// already in the graph are kept as they are and nothing is added below
// them. All added nodes share one query and one debug state set. Returns the
// number of nodes added.
uint32_t insertOcclusionQueries(osg::Node& root, const OcclusionSettings& settings);

// Vertices (the vertex arrays' element counts) of the geometry under `node`,
// shared subgraphs counted once per path; counting stops once the total
// exceeds `limit`, so the result is min(total, something > limit).
uint64_t countVertices(osg::Node& node, uint64_t limit = UINT64_MAX);

// OSG's view matrix for a walkthrough control point: the inverse of the
// camera's placement rotate(q) * translate(eye), as osg::AnimationPath plays
// the same files (the camera looks down its local -Z, +Y up).
osg::Matrixd osgViewMatrix(const ControlPoint& p);

struct OsgViewerOptions {
  std::string model;        // any file osgDB reads (the scene generator's .osgb)
  std::string walkthrough;  // AnimationPath file, one frame per control point
  std::string out;          // frames land here as frame_NNNNNN.png
  std::string stats;        // optional CSV: frame, frame_ms, draw_ms, drawables, triangles
  ViewOptions view;         // near 0: the model's diagonal * 1e-5, as dmmr's default
  bool occlusion = true;    // insert OcclusionQueryNodes
  OcclusionSettings queries;
  bool progress = true;
};

// Renders the walkthrough. Per frame: the view matrix, osgViewer's frame()
// (update, cull, draw), glFinish, glReadPixels (draw_ms ends here), the PNG
// written atomically (frame_ms ends here), the same split as
// dmmr-reference's. The stats CSV is rewritten as frames finish. Throws
// Error naming the model file when osgDB cannot read it, and for a bad
// walkthrough or a context that cannot be created.
void runOsgViewer(const OsgViewerOptions& opts);

}  // namespace dmmr
