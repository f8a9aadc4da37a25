// Meshes split into clusters, end to end (issue 15): dense meshes (a
// subdivided monument, instanced twice on a grid and once rotated)
// preprocessed whole and in clusters. dmmr-reference draws the clustered
// scene exactly as the whole one (tolerance zero: clusters keep every
// triangle's floats, and the order of a mesh's triangles, which part order
// changes within each geometry, matters only where two of them have equal
// depth at a pixel, which this scene has none of), and dmmr-render with 1
// and 3 clients equals the reference on the clustered scene, drawing
// objects part by part or whole.
#include <gtest/gtest.h>

#include <cstdio>

#include <osg/MatrixTransform>
#include <osgDB/WriteFile>

#include "compare.h"
#include "preprocess.h"
#include "scene.h"
#include "scenegen.h"
#include "test_support.h"
#include "walkthrough.h"

using namespace dmmr;
using dmmr::test::TempDir;
namespace sg = dmmr::scenegen;

namespace {

const std::string kView = " --no-progress --width 160 --height 120";

struct DenseScene {
  TempDir dir;
  std::string path = dir / "path";
  DenseScene() {
    osg::ref_ptr<osg::Node> dense = sg::subdivide(sg::makeMonument({5, 60000, 12}).get(), 2);
    osg::ref_ptr<osg::Group> root = new osg::Group;
    root->addChild(sg::replicate(dense.get(), 2, 0));
    auto* turned = new osg::MatrixTransform(osg::Matrixd::rotate(0.3, osg::Vec3d(0, 0, 1)) *
                                            osg::Matrixd::translate(0, 500, 0));
    turned->addChild(dense);
    root->addChild(turned);
    std::string model = dir / "dense.osgb";
    EXPECT_TRUE(osgDB::writeNodeFile(*root, model));
    writeWalkthrough(path,
                     sg::makeWalkthrough(sg::sceneBounds(*root), 4, sg::PathKind::FlyThrough));
    for (uint64_t c : {uint64_t(0), uint64_t(1024)}) {
      PreprocessOptions o;
      o.inputs = {model};
      o.out = scene(c);
      o.progress = false;
      o.cluster_triangles = c;
      stats[c != 0] = preprocess(o);
      EXPECT_EQ(test::run(test::tool("dmmr-reference") + kView + " --scene " + scene(c) +
                          " --walkthrough " + path + " --out " + reference(c)),
                0);
    }
  }
  std::string scene(uint64_t c) const { return dir / ("scene-c" + std::to_string(c)); }
  std::string reference(uint64_t c) const { return dir / ("reference-c" + std::to_string(c)); }
  PreprocessStats stats[2];
};

DenseScene& denseScene() {
  static DenseScene s;  // built once per test binary, removed at exit
  return s;
}

void expectIdentical(const std::string& a, const std::string& b) {
  std::vector<FrameDiff> diffs = compareDirectories(a, b);
  ASSERT_EQ(diffs.size(), 4u);
  for (const FrameDiff& d : diffs) EXPECT_EQ(d.diff.differing_pixels, 0) << d.name << " " << d.diff;
}

}  // namespace

TEST(Clusters, TheReferenceDrawsTheClusteredSceneAsTheWholeOne) {
  DenseScene& s = denseScene();
  // The monument's big geodes were split; many objects now.
  EXPECT_GT(s.stats[1].split_meshes, 3u);
  EXPECT_GT(s.stats[1].objects, 4 * s.stats[0].objects);
  EXPECT_EQ(s.stats[1].triangles, s.stats[0].triangles);
  expectIdentical(s.reference(0), s.reference(1024));
}

class ClustersDistributed : public testing::TestWithParam<int> {};

TEST_P(ClustersDistributed, FramesArePixelIdenticalToTheReference) {
  DenseScene& s = denseScene();
  std::string out = s.dir / ("frames" + std::to_string(GetParam()));
  int status = 0;
  std::string log = test::runCapture(
      "timeout 120 " + test::mpirun(GetParam() + 1) + " " + test::tool("dmmr-render") + kView +
          " --scene " + s.scene(1024) + " --walkthrough " + s.path + " --out " + out,
      &status);
  ASSERT_EQ(status, 0) << log;
  expectIdentical(s.reference(1024), out);
}

INSTANTIATE_TEST_SUITE_P(Clients, ClustersDistributed, testing::Values(1, 3));

// Part draws (--part-draws, the default): only the parts of an object that
// reach the client's region, and are not found hidden, are drawn. In both
// stage modes, with 1 and 3 clients, every frame stays exact, and the
// clients draw fewer triangles between them than when drawing whole objects.
TEST(Clusters, PartDrawsDrawLessAndStayExact) {
  DenseScene& s = denseScene();
  for (const char* stages : {"split", "fused"})
    for (int clients : {1, 3}) {
      double drawn[2] = {0, 0};
      for (int on : {0, 1}) {
        std::string out =
            s.dir / ("part-draws" + std::to_string(on) + stages + std::to_string(clients));
        int status = 0;
        std::string log = test::runCapture(
            "timeout 120 " + test::mpirun(clients + 1) + " " + test::tool("dmmr-render") + kView +
                " --scene " + s.scene(1024) + " --walkthrough " + s.path + " --out " + out +
                " --stages " + stages + " --cost-model off --part-draws " + (on ? "on" : "off") +
                " --stats " + out + ".csv",
            &status);
        ASSERT_EQ(status, 0) << log;
        expectIdentical(s.reference(1024), out);
        for (const test::CsvRow& row : test::readCsv(out + ".csv"))
          for (int k = 1; k <= clients; ++k)
            drawn[on] += row["c" + std::to_string(k) + "_triangles"];
      }
      EXPECT_LT(drawn[1], drawn[0]) << stages << ", " << clients << " clients";
      std::printf("%s, %d clients: triangles drawn %.0f by parts, %.0f whole\n", stages, clients,
                  drawn[1], drawn[0]);
    }
}
