// dmmr-preprocess: turns any model OpenSceneGraph or assimp reads into a
// dmmr scene directory (see common/formats.h).
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "formats.h"

namespace osg {
class Node;
}

namespace dmmr {

struct PreprocessOptions {
  // Model files, or directories standing for every model file in them and
  // below (sorted by path). Read one at a time; see docs/scene-format.md.
  std::vector<std::string> inputs;
  std::string out;  // must not exist; written to a temporary sibling, then renamed
  bool progress = true;
  // An input that cannot be read is an error, unless this is set: then it
  // is skipped with a warning naming it (for a directory with a few broken
  // files among many).
  bool skip_unreadable = false;
  // Potential occluders are big and cheap: the largest face of an object's
  // world box is in the top (100 - area_percentile)% of all objects, and it
  // has at most max_triangles triangles.
  double occluder_area_percentile = 90;
  uint64_t occluder_max_triangles = 10000;
  // Occluder levels of detail: meshoptimizer's simplifier aims at this
  // fraction of each geometry's triangles within `lod_error` (relative to the
  // geometry's extent); kept when it saves at least a quarter. Off (0) by
  // default: it costs about as much as the rest of preprocessing.
  double lod_ratio = 0;
  double lod_error = 0.01;
  uint64_t lod_min_triangles = 64;  // smaller geometries get no level of detail
  // Meshes (a geode's merged geometry) of more triangles than this are split
  // into clusters of at most this many (preprocess/cluster.h), each its own
  // object, under one group per mesh; 0 keeps every mesh whole.
  uint64_t cluster_triangles = 4096;
  // Within every geometry of enough triangles to have part boxes, each
  // part's triangles are stored together (parts.bin version 2), so that
  // clients can draw only the parts that reach their region; off keeps the
  // input's triangle order (parts unordered, drawn whole).
  bool part_order = true;
  // How geometry files store vertices and indices (formats.h); recorded in
  // the manifest. The default is exact; Quantized and QuantizedMeshopt are
  // lossy (docs/scene-format.md gives their error bounds).
  Encoding encoding = Encoding::Float32;
};

struct PreprocessStats {
  uint64_t objects = 0, geometries = 0, textures = 0, occluders = 0;
  uint64_t triangles = 0, unique_triangles = 0;
  uint64_t nonfinite_vertices = 0;     // vertices with NaN/inf coordinates (dropped)
  uint64_t dropped_triangles = 0;      // triangles that used such vertices
  uint64_t bad_index_triangles = 0;    // naming a vertex the mesh lacks: dropped
  uint64_t degenerate_triangles = 0;   // with coinciding corners (no pixels): dropped
  uint64_t skipped_drawables = 0;      // drawables that are not triangle geometry
  uint64_t camera_fixed_subtrees = 0;  // under an ABSOLUTE_RF transform (a HUD): skipped
  uint64_t billboards = 0;  // osg::Billboards: drawn as modelled at each position, not turned
  uint64_t unloaded_lod_files = 0;  // PagedLOD levels in files, not read (not loaded)
  uint64_t split_meshes = 0;        // meshes split into clusters
  uint64_t lod_geometries = 0, lod_triangles = 0;  // levels of detail stored
  uint64_t bytes_written = 0;
  uint64_t inputs = 0, skipped_inputs = 0;  // model files read, and skipped as unreadable
  double seconds = 0;
};

// Throws Error naming the input or output and what is wrong; never leaves a
// partial scene at `out`.
PreprocessStats preprocess(const PreprocessOptions& opts);

// A run writes its scene to OUT + partialSuffix(its PID) and renames it to
// OUT when done: ".partial-PID-START", START the process's start time, so
// that a later run can tell the PID's process from another that got the
// same PID (exposed for tests).
std::string partialSuffix(long pid);
// Removes OUT's partial directories whose run is gone: no process has the
// PID, or the process with it started at another time (a reused PID).
// Directories of older runs (OUT.partial-PID) go only when the PID is free.
void removeStalePartials(const std::filesystem::path& out);

// The occluder criterion above, over plain data (exposed for tests).
std::vector<uint32_t> selectOccluders(const std::vector<ObjectBounds>& objects,
                                      double area_percentile, uint64_t max_triangles);

}  // namespace dmmr
