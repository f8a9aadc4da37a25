// dmmr_baseline without GL: where OcclusionQueryNodes go, vertex counts, and
// the OSG camera matching dmmr's.
#include <gtest/gtest.h>

#include <osg/Geode>
#include <osg/Geometry>
#include <osg/MatrixTransform>
#include <osg/OcclusionQueryNode>

#include "camera.h"
#include "osg_baseline.h"

using namespace dmmr;

namespace {

osg::ref_ptr<osg::Geode> geodeWith(unsigned vertices) {
  osg::ref_ptr<osg::Vec3Array> v = new osg::Vec3Array(vertices);
  for (unsigned i = 0; i < vertices; ++i) (*v)[i].set(float(i % 7), float(i % 5), float(i % 3));
  osg::ref_ptr<osg::Geometry> g = new osg::Geometry;
  g->setVertexArray(v);
  g->addPrimitiveSet(new osg::DrawArrays(GL_TRIANGLES, 0, vertices - vertices % 3));
  osg::ref_ptr<osg::Geode> geode = new osg::Geode;
  geode->addDrawable(g);
  return geode;
}

osg::OcclusionQueryNode* oqnAbove(osg::Node* n, unsigned parent = 0) {
  return n->getNumParents() > parent ? dynamic_cast<osg::OcclusionQueryNode*>(n->getParent(parent))
                                     : nullptr;
}

}  // namespace

TEST(CountVertices, SumsGeometryAndStopsPastTheLimit) {
  osg::ref_ptr<osg::Group> g = new osg::Group;
  g->addChild(geodeWith(300));
  g->addChild(geodeWith(30));
  EXPECT_EQ(countVertices(*g), 330u);
  EXPECT_EQ(countVertices(*g, 100), 300u);  // stopped after the first geode
}

// root -> A -> {G1 (6000), G2 (100)}; root -> B -> {G3 (3000), G4 (3000)}.
// G1 exceeds 5000 alone; B's children do not, B does; A and root have a query
// below them and get none (no nesting).
TEST(InsertOcclusionQueries, LowestGroupOverTheThresholdNoNesting) {
  osg::ref_ptr<osg::Group> root = new osg::Group, a = new osg::Group, b = new osg::Group;
  osg::ref_ptr<osg::Geode> g1 = geodeWith(6000), g2 = geodeWith(100), g3 = geodeWith(3000),
                           g4 = geodeWith(3000);
  root->addChild(a);
  root->addChild(b);
  a->addChild(g1);
  a->addChild(g2);
  b->addChild(g3);
  b->addChild(g4);
  OcclusionSettings s;
  s.visibility_threshold = 7;
  s.query_frame_count = 2;
  EXPECT_EQ(insertOcclusionQueries(*root, s), 2u);
  osg::OcclusionQueryNode* q1 = oqnAbove(g1);
  osg::OcclusionQueryNode* qb = oqnAbove(b);
  ASSERT_NE(q1, nullptr);
  ASSERT_NE(qb, nullptr);
  EXPECT_EQ(oqnAbove(g2), nullptr);
  EXPECT_EQ(oqnAbove(g3), nullptr);
  EXPECT_EQ(oqnAbove(a), nullptr);
  EXPECT_EQ(q1->getParent(0), a.get());
  EXPECT_EQ(qb->getParent(0), root.get());
  EXPECT_EQ(q1->getVisibilityThreshold(), 7u);
  EXPECT_EQ(q1->getQueryFrameCount(), 2u);
  EXPECT_EQ(q1->getQueryStateSet(), qb->getQueryStateSet());  // shared, as the example does
  EXPECT_EQ(a->getNumChildren(), 2u);
  EXPECT_EQ(root->getNumChildren(), 2u);
}

// One subgraph instanced twice: one query per placement, none above the
// transforms (they have one below), and the instance is still shared.
TEST(InsertOcclusionQueries, OneQueryPerInstance) {
  osg::ref_ptr<osg::Group> root = new osg::Group;
  osg::ref_ptr<osg::Geode> shared = geodeWith(6000);
  osg::ref_ptr<osg::MatrixTransform> t1 = new osg::MatrixTransform, t2 = new osg::MatrixTransform;
  t2->setMatrix(osg::Matrixd::translate(100, 0, 0));
  t1->addChild(shared);
  t2->addChild(shared);
  root->addChild(t1);
  root->addChild(t2);
  EXPECT_EQ(insertOcclusionQueries(*root, {}), 2u);
  ASSERT_EQ(shared->getNumParents(), 2u);
  osg::OcclusionQueryNode* q0 = oqnAbove(shared, 0);
  osg::OcclusionQueryNode* q1 = oqnAbove(shared, 1);
  ASSERT_NE(q0, nullptr);
  ASSERT_NE(q1, nullptr);
  EXPECT_NE(q0, q1);
  EXPECT_EQ(oqnAbove(t1), nullptr);
  EXPECT_EQ(oqnAbove(t2), nullptr);
}

TEST(InsertOcclusionQueries, KeepsExistingQueriesAndSkipsTheRoot) {
  osg::ref_ptr<osg::Group> root = new osg::Group;
  osg::ref_ptr<osg::OcclusionQueryNode> existing = new osg::OcclusionQueryNode;
  osg::ref_ptr<osg::Group> inner = new osg::Group;
  inner->addChild(geodeWith(6000));
  existing->addChild(inner);
  root->addChild(existing);
  EXPECT_EQ(insertOcclusionQueries(*root, {}), 0u);
  EXPECT_EQ(oqnAbove(inner), existing.get());

  osg::ref_ptr<osg::Geode> lone = geodeWith(6000);  // a root has no parent to insert under
  EXPECT_EQ(insertOcclusionQueries(*lone, {}), 0u);

  osg::ref_ptr<osg::Group> small = new osg::Group;  // under the threshold: nothing
  small->addChild(geodeWith(4000));
  osg::ref_ptr<osg::Group> top = new osg::Group;
  top->addChild(small);
  OcclusionSettings s;
  EXPECT_EQ(insertOcclusionQueries(*top, s), 0u);
  s.min_vertices = 3999;
  EXPECT_EQ(insertOcclusionQueries(*top, s), 1u);
}

// OSG's view matrix for a control point maps world points where dmmr's does.
TEST(OsgViewMatrix, MatchesDmmrCamera) {
  const Vec3d eyes[] = {{0, 0, 0}, {10, -20, 5}, {-3.5, 7, 100}};
  const Vec3d targets[] = {{1, 2, 3}, {0, 0, 0}, {50, 50, -10}};
  const Vec3d points[] = {{0, 0, 0}, {1, 2, 3}, {-40, 12, 9}, {100, -100, 50}};
  for (int i = 0; i < 3; ++i) {
    ControlPoint p{0, eyes[i], lookAtRotation(eyes[i], targets[i], {0, 0, 1})};
    Mat4d ours = viewMatrix(cameraAt(p, 640, 480, 45, 0.1));
    osg::Matrixd theirs = osgViewMatrix(p);
    for (const Vec3d& w : points) {
      Vec3d a = ours.transformPoint(w);
      osg::Vec3d b = osg::Vec3d(w.x, w.y, w.z) * theirs;
      EXPECT_NEAR(a.x, b.x(), 1e-9);
      EXPECT_NEAR(a.y, b.y(), 1e-9);
      EXPECT_NEAR(a.z, b.z(), 1e-9);
    }
    // the target lies straight ahead, down -Z
    osg::Vec3d t = osg::Vec3d(targets[i].x, targets[i].y, targets[i].z) * theirs;
    EXPECT_NEAR(t.x(), 0, 1e-9);
    EXPECT_NEAR(t.y(), 0, 1e-9);
    EXPECT_LT(t.z(), 0);
  }
}
