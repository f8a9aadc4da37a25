// Meshes split into clusters by dmmr-preprocess (issue 15): the clusters of
// a mesh hold its triangles exactly (same floats, attributes, winding), in
// their original relative order, under one group, with tight boxes; small
// meshes stay whole; instances share the clusters; occluders and levels of
// detail are per cluster.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <map>
#include <osg/Geode>
#include <osg/Geometry>
#include <osg/Material>
#include <osg/MatrixTransform>
#include <osgDB/WriteFile>

#include "formats.h"
#include "preprocess.h"
#include "scene.h"
#include "test_support.h"

using namespace dmmr;
using dmmr::test::TempDir;

namespace {

// A bumpy n x n grid of quads (2 n^2 triangles) with normals and colours.
osg::ref_ptr<osg::Geometry> grid(int n, float x0, float y0, const osg::Vec4& diffuse) {
  auto* v = new osg::Vec3Array;
  auto* nrm = new osg::Vec3Array;
  auto* col = new osg::Vec4Array;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      v->push_back({x0 + i * 0.1f, y0 + j * 0.1f, 0.05f * std::sin(0.7f * i) * std::cos(0.4f * j)});
      nrm->push_back({0.1f * i, 0.2f, 1});
      col->push_back({i / float(n), j / float(n), 0.5f, 1});
    }
  auto* idx = new osg::DrawElementsUInt(GL_TRIANGLES);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      GLuint a = j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
      for (GLuint k : {a, b, d, a, d, c}) idx->push_back(k);
    }
  osg::ref_ptr<osg::Geometry> g = new osg::Geometry;
  g->setVertexArray(v);
  g->setNormalArray(nrm, osg::Array::BIND_PER_VERTEX);
  g->setColorArray(col, osg::Array::BIND_PER_VERTEX);
  g->addPrimitiveSet(idx);
  auto* m = new osg::Material;
  m->setDiffuse(osg::Material::FRONT_AND_BACK, diffuse);
  g->getOrCreateStateSet()->setAttribute(m);
  return g;
}

// One mesh of two drawables (2 x 800 triangles, two materials; offset, so
// two corners of the mesh's box are no vertex) under a translation and
// again under a rotation, and a small 2-triangle mesh.
std::string writeModel(const TempDir& dir) {
  osg::ref_ptr<osg::Geode> big = new osg::Geode;
  big->setName("big");
  big->addDrawable(grid(20, 0, 0, {1, 0, 0, 1}));
  big->addDrawable(grid(20, 2.5f, 1, {0, 1, 0, 1}));
  osg::ref_ptr<osg::Geode> small = new osg::Geode;
  small->addDrawable(grid(1, 0, 0, {0, 0, 1, 1}));
  osg::ref_ptr<osg::Group> root = new osg::Group;
  auto* a = new osg::MatrixTransform(osg::Matrixd::translate(100, 0, 0));
  auto* b = new osg::MatrixTransform(osg::Matrixd::rotate(0.5, osg::Vec3d(0, 0, 1)) *
                                     osg::Matrixd::translate(0, 50, 1000));
  a->addChild(big);
  b->addChild(big);
  root->addChild(a);
  root->addChild(b);
  root->addChild(small);
  std::string path = dir / "model.osgb";
  EXPECT_TRUE(osgDB::writeNodeFile(*root, path));
  return path;
}

PreprocessStats run(const std::string& model, const std::string& out, uint64_t cluster,
                    double lod = 0, uint64_t occluderMax = 10000, bool part_order = true) {
  PreprocessOptions o;
  o.part_order = part_order;
  o.inputs = {model};
  o.out = out;
  o.progress = false;
  o.cluster_triangles = cluster;
  o.lod_ratio = lod;
  o.occluder_area_percentile = 0;
  o.occluder_max_triangles = occluderMax;
  return preprocess(o);
}

// Each triangle's corners (position, normal, colour) and its submesh's
// diffuse, as bytes: equal keys mean identical triangles as drawn.
std::vector<std::string> triangleKeys(const GeometryData& g) {
  std::vector<std::string> keys;
  for (const SubMesh& sm : g.submeshes)
    for (uint32_t i = sm.first_index; i < sm.first_index + sm.index_count; i += 3) {
      std::string k(reinterpret_cast<const char*>(sm.diffuse), sizeof sm.diffuse);
      for (int c = 0; c < 3; ++c) {
        uint32_t v = g.indices[i + c];
        k.append(reinterpret_cast<const char*>(&g.positions[3 * v]), 12);
        k.append(reinterpret_cast<const char*>(&g.normals[3 * v]), 12);
        k.append(reinterpret_cast<const char*>(&g.colors[4 * v]), 4);
      }
      keys.push_back(k);
    }
  return keys;
}

class Clusters : public testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir;
    std::string model = writeModel(*dir_);
    // In the input's order (--part-order off), so that the clusters can be
    // checked against the mesh's own order; "ordered" as by default.
    run(model, *dir_ / "whole", 0, 0, 10000, false);
    stats_ = run(model, *dir_ / "split", 100, 0, 10000, false);
    run(model, *dir_ / "ordered", 100);
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  static TempDir* dir_;
  static PreprocessStats stats_;
};
TempDir* Clusters::dir_ = nullptr;
PreprocessStats Clusters::stats_;

TEST_F(Clusters, BigMeshesBecomeClustersUnderAGroupAndSmallOnesStayWhole) {
  Scene whole = loadScene(*dir_ / "whole"), split = loadScene(*dir_ / "split");
  ASSERT_EQ(whole.objects.size(), 3u);
  EXPECT_EQ(stats_.split_meshes, 1u);
  EXPECT_EQ(split.objects.size(), 16u + 16u + 1u);  // 1600 triangles in clusters of <= 100
  EXPECT_EQ(split.manifest.geometries, 17u);        // both instances share the clusters
  EXPECT_EQ(split.manifest.triangles, whole.manifest.triangles);
  EXPECT_EQ(split.manifest.unique_triangles, whole.manifest.unique_triangles);
  // The scene's bounds (and so the default near plane) are the unsplit ones,
  // though the clusters' boxes under the rotation enclose less.
  EXPECT_EQ(split.manifest.bounds, whole.manifest.bounds);
  // Skeleton: each instance's clusters are the objects of one group named
  // after the geode, in object order.
  int groups = 0;
  for (uint32_t i = 0; i < split.skeleton.size(); ++i) {
    const SkeletonNode& n = split.skeleton[i];
    if (n.name != "big") continue;
    ++groups;
    EXPECT_EQ(n.kind, NodeKind::Group);
    ASSERT_EQ(n.end - i - 1, 16u);
    for (uint32_t c = i + 1; c < n.end; ++c) {
      EXPECT_EQ(split.skeleton[c].kind, NodeKind::Object);
      EXPECT_EQ(split.skeleton[c].parent, i);
      EXPECT_EQ(split.skeleton[c].object, split.skeleton[i + 1].object + (c - i - 1));
    }
  }
  EXPECT_EQ(groups, 2);
  // The small mesh is one object, as before.
  EXPECT_EQ(split.objects.back().weight, 2u);
  EXPECT_EQ(loadGeometry(split, split.objects.back().geometry),
            loadGeometry(whole, whole.objects.back().geometry));
}

TEST_F(Clusters, ClustersHoldTheMeshsTrianglesExactlyInTheirOrder) {
  Scene whole = loadScene(*dir_ / "whole"), split = loadScene(*dir_ / "split");
  std::vector<std::string> all = triangleKeys(loadGeometry(whole, whole.objects[0].geometry));
  std::map<std::string, size_t> original;
  for (size_t t = 0; t < all.size(); ++t) original[all[t]] = t;
  ASSERT_EQ(original.size(), 1600u);
  for (int instance = 0; instance < 2; ++instance) {
    std::vector<int> seen(all.size(), 0);
    size_t previousFirst = 0;
    for (uint32_t k = 0; k < 16; ++k) {
      const ObjectBounds& o = split.objects[instance * 16 + k];
      // Same transform as the whole mesh: recentred on the mesh's centre.
      EXPECT_EQ(o.transform, whole.objects[instance].transform) << "cluster " << k;
      GeometryData g = loadGeometry(split, o.geometry);
      EXPECT_EQ(o.weight, g.triangleCount());
      EXPECT_LE(g.triangleCount(), 100u);
      std::vector<std::string> keys = triangleKeys(g);
      ASSERT_EQ(keys.size(), g.triangleCount());
      size_t last = 0;
      for (size_t t = 0; t < keys.size(); ++t) {
        auto it = original.find(keys[t]);
        ASSERT_NE(it, original.end()) << "cluster " << k << " triangle " << t << " changed";
        ++seen[it->second];
        if (t > 0) {
          EXPECT_GT(it->second, last) << "cluster " << k << " reorders triangles";
        } else if (k > 0) {
          EXPECT_GT(it->second, previousFirst) << "clusters out of order";
        }
        if (t == 0) previousFirst = it->second;
        last = it->second;
      }
      // The box is tight: that of the cluster's own vertices.
      Box3d local;
      for (size_t i = 0; i < g.positions.size(); i += 3)
        local.expand(Vec3d{g.positions[i], g.positions[i + 1], g.positions[i + 2]});
      EXPECT_EQ(o.box, transformBox(o.transform, local)) << "cluster " << k;
    }
    for (size_t t = 0; t < seen.size(); ++t) EXPECT_EQ(seen[t], 1) << "triangle " << t;
  }
}

// By default each cluster keeps its parts' triangles together (parts.bin
// version 2): the same triangles, unchanged, each part's in the mesh's
// order, every one within its part's box; --part-order off leaves the
// parts unordered.
TEST_F(Clusters, PartOrderKeepsEachPartsTrianglesTogetherInTheirOrder) {
  Scene whole = loadScene(*dir_ / "whole", true, true);
  Scene split = loadScene(*dir_ / "split", true, true);
  Scene ordered = loadScene(*dir_ / "ordered", true, true);
  ASSERT_EQ(ordered.parts.size(), split.parts.size());
  for (const GeometryParts& g : split.parts) EXPECT_FALSE(g.ordered());
  std::vector<std::string> all = triangleKeys(loadGeometry(whole, whole.objects[0].geometry));
  std::map<std::string, size_t> original;
  for (size_t t = 0; t < all.size(); ++t) original[all[t]] = t;
  std::vector<int> seen(all.size(), 0);
  for (uint32_t k = 0; k < 16; ++k) {
    const ObjectBounds& o = ordered.objects[k];
    GeometryData g = loadGeometry(ordered, o.geometry);
    const GeometryParts& p = ordered.parts[o.geometry];
    ASSERT_TRUE(p.ordered()) << "cluster " << k;
    ASSERT_EQ(p.triangles.size(), p.parts.size() * g.submeshes.size());
    std::vector<std::string> keys = triangleKeys(g);
    size_t t = 0;
    for (size_t s = 0; s < g.submeshes.size(); ++s) {
      uint32_t in_submesh = 0;
      for (size_t part = 0; part < p.parts.size(); ++part) {
        Box3d box = partBox(p, part);
        size_t last = 0;
        for (uint32_t i = 0; i < p.triangles[s * p.parts.size() + part]; ++i, ++t) {
          auto it = original.find(keys.at(t));
          ASSERT_NE(it, original.end()) << "cluster " << k << " triangle " << t << " changed";
          ++seen[it->second];
          if (i > 0) EXPECT_GT(it->second, last) << "cluster " << k << " part " << part;
          last = it->second;
          for (int c = 0; c < 3; ++c) {
            const float* v = &g.positions[3 * size_t(g.indices[3 * t + size_t(c)])];
            for (int a = 0; a < 3; ++a) {
              EXPECT_GE(v[a], box.lo[a]) << "cluster " << k << " part " << part;
              EXPECT_LE(v[a], box.hi[a]) << "cluster " << k << " part " << part;
            }
          }
        }
        in_submesh += p.triangles[s * p.parts.size() + part];
      }
      EXPECT_EQ(3 * in_submesh, g.submeshes[s].index_count) << "cluster " << k;
    }
    EXPECT_EQ(t, g.triangleCount());
  }
  for (size_t t = 0; t < seen.size(); ++t) EXPECT_EQ(seen[t], 1) << "triangle " << t;
}

TEST(ClusterOptions, OccludersAndLevelsOfDetailArePerCluster) {
  TempDir dir;
  std::string model = writeModel(dir);
  // At most 150 triangles: the whole mesh (1600) is no occluder, its
  // clusters are.
  PreprocessStats whole = run(model, dir / "whole", 0, 0.25, 150);
  PreprocessStats split = run(model, dir / "split", 100, 0.25, 150);
  EXPECT_EQ(whole.occluders, 1u);  // the small mesh
  EXPECT_EQ(split.occluders, 33u);
  EXPECT_EQ(whole.lod_geometries, 1u);
  EXPECT_GT(split.lod_geometries, 1u);
  Scene s = loadScene(dir / "split");
  for (uint32_t i = 0; i < 16; ++i) {
    GeometryData g = loadGeometry(s, s.objects[i].geometry);
    if (g.lod_indices.empty()) continue;
    EXPECT_LT(g.lod_indices.size(), g.indices.size());
    for (uint32_t v : g.lod_indices) EXPECT_LT(v, g.vertexCount());
  }
}

TEST(ClusterOptions, CommandLineTakesTheClusterSize) {
  TempDir dir;
  std::string model = writeModel(dir);
  int status = 0;
  std::string log = test::runCapture(test::tool("dmmr-preprocess") + " --no-progress " + model +
                                         " -o " + (dir / "s") + " --cluster-triangles 400",
                                     &status);
  EXPECT_EQ(status, 0) << log;
  EXPECT_NE(log.find("1 meshes split into clusters of at most 400 triangles"), std::string::npos)
      << log;
  EXPECT_EQ(loadScene(dir / "s").objects.size(), 4u + 4u + 1u);
  log = test::runCapture(test::tool("dmmr-preprocess") + " " + model + " -o " + (dir / "t") +
                             " --cluster-triangles -5",
                         &status);
  EXPECT_NE(status, 0) << log;
}

}  // namespace
