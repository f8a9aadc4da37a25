// Splitting a big mesh into spatially coherent clusters (issue 15), so that
// culling, the division between clients and the cache work inside it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "math.h"

namespace dmmr {

// Splits a triangle list into clusters of at most `max_triangles` triangles
// by a recursive median split of the triangle centroids along the longest
// axis of their box (the split that gives the tightest cluster boxes; the
// two halves get triangle counts proportional to the clusters each will
// hold, so every cluster but the smallest is nearly full).
//
// In: `positions`, xyz per vertex (3 * vertex_count floats); `indices`, a
// triangle list (index_count a multiple of 3) whose entries are all below
// vertex_count; max_triangles >= 1.
// Out: clusters of triangle numbers (triangle t is indices[3t..3t+2]).
// Every triangle is in exactly one cluster; no cluster is empty or holds
// more than max_triangles; each cluster lists its triangles in ascending
// order (their original relative order), and clusters are ordered by their
// first triangle, so drawing the clusters in order draws a mesh whose
// triangles were already spatially grouped in its original order. A mesh of
// at most max_triangles triangles is one cluster; there are always exactly
// ceil(triangles / max_triangles) clusters. Deterministic: ties in
// centroid order break by triangle number. Throws std::invalid_argument when
// max_triangles is 0, index_count is not a multiple of 3, or an index is
// out of range.
std::vector<std::vector<uint32_t>> clusterTriangles(const float* positions, size_t vertex_count,
                                                    const uint32_t* indices, size_t index_count,
                                                    size_t max_triangles);

// The part boxes of a triangle list (formats.h, GeometryParts): the boxes
// of clusterTriangles' clusters of ceil(triangles / max_parts) triangles, in
// the order of its split tree (each half's clusters before the other's, so
// that parts next to each other in the list are next to each other in
// space). Every triangle lies whole (all three corners) in one of them;
// there are at most max_parts (>= 1), none for an empty list. Same inputs
// and exceptions as clusterTriangles.
std::vector<Box3d> partBoxes(const float* positions, size_t vertex_count, const uint32_t* indices,
                             size_t index_count, size_t max_parts);

// partBoxes' parts, and the triangle order that keeps each part's triangles
// together within every submesh (formats.h, GeometryParts::triangles), so
// that a client can draw some parts of a geometry and not others.
struct PartOrder {
  std::vector<Box3d> boxes;  // partBoxes' result
  // The new triangle list: new triangle t is old triangle order[t]. Within
  // submesh s (whose triangles stay within its range), part 0's triangles
  // come first, then part 1's, each in ascending old order.
  std::vector<uint32_t> order;
  // triangles[s * boxes.size() + k]: how many of submesh s's triangles are
  // part k's (empty with no parts).
  std::vector<uint32_t> triangles;
};
// `submesh_triangles`: each submesh's triangle count, the submeshes lying one
// after another from triangle 0 and covering the list (their sum is
// index_count / 3, else std::invalid_argument). Otherwise as partBoxes.
PartOrder orderByParts(const float* positions, size_t vertex_count, const uint32_t* indices,
                       size_t index_count, const std::vector<uint32_t>& submesh_triangles,
                       size_t max_parts);

}  // namespace dmmr
