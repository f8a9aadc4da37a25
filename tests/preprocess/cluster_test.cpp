// clusterTriangles (preprocess/cluster.h) alone: fixed-seed random meshes
// checked for its contract, and the degenerate inputs.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <stdexcept>
#include <vector>

#include "cluster.h"

using namespace dmmr;

namespace {

struct Mesh {
  std::vector<float> positions;
  std::vector<uint32_t> indices;
  size_t triangles() const { return indices.size() / 3; }
};

uint64_t splitmix(uint64_t& s) {
  uint64_t z = (s += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}
float uniform(uint64_t& s) {
  return float(splitmix(s) >> 40) / float(1 << 24);
}

// `n` small triangles scattered in the unit cube (z = 0 when flat), in
// random order; with `share`, a quarter of the corners reuse a random
// earlier vertex (which makes long triangles).
Mesh randomMesh(uint64_t seed, size_t n, bool flat = false, bool share = true) {
  Mesh m;
  uint64_t s = seed;
  for (size_t t = 0; t < n; ++t) {
    float c[3] = {uniform(s), uniform(s), flat ? 0.f : uniform(s)};
    for (int k = 0; k < 3; ++k) {
      size_t nv = m.positions.size() / 3;
      if (share && nv > 0 && splitmix(s) % 4 == 0) {  // reuse a vertex
        m.indices.push_back(uint32_t(splitmix(s) % nv));
        continue;
      }
      m.indices.push_back(uint32_t(nv));
      for (int a = 0; a < 3; ++a)
        m.positions.push_back(flat && a == 2 ? 0.f : c[a] + 0.01f * (uniform(s) - 0.5f));
    }
  }
  return m;
}

struct Box {
  float lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f};
  void add(const float* p) {
    for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], p[k]), hi[k] = std::max(hi[k], p[k]);
  }
  double measure(int dims) const {  // volume, or area over x and y
    double m = 1;
    for (int k = 0; k < dims; ++k) m *= double(hi[k]) - lo[k];
    return m;
  }
};

Box boxOf(const Mesh& m, const std::vector<uint32_t>& tris) {
  Box b;
  for (uint32_t t : tris)
    for (int c = 0; c < 3; ++c) b.add(&m.positions[3 * size_t(m.indices[3 * size_t(t) + c])]);
  return b;
}

std::vector<std::vector<uint32_t>> cluster(const Mesh& m, size_t max) {
  return clusterTriangles(m.positions.data(), m.positions.size() / 3, m.indices.data(),
                          m.indices.size(), max);
}

// The contract's partition and order properties.
void checkPartition(const Mesh& m, const std::vector<std::vector<uint32_t>>& clusters, size_t max) {
  size_t n = m.triangles();
  EXPECT_EQ(clusters.size(), (n + max - 1) / max);
  std::vector<int> seen(n, 0);
  for (size_t c = 0; c < clusters.size(); ++c) {
    const auto& cl = clusters[c];
    ASSERT_FALSE(cl.empty()) << "cluster " << c;
    EXPECT_LE(cl.size(), max) << "cluster " << c;
    EXPECT_TRUE(std::is_sorted(cl.begin(), cl.end())) << "cluster " << c;
    if (c > 0) {
      EXPECT_LT(clusters[c - 1][0], cl[0]) << "clusters out of order at " << c;
    }
    for (uint32_t t : cl) {
      ASSERT_LT(t, n);
      ++seen[t];
    }
  }
  for (size_t t = 0; t < n; ++t) EXPECT_EQ(seen[t], 1) << "triangle " << t;
}

TEST(ClusterTriangles, RandomMeshesArePartitionedInOrder) {
  for (uint64_t seed = 1; seed <= 20; ++seed) {
    uint64_t s = seed * 7919;
    size_t n = 1 + splitmix(s) % 5000, max = 1 + splitmix(s) % 700;
    Mesh m = randomMesh(seed, n);
    SCOPED_TRACE(testing::Message() << "seed " << seed << ", " << n << " triangles, max " << max);
    checkPartition(m, cluster(m, max), max);
  }
}

TEST(ClusterTriangles, ClusterBoxesAreTight) {
  // Scattered small triangles: the clusters' boxes nearly tile the mesh's
  // box, where chunks of the (random) original order would each span all of
  // it. Allow twice the mesh's volume (the triangles' own size makes
  // neighbouring boxes overlap a little).
  for (bool flat : {false, true}) {
    Mesh m = randomMesh(flat ? 5 : 4, 20000, flat, false);
    int dims = flat ? 2 : 3;
    auto clusters = cluster(m, 500);
    ASSERT_EQ(clusters.size(), 40u);
    std::vector<uint32_t> all(m.triangles());
    for (size_t t = 0; t < all.size(); ++t) all[t] = uint32_t(t);
    double whole = boxOf(m, all).measure(dims), sum = 0, chunks = 0;
    for (const auto& c : clusters) sum += boxOf(m, c).measure(dims);
    for (size_t i = 0; i < all.size(); i += 500)
      chunks += boxOf(m, {all.begin() + long(i), all.begin() + long(i + 500)}).measure(dims);
    EXPECT_LE(sum, 2 * whole) << (flat ? "flat" : "volume");
    EXPECT_GE(chunks, 20 * whole) << "the baseline should be loose";
  }
}

TEST(ClusterTriangles, CorrespondsToTheOriginalTriangles) {
  // Triangle numbers refer to the input's corners, so a cluster rebuilt from
  // them has every triangle's corners in their order (winding kept).
  Mesh m = randomMesh(9, 3000);
  auto clusters = cluster(m, 256);
  std::vector<uint32_t> rebuilt;
  for (const auto& c : clusters)
    for (uint32_t t : c)
      rebuilt.insert(rebuilt.end(), {m.indices[3 * t], m.indices[3 * t + 1], m.indices[3 * t + 2]});
  ASSERT_EQ(rebuilt.size(), m.indices.size());
  // The first cluster holds triangle 0 with its corners as they were.
  EXPECT_EQ(clusters[0][0], 0u);
  EXPECT_TRUE(std::equal(rebuilt.begin(), rebuilt.begin() + 3, m.indices.begin()));
}

TEST(ClusterTriangles, SmallMeshIsOneCluster) {
  Mesh m = randomMesh(2, 100);
  auto clusters = cluster(m, 100);
  ASSERT_EQ(clusters.size(), 1u);
  for (uint32_t t = 0; t < 100; ++t) EXPECT_EQ(clusters[0][t], t);
  EXPECT_TRUE(cluster(Mesh{}, 10).empty());
}

TEST(ClusterTriangles, AllTrianglesAtOnePoint) {
  Mesh m;
  m.positions = {1, 2, 3};
  for (int i = 0; i < 3 * 1001; ++i) m.indices.push_back(0);
  checkPartition(m, cluster(m, 100), 100);
}

TEST(ClusterTriangles, OneTrianglePerCluster) {
  Mesh m = randomMesh(3, 257);
  auto clusters = cluster(m, 1);
  checkPartition(m, clusters, 1);
  for (uint32_t t = 0; t < clusters.size(); ++t) EXPECT_EQ(clusters[t][0], t);
}

TEST(ClusterTriangles, RejectsBadInput) {
  Mesh m = randomMesh(1, 10);
  size_t nv = m.positions.size() / 3;
  EXPECT_THROW(clusterTriangles(m.positions.data(), nv, m.indices.data(), m.indices.size(), 0),
               std::invalid_argument);
  EXPECT_THROW(clusterTriangles(m.positions.data(), nv, m.indices.data(), 4, 2),
               std::invalid_argument);
  m.indices[5] = uint32_t(nv);
  EXPECT_THROW(clusterTriangles(m.positions.data(), nv, m.indices.data(), m.indices.size(), 2),
               std::invalid_argument);
}

}  // namespace

// ---- partBoxes ----

// Every triangle lies whole in one of at most max_parts boxes, and the
// boxes are those of clusterTriangles' clusters (so no looser than them).
TEST(PartBoxes, EveryTriangleLiesWholeInAPart) {
  for (uint64_t seed = 1; seed <= 20; ++seed)
    for (size_t n : {size_t(1), size_t(7), size_t(8), size_t(9), size_t(100), size_t(1001)})
      for (size_t max : {size_t(1), size_t(3), size_t(8)}) {
        Mesh m = randomMesh(seed, n, seed % 2 == 0);
        std::vector<Box3d> parts = partBoxes(m.positions.data(), m.positions.size() / 3,
                                             m.indices.data(), m.indices.size(), max);
        // The same clusters as clusterTriangles', in another order.
        auto clusters = cluster(m, (n + max - 1) / max);
        ASSERT_EQ(parts.size(), clusters.size());
        ASSERT_LE(parts.size(), max);
        std::vector<uint32_t> one{uint32_t(n)};
        PartOrder o = orderByParts(m.positions.data(), m.positions.size() / 3, m.indices.data(),
                                   m.indices.size(), one, max);
        ASSERT_EQ(o.boxes, parts);
        std::vector<std::vector<uint32_t>> byPart(parts.size());
        for (size_t k = 0, t = 0; k < parts.size(); ++k)
          for (uint32_t i = 0; i < o.triangles[k]; ++i) byPart[k].push_back(o.order[t++]);
        std::vector<std::vector<uint32_t>> sorted = byPart;
        std::sort(sorted.begin(), sorted.end());
        std::sort(clusters.begin(), clusters.end());
        ASSERT_EQ(sorted, clusters) << "seed " << seed << " n " << n;
        for (size_t k = 0; k < byPart.size(); ++k)
          for (uint32_t t : byPart[k])
            for (int c = 0; c < 3; ++c) {
              const float* p = &m.positions[3 * size_t(m.indices[3 * size_t(t) + size_t(c)])];
              for (int a = 0; a < 3; ++a) {
                ASSERT_LE(parts[k].lo[a], double(p[a])) << "seed " << seed << " n " << n;
                ASSERT_GE(parts[k].hi[a], double(p[a])) << "seed " << seed << " n " << n;
              }
            }
      }
}

// An L of two thin bars: two parts leave its empty corner out.
TEST(PartBoxes, AnLShapeLeavesItsCornerOut) {
  Mesh m;
  auto bar = [&](float x0, float y0, float x1, float y1) {
    for (int t = 0; t < 8; ++t) {  // 8 slivers along the bar
      float a = float(t) / 8, b = float(t + 1) / 8;
      uint32_t v = uint32_t(m.positions.size() / 3);
      for (float f : {a, b, b})
        m.positions.insert(m.positions.end(), {x0 + (x1 - x0) * f, y0 + (y1 - y0) * f, 0});
      m.positions[m.positions.size() - 2] += 0.01f;  // give the last corner some width
      m.indices.insert(m.indices.end(), {v, v + 1, v + 2});
    }
  };
  bar(0, 0, 1, 0);
  bar(0, 0.02f, 0, 1);
  std::vector<Box3d> parts =
      partBoxes(m.positions.data(), m.positions.size() / 3, m.indices.data(), m.indices.size(), 2);
  ASSERT_EQ(parts.size(), 2u);
  for (const Box3d& p : parts) {  // neither holds the corner (0.5, 0.5)
    bool holds = p.lo.x <= 0.5 && p.hi.x >= 0.5 && p.lo.y <= 0.5 && p.hi.y >= 0.5;
    EXPECT_FALSE(holds) << p.lo.x << " " << p.lo.y << " " << p.hi.x << " " << p.hi.y;
  }
}

TEST(PartBoxes, EmptyListHasNoPartsAndBadInputThrows) {
  Mesh m = randomMesh(3, 4);
  EXPECT_TRUE(
      partBoxes(m.positions.data(), m.positions.size() / 3, m.indices.data(), 0, 8).empty());
  EXPECT_THROW(
      partBoxes(m.positions.data(), m.positions.size() / 3, m.indices.data(), m.indices.size(), 0),
      std::invalid_argument);
  EXPECT_THROW(partBoxes(m.positions.data(), 1, m.indices.data(), m.indices.size(), 8),
               std::invalid_argument);
}

// orderByParts: a permutation that keeps every triangle in its submesh,
// puts each part's triangles of a submesh together in ascending order, with
// counts that add up; the boxes are partBoxes'.
TEST(OrderByParts, EachSubmeshHoldsItsPartsInOrder) {
  for (uint64_t seed = 1; seed <= 20; ++seed)
    for (size_t n : {size_t(1), size_t(9), size_t(100), size_t(1001)}) {
      Mesh m = randomMesh(seed, n, seed % 2 == 0);
      // Up to 3 submeshes of random sizes (some empty).
      uint64_t s = seed * 77;
      std::vector<uint32_t> submeshes;
      size_t left = n;
      for (int k = 0; k < 2; ++k) {
        uint32_t c = uint32_t(splitmix(s) % (left + 1));
        submeshes.push_back(c);
        left -= c;
      }
      submeshes.push_back(uint32_t(left));
      PartOrder o = orderByParts(m.positions.data(), m.positions.size() / 3, m.indices.data(),
                                 m.indices.size(), submeshes, 8);
      std::vector<Box3d> boxes = partBoxes(m.positions.data(), m.positions.size() / 3,
                                           m.indices.data(), m.indices.size(), 8);
      ASSERT_EQ(o.boxes, boxes);
      const size_t parts = boxes.size();
      ASSERT_EQ(o.order.size(), n);
      ASSERT_EQ(o.triangles.size(), submeshes.size() * parts);
      std::vector<int> seen(n, 0);
      size_t t = 0, first = 0;
      for (size_t sm = 0; sm < submeshes.size(); ++sm) {
        size_t end = first + submeshes[sm];
        for (size_t k = 0; k < parts; ++k) {
          uint32_t last = 0;
          for (uint32_t i = 0; i < o.triangles[sm * parts + k]; ++i, ++t) {
            uint32_t old = o.order.at(t);
            ++seen.at(old);
            ASSERT_GE(old, first) << "seed " << seed << ": left its submesh";
            ASSERT_LT(old, end) << "seed " << seed << ": left its submesh";
            if (i > 0) ASSERT_GT(old, last) << "seed " << seed << ": part out of order";
            last = old;
            for (int c = 0; c < 3; ++c) {
              const float* p = &m.positions[3 * size_t(m.indices[3 * size_t(old) + size_t(c)])];
              for (int a = 0; a < 3; ++a) {
                ASSERT_LE(boxes[k].lo[a], double(p[a])) << "seed " << seed << " part " << k;
                ASSERT_GE(boxes[k].hi[a], double(p[a])) << "seed " << seed << " part " << k;
              }
            }
          }
        }
        ASSERT_EQ(t, end) << "seed " << seed << ": submesh " << sm << "'s counts";
        first = end;
      }
      for (size_t i = 0; i < n; ++i) ASSERT_EQ(seen[i], 1) << "seed " << seed << " triangle " << i;
    }
}

TEST(OrderByParts, RejectsSubmeshesThatDoNotCoverTheList) {
  Mesh m = randomMesh(5, 10);
  EXPECT_THROW(orderByParts(m.positions.data(), m.positions.size() / 3, m.indices.data(),
                            m.indices.size(), {4, 5}, 8),
               std::invalid_argument);
  EXPECT_THROW(orderByParts(m.positions.data(), m.positions.size() / 3, m.indices.data(),
                            m.indices.size(), {4, 7}, 8),
               std::invalid_argument);
}
