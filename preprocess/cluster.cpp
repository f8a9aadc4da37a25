#include "cluster.h"

#include <algorithm>
#include <stdexcept>

namespace dmmr {

namespace {

struct Splitter {
  const std::vector<float>& centroids;  // xyz per triangle (sums of corners: thirds left out)
  size_t max_triangles;
  std::vector<std::vector<uint32_t>>* out;

  // Splits tris[begin, end) into ceil(n / max_triangles) clusters.
  void split(std::vector<uint32_t>& tris, size_t begin, size_t end) {
    size_t n = end - begin;
    if (n <= max_triangles) {
      out->emplace_back(tris.begin() + long(begin), tris.begin() + long(end));
      std::sort(out->back().begin(), out->back().end());
      return;
    }
    float lo[3] = {centroids[3 * tris[begin]], centroids[3 * tris[begin] + 1],
                   centroids[3 * tris[begin] + 2]};
    float hi[3] = {lo[0], lo[1], lo[2]};
    for (size_t i = begin; i < end; ++i)
      for (int k = 0; k < 3; ++k) {
        float c = centroids[3 * tris[i] + k];
        lo[k] = std::min(lo[k], c);
        hi[k] = std::max(hi[k], c);
      }
    int axis = 0;
    for (int k = 1; k < 3; ++k)
      if (hi[k] - lo[k] > hi[axis] - lo[axis]) axis = k;
    // Halves sized for whole clusters: with c clusters in all, the first
    // c / 2 of them take n * (c / 2) / c triangles, at most (c / 2) * max.
    size_t clusters = (n + max_triangles - 1) / max_triangles;
    size_t mid = begin + n * (clusters / 2) / clusters;
    std::nth_element(tris.begin() + long(begin), tris.begin() + long(mid), tris.begin() + long(end),
                     [&](uint32_t a, uint32_t b) {
                       float ca = centroids[3 * a + axis], cb = centroids[3 * b + axis];
                       return ca < cb || (ca == cb && a < b);
                     });
    split(tris, begin, mid);
    split(tris, mid, end);
  }
};

// clusterTriangles' clusters in the split tree's order (each half's before
// the other's), which keeps neighbours in space neighbours in the list.
std::vector<std::vector<uint32_t>> splitTree(const float* positions, size_t vertex_count,
                                             const uint32_t* indices, size_t index_count,
                                             size_t max_triangles) {
  if (max_triangles == 0) throw std::invalid_argument("clusterTriangles: max_triangles is 0");
  if (index_count % 3) throw std::invalid_argument("clusterTriangles: not a triangle list");
  size_t n = index_count / 3;
  std::vector<std::vector<uint32_t>> out;
  if (n == 0) return out;
  std::vector<float> centroids(3 * n);
  for (size_t t = 0; t < n; ++t)
    for (int c = 0; c < 3; ++c) {
      uint32_t v = indices[3 * t + c];
      if (v >= vertex_count) throw std::invalid_argument("clusterTriangles: index out of range");
      for (int k = 0; k < 3; ++k) centroids[3 * t + k] += positions[3 * size_t(v) + k];
    }
  std::vector<uint32_t> tris(n);
  for (size_t t = 0; t < n; ++t) tris[t] = uint32_t(t);
  Splitter s{centroids, max_triangles, &out};
  s.split(tris, 0, n);
  return out;
}

}  // namespace

std::vector<std::vector<uint32_t>> clusterTriangles(const float* positions, size_t vertex_count,
                                                    const uint32_t* indices, size_t index_count,
                                                    size_t max_triangles) {
  std::vector<std::vector<uint32_t>> out =
      splitTree(positions, vertex_count, indices, index_count, max_triangles);
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a[0] < b[0]; });
  return out;
}

std::vector<Box3d> partBoxes(const float* positions, size_t vertex_count, const uint32_t* indices,
                             size_t index_count, size_t max_parts) {
  std::vector<uint32_t> one{uint32_t(index_count / 3)};
  return orderByParts(positions, vertex_count, indices, index_count, one, max_parts).boxes;
}

PartOrder orderByParts(const float* positions, size_t vertex_count, const uint32_t* indices,
                       size_t index_count, const std::vector<uint32_t>& submesh_triangles,
                       size_t max_parts) {
  if (max_parts == 0) throw std::invalid_argument("orderByParts: max_parts is 0");
  if (index_count % 3) throw std::invalid_argument("orderByParts: not a triangle list");
  size_t n = index_count / 3, covered = 0;
  for (uint32_t c : submesh_triangles) covered += c;
  if (covered != n)
    throw std::invalid_argument("orderByParts: the submeshes do not cover the triangle list");
  PartOrder out;
  std::vector<uint32_t> part(n);
  // Parts in the split tree's order: a region's edge or an occluder's
  // outline across the mesh then tends to leave a run of consecutive parts,
  // drawn with one call.
  for (const auto& tris : splitTree(positions, vertex_count, indices, index_count,
                                    std::max<size_t>(1, (n + max_parts - 1) / max_parts))) {
    Box3d b;
    for (uint32_t t : tris) {
      part[t] = uint32_t(out.boxes.size());
      for (size_t c = 0; c < 3; ++c) {
        const float* p = positions + 3 * size_t(indices[3 * size_t(t) + c]);
        b.expand(Vec3d{p[0], p[1], p[2]});
      }
    }
    out.boxes.push_back(b);
  }
  if (out.boxes.empty()) return out;
  // A counting sort per submesh, stable: each part's triangles keep their order.
  const size_t parts = out.boxes.size();
  out.order.resize(n);
  out.triangles.assign(submesh_triangles.size() * parts, 0);
  std::vector<size_t> at(parts);
  size_t first = 0;
  for (size_t s = 0; s < submesh_triangles.size(); ++s) {
    size_t end = first + submesh_triangles[s];
    uint32_t* count = out.triangles.data() + s * parts;
    for (size_t t = first; t < end; ++t) ++count[part[t]];
    for (size_t k = 0, next = first; k < parts; ++k) {
      at[k] = next;
      next += count[k];
    }
    for (size_t t = first; t < end; ++t) out.order[at[part[t]]++] = uint32_t(t);
    first = end;
  }
  return out;
}

}  // namespace dmmr
