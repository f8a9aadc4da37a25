#include "scenegen.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include <osg/Geode>
#include <osg/Geometry>
#include <osg/Material>
#include <osg/MatrixTransform>
#include <osg/NodeVisitor>
#include <osg/TriangleFunctor>
#include <osg/TriangleIndexFunctor>
#include <osgDB/ReadFile>
#include <osgDB/WriteFile>

#include "error.h"

namespace sg = dmmr::scenegen;
namespace fs = std::filesystem;

namespace {

// Every geode reached from the root, with its world matrix and depth, plus
// facts about the transforms on the way.
class Collector : public osg::NodeVisitor {
 public:
  struct Item {
    osg::Geode* geode;
    osg::Matrixd world;
    int depth;
  };
  Collector() : osg::NodeVisitor(TRAVERSE_ALL_CHILDREN) {}
  void apply(osg::MatrixTransform& t) override {
    const osg::Matrixd& m = t.getMatrix();
    bool rotates = std::fabs(m(0, 0) - 1) > 1e-9 || std::fabs(m(1, 1) - 1) > 1e-9;
    rotations += rotates;
    translations += m.getTrans().length() > 1e-9;
    stack_.push_back(m * stack_.back());
    descend(t);
    stack_.pop_back();
  }
  void apply(osg::Group& g) override { descend(g); }
  void apply(osg::Geode& g) override {
    items.push_back({&g, stack_.back(), depth_});
    maxDepth = std::max(maxDepth, depth_);
  }
  std::vector<Item> items;
  int maxDepth = 0, rotations = 0, translations = 0;

 private:
  void descend(osg::Group& g) {
    ++depth_;
    traverse(g);
    --depth_;
  }
  std::vector<osg::Matrixd> stack_{osg::Matrixd()};
  int depth_ = 0;
};

Collector collect(osg::Node& n) {
  Collector c;
  n.accept(c);
  return c;
}

struct TriCount {
  uint64_t n = 0;
  void operator()(unsigned, unsigned, unsigned) { ++n; }
};

uint64_t triangles(const osg::Geometry& g) {
  osg::TriangleIndexFunctor<TriCount> f;
  const_cast<osg::Geometry&>(g).accept(f);
  return f.n;
}

uint64_t triangles(osg::Node& root) {
  uint64_t n = 0;
  for (const auto& it : collect(root).items)
    for (unsigned i = 0; i < it.geode->getNumDrawables(); ++i)
      n += triangles(*it.geode->getDrawable(i)->asGeometry());
  return n;
}

const osg::Geometry& geometryOf(const osg::Geode& g) {
  return *g.getDrawable(0)->asGeometry();
}

const osg::Vec3Array& verticesOf(const osg::Geode& g) {
  return *static_cast<const osg::Vec3Array*>(geometryOf(g).getVertexArray());
}

// True when both scenes have the same geodes in the same places with the same vertices.
bool sameScene(osg::Node& a, osg::Node& b) {
  Collector ca = collect(a), cb = collect(b);
  if (ca.items.size() != cb.items.size()) return false;
  for (size_t i = 0; i < ca.items.size(); ++i) {
    const auto &x = ca.items[i], &y = cb.items[i];
    if (x.world != y.world || x.geode->getName() != y.geode->getName()) return false;
    const osg::Vec3Array &vx = verticesOf(*x.geode), &vy = verticesOf(*y.geode);
    if (vx.size() != vy.size() || !std::equal(vx.begin(), vx.end(), vy.begin())) return false;
  }
  return true;
}

// Signed volume enclosed by the triangles (positive for outward winding).
struct VolumeSum {
  double v = 0;
  void operator()(const osg::Vec3& a, const osg::Vec3& b, const osg::Vec3& c) {
    v += osg::Vec3d(a) * (osg::Vec3d(b) ^ osg::Vec3d(c)) / 6.0;
  }
};

// Triangles whose winding disagrees with their vertex normals.
struct NormalCheck {
  const osg::Vec3Array* v = nullptr;
  const osg::Vec3Array* n = nullptr;
  uint64_t total = 0, bad = 0;
  void operator()(unsigned a, unsigned b, unsigned c) {
    osg::Vec3 face = ((*v)[b] - (*v)[a]) ^ ((*v)[c] - (*v)[a]);
    ++total;
    if (face * ((*n)[a] + (*n)[b] + (*n)[c]) <= 0) ++bad;
  }
};

// Backface culling and lighting need outward winding agreeing with the
// normals: curved parts are checked against their normals, flat parts (closed
// boxes) by their enclosed volume being positive.
void expectOutwardWinding(osg::Node& root) {
  uint64_t total = 0, bad = 0;
  for (const auto& it : collect(root).items) {
    osg::Geometry& g = *it.geode->getDrawable(0)->asGeometry();
    if (g.getNormalArray()) {
      osg::TriangleIndexFunctor<NormalCheck> f;
      f.v = static_cast<const osg::Vec3Array*>(g.getVertexArray());
      f.n = static_cast<const osg::Vec3Array*>(g.getNormalArray());
      g.accept(f);
      total += f.total;
      bad += f.bad;
    } else {
      osg::TriangleFunctor<VolumeSum> f;
      g.accept(f);
      EXPECT_GT(f.v, 0) << it.geode->getName();
    }
  }
  EXPECT_GT(total, 0u);
  EXPECT_LT(double(bad), 0.001 * total);
}

class TempDir {
 public:
  TempDir() {
    path_ = fs::temp_directory_path() / ("scenegen_test_" + std::to_string(::getpid()));
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  std::string file(const std::string& name) const { return (path_ / name).string(); }

 private:
  fs::path path_;
};

osg::ref_ptr<osg::Node> smallPlant(uint64_t seed = 7) {
  return sg::makePlant({seed, 200'000, 2000});
}

}  // namespace

// ------------------------------------------------------------------ plant

TEST(PlantTest, SameSeedGivesIdenticalScene) {
  auto a = smallPlant(), b = smallPlant();
  EXPECT_TRUE(sameScene(*a, *b));
}

TEST(PlantTest, DifferentSeedsDiffer) {
  auto a = smallPlant(7), b = smallPlant(8);
  EXPECT_FALSE(sameScene(*a, *b));
}

struct Target {
  uint64_t triangles;
  uint32_t geodes;
};

class PlantTargetTest : public ::testing::TestWithParam<Target> {};

TEST_P(PlantTargetTest, TriangleAndGeodeCountsNearTarget) {
  Target t = GetParam();
  auto plant = sg::makePlant({3, t.triangles, t.geodes});
  double tris = double(triangles(*plant));
  EXPECT_NEAR(tris, double(t.triangles), 0.10 * t.triangles);
  EXPECT_NEAR(double(collect(*plant).items.size()), double(t.geodes), 0.02 * t.geodes);
  sg::SceneStats s = sg::sceneStats(*plant);
  EXPECT_EQ(s.triangles, uint64_t(tris));
  EXPECT_EQ(s.instancedTriangles, s.triangles);
  EXPECT_EQ(s.geodes, s.geometries);
}

INSTANTIATE_TEST_SUITE_P(Targets, PlantTargetTest,
                         ::testing::Values(Target{50'000, 500}, Target{1'000'000, 20000},
                                           Target{3'000'000, 20000}, Target{12'500'000, 20000}));

TEST(PlantTest, TooFewTrianglesLowersGeodeCount) {
  auto plant = sg::makePlant({1, 20'000, 20000});
  size_t geodes = collect(*plant).items.size();
  EXPECT_LT(geodes, 2000u);
  EXPECT_GT(geodes, 100u);
  EXPECT_NEAR(double(triangles(*plant)), 20'000.0, 2'000.0);
}

TEST(PlantTest, LayoutAndAttributes) {
  auto plant = smallPlant();
  Collector c = collect(*plant);
  EXPECT_GE(c.maxDepth, 6);
  EXPECT_GT(c.rotations, 10);
  EXPECT_GT(c.translations, 100);
  int curved = 0, flat = 0, coloured = 0;
  for (const auto& it : c.items) {
    ASSERT_EQ(it.geode->getNumDrawables(), 1u);
    const osg::Geometry& g = geometryOf(*it.geode);
    ASSERT_EQ(g.getNumPrimitiveSets(), 1u);
    auto* de = dynamic_cast<const osg::DrawElements*>(g.getPrimitiveSet(0));
    ASSERT_TRUE(de);
    EXPECT_EQ(de->getMode(), GLenum(GL_TRIANGLES));
    const osg::StateSet* ss = it.geode->getStateSet();
    ASSERT_TRUE(ss);
    EXPECT_TRUE(ss->getAttribute(osg::StateAttribute::MATERIAL));
    size_t nv = verticesOf(*it.geode).size();
    if (g.getNormalArray()) {
      ++curved;
      EXPECT_EQ(g.getNormalArray()->getBinding(), osg::Array::BIND_PER_VERTEX);
      EXPECT_EQ(g.getNormalArray()->getNumElements(), nv);
    } else {
      ++flat;
    }
    if (g.getColorArray()) {
      ++coloured;
      EXPECT_EQ(g.getColorArray()->getBinding(), osg::Array::BIND_PER_VERTEX);
      EXPECT_EQ(g.getColorArray()->getNumElements(), nv);
    }
  }
  EXPECT_GT(curved, 200);
  EXPECT_GT(flat, 200);
  EXPECT_GT(coloured, 5);
  EXPECT_LT(coloured, int(c.items.size()) / 10);

  osg::BoundingBox bb = sg::sceneBounds(*plant);
  EXPECT_NEAR(bb.xMax() - bb.xMin(), 100, 10);
  EXPECT_NEAR(bb.yMax() - bb.yMin(), 100, 10);
  EXPECT_NEAR(bb.zMax() - bb.zMin(), 40, 2);
  EXPECT_NEAR(bb.center().x(), 0, 3);
  EXPECT_NEAR(bb.zMin(), 0, 0.5);
}

TEST(PlantTest, WindingIsOutward) {
  expectOutwardWinding(*smallPlant());
}

TEST(PlantTest, RejectsZeroSizes) {
  EXPECT_THROW(sg::makePlant({1, 0, 10}), dmmr::Error);
  EXPECT_THROW(sg::makePlant({1, 1000, 0}), dmmr::Error);
}

// ------------------------------------------------------------------ subdivide

TEST(SubdivideTest, CutsEveryTriangleKeepingShapeWindingAndInstances) {
  osg::ref_ptr<osg::Node> rep = sg::replicate(smallPlant().get(), 2, 0);
  osg::ref_ptr<osg::Node> sub = sg::subdivide(rep.get(), 3);
  sg::SceneStats a = sg::sceneStats(*rep), b = sg::sceneStats(*sub);
  EXPECT_EQ(b.triangles, 9 * a.triangles);
  EXPECT_EQ(b.geodes, a.geodes);  // the copies still share every geode
  EXPECT_EQ(b.geodeInstances, a.geodeInstances);
  EXPECT_EQ(sg::sceneStats(*rep).triangles, a.triangles);  // the input is left as it was
  osg::BoundingBox ba = sg::sceneBounds(*rep), bb = sg::sceneBounds(*sub);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(ba._min[k], bb._min[k], 1e-4);
    EXPECT_NEAR(ba._max[k], bb._max[k], 1e-4);
  }
  expectOutwardWinding(*sub);
  // Same enclosed volume per closed flat part: no cracks, no flipped pieces.
  auto ia = collect(*rep).items, ib = collect(*sub).items;
  ASSERT_EQ(ia.size(), ib.size());
  for (size_t i = 0; i < ia.size(); ++i) {
    osg::Geometry& ga = *ia[i].geode->getDrawable(0)->asGeometry();
    if (ga.getNormalArray()) continue;
    osg::TriangleFunctor<VolumeSum> fa, fb;
    ga.accept(fa);
    ib[i].geode->getDrawable(0)->accept(fb);
    EXPECT_NEAR(fa.v, fb.v, 1e-4 * std::fabs(fa.v) + 1e-9) << i;
  }
}

TEST(SubdivideTest, EdgePointsAreShared) {
  // A closed tetrahedron: V + E (n - 1) + F (n - 1)(n - 2) / 2 vertices.
  auto* v = new osg::Vec3Array;
  for (osg::Vec3 p :
       {osg::Vec3(0, 0, 0), osg::Vec3(1, 0, 0), osg::Vec3(0, 1, 0), osg::Vec3(0, 0, 1)})
    v->push_back(p);
  auto* geom = new osg::Geometry;
  geom->setVertexArray(v);
  const GLuint idx[12] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
  geom->addPrimitiveSet(new osg::DrawElementsUInt(GL_TRIANGLES, 12, idx));
  osg::ref_ptr<osg::Geode> g = new osg::Geode;
  g->addDrawable(geom);
  const uint32_t n = 4;
  osg::ref_ptr<osg::Node> sub = sg::subdivide(g.get(), n);
  const osg::Geometry* out = sub->asGeode()->getDrawable(0)->asGeometry();
  EXPECT_EQ(out->getVertexArray()->getNumElements(), 4 + 6 * (n - 1) + 4 * (n - 1) * (n - 2) / 2);
  EXPECT_EQ(sg::countTriangles(*out), 4 * n * n);
  osg::TriangleFunctor<VolumeSum> fa, fb;
  geom->accept(fa);
  const_cast<osg::Geometry*>(out)->accept(fb);
  EXPECT_NEAR(fb.v, fa.v, 1e-7);
}

TEST(SubdivideTest, OneIsTheInputAndBadCountsThrow) {
  osg::ref_ptr<osg::Node> plant = smallPlant();
  EXPECT_EQ(sg::subdivide(plant.get(), 1).get(), plant.get());
  EXPECT_THROW(sg::subdivide(plant.get(), 0), dmmr::Error);
  EXPECT_THROW(sg::subdivide(nullptr, 2), dmmr::Error);
}

// ------------------------------------------------------------------ monument

TEST(MonumentTest, DeterministicAndNearTarget) {
  auto a = sg::makeMonument({5, 500'000, 600}), b = sg::makeMonument({5, 500'000, 600});
  EXPECT_TRUE(sameScene(*a, *b));
  EXPECT_FALSE(sameScene(*a, *sg::makeMonument({6, 500'000, 600})));
  EXPECT_NEAR(double(triangles(*a)), 500'000.0, 50'000.0);
  EXPECT_NEAR(double(collect(*a).items.size()), 600.0, 12.0);
}

TEST(MonumentTest, DefaultSizeAndExtent) {
  auto m = sg::makeMonument({});
  EXPECT_NEAR(double(triangles(*m)), 1e6, 1e5);
  Collector c = collect(*m);
  EXPECT_NEAR(double(c.items.size()), 1000.0, 20.0);
  EXPECT_GE(c.maxDepth, 6);
  EXPECT_GT(c.rotations, 10);
  osg::BoundingBox bb = sg::sceneBounds(*m);
  EXPECT_NEAR(bb.xMax() - bb.xMin(), 400, 10);
  EXPECT_NEAR(bb.yMax() - bb.yMin(), 400, 10);
  int curved = 0, flat = 0;
  for (const auto& it : c.items) (geometryOf(*it.geode).getNormalArray() ? curved : flat)++;
  EXPECT_GT(curved, 100);
  EXPECT_GT(flat, 50);
  expectOutwardWinding(*m);
}

// ------------------------------------------------------------------ replicate

TEST(ReplicateTest, CopiesShareOneChild) {
  auto plant = smallPlant();
  auto rep = sg::replicate(plant.get(), 10, 0);
  osg::Group* g = rep->asGroup();
  ASSERT_TRUE(g);
  ASSERT_EQ(g->getNumChildren(), 10u);
  std::set<std::pair<double, double>> spots;
  for (unsigned i = 0; i < 10; ++i) {
    auto* t = dynamic_cast<osg::MatrixTransform*>(g->getChild(i));
    ASSERT_TRUE(t);
    ASSERT_EQ(t->getNumChildren(), 1u);
    EXPECT_EQ(t->getChild(0), plant.get());
    spots.insert({t->getMatrix().getTrans().x(), t->getMatrix().getTrans().y()});
  }
  EXPECT_EQ(spots.size(), 10u);
  // Automatic spacing: the bounding sphere's diameter * 1.1 between neighbours.
  auto* t0 = static_cast<osg::MatrixTransform*>(g->getChild(0));
  auto* t1 = static_cast<osg::MatrixTransform*>(g->getChild(1));
  double step = (t1->getMatrix().getTrans() - t0->getMatrix().getTrans()).length();
  EXPECT_NEAR(step, 2.2 * plant->getBound().radius(), 1e-6 * step);

  sg::SceneStats s = sg::sceneStats(*rep), one = sg::sceneStats(*plant);
  EXPECT_EQ(s.geometries, one.geometries);
  EXPECT_EQ(s.triangles, one.triangles);
  EXPECT_EQ(s.instancedTriangles, 10 * one.triangles);
  EXPECT_EQ(s.geodeInstances, 10 * one.geodes);
}

TEST(ReplicateTest, ExplicitSpacingAndNearSquareGrid) {
  auto plant = sg::makePlant({1, 20'000, 200});
  auto rep = sg::replicate(plant.get(), 7, 250.0);
  osg::BoundingBox bb = sg::sceneBounds(*rep), one = sg::sceneBounds(*plant);
  // 7 copies: 3 columns, 3 rows.
  EXPECT_NEAR(bb.xMax() - bb.xMin(), 500 + (one.xMax() - one.xMin()), 1e-3);
  EXPECT_NEAR(bb.yMax() - bb.yMin(), 500 + (one.yMax() - one.yMin()), 1e-3);
}

TEST(ReplicateTest, OsgbStoresGeometryOnce) {
  TempDir dir;
  auto plant = smallPlant();
  auto rep = sg::replicate(plant.get(), 16, 0);
  std::string one = dir.file("one.osgb"), many = dir.file("many.osgb");
  ASSERT_TRUE(osgDB::writeNodeFile(*plant, one));
  ASSERT_TRUE(osgDB::writeNodeFile(*rep, many));
  EXPECT_LT(fs::file_size(many), fs::file_size(one) * 11 / 10);

  osg::ref_ptr<osg::Node> back = osgDB::readRefNodeFile(many);
  ASSERT_TRUE(back);
  osg::Group* g = back->asGroup();
  ASSERT_TRUE(g);
  ASSERT_EQ(g->getNumChildren(), 16u);
  osg::Node* shared = g->getChild(0)->asGroup()->getChild(0);
  for (unsigned i = 1; i < 16; ++i) EXPECT_EQ(g->getChild(i)->asGroup()->getChild(0), shared);
  EXPECT_EQ(sg::sceneStats(*back).instancedTriangles, 16 * sg::sceneStats(*plant).triangles);
}

TEST(ReplicateTest, RealMesh) {
#ifdef DMMR_SOURCE_DIR
  std::string path = std::string(DMMR_SOURCE_DIR) + "/../shared/models/skull/skull.obj";
#else
  std::string path = "../shared/models/skull/skull.obj";
#endif
  if (!fs::exists(path)) GTEST_SKIP() << "shared models absent: " << path;
  osg::ref_ptr<osg::Node> skull = osgDB::readRefNodeFile(path);
  ASSERT_TRUE(skull);
  auto rep = sg::replicate(skull.get(), 4, 0);
  sg::SceneStats s = sg::sceneStats(*rep);
  EXPECT_GT(s.triangles, 50'000u);
  EXPECT_EQ(s.instancedTriangles, 4 * s.triangles);
}

TEST(ReplicateTest, Errors) {
  auto plant = sg::makePlant({1, 20'000, 200});
  EXPECT_THROW(sg::replicate(nullptr, 4, 0), dmmr::Error);
  EXPECT_THROW(sg::replicate(plant.get(), 0, 0), dmmr::Error);
  EXPECT_THROW(sg::replicate(plant.get(), 4, std::nan("")), dmmr::Error);
  osg::ref_ptr<osg::Group> empty = new osg::Group;
  EXPECT_THROW(sg::replicate(empty.get(), 4, 0), dmmr::Error);
}

// ------------------------------------------------------------------ walkthroughs

namespace {

dmmr::Vec3d toDmmr(const osg::Vec3d& v) {
  return {v.x(), v.y(), v.z()};
}

void expectWellFormed(const dmmr::Walkthrough& w, uint32_t frames) {
  ASSERT_EQ(w.points.size(), frames);
  for (size_t i = 0; i < w.points.size(); ++i) {
    const auto& p = w.points[i];
    EXPECT_NEAR(p.time, i / 30.0, 1e-12);
    if (i > 0) {
      EXPECT_GT(p.time, w.points[i - 1].time);
    }
    const auto& q = p.rotation;
    EXPECT_NEAR(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w, 1.0, 1e-9);
    EXPECT_TRUE(dmmr::isFinite(p.position));
  }
}

// Cosine of the angle between the camera's view direction and the way to `target`.
double facing(const dmmr::ControlPoint& p, dmmr::Vec3d target) {
  dmmr::Vec3d forward = dmmr::rotate(p.rotation, {0, 0, -1});
  return dmmr::dot(dmmr::normalize(forward), dmmr::normalize(target - p.position));
}

}  // namespace

TEST(WalkthroughTest, FlyThroughCrossesPlant) {
  auto plant = smallPlant();
  osg::BoundingBox bb = sg::sceneBounds(*plant);
  auto w = sg::makeWalkthrough(bb, 120, sg::PathKind::FlyThrough);
  expectWellFormed(w, 120);
  const auto& first = w.points.front();
  EXPECT_LT(first.position.x, bb.xMin());  // starts outside
  EXPECT_GT(w.points.back().position.x, bb.center().x());
  for (const auto& p : w.points)
    EXPECT_NEAR(p.position.z, bb.zMin() + (bb.zMax() - bb.zMin()) / 3, 1e-6);
  EXPECT_GT(facing(w.points[60], toDmmr(bb.center())), std::cos(45 * M_PI / 180));
  // Looks slightly down, never up.
  for (const auto& p : w.points) EXPECT_LT(dmmr::rotate(p.rotation, {0, 0, -1}).z, -0.1);
}

TEST(WalkthroughTest, OrbitLooksAtCentre) {
  osg::BoundingBox bb(-1, -2, -3, 5, 4, 3);
  auto w = sg::makeWalkthrough(bb, 48, sg::PathKind::Orbit);
  expectWellFormed(w, 48);
  dmmr::Vec3d c = toDmmr(bb.center());
  for (const auto& p : w.points) {
    EXPECT_NEAR(dmmr::length(p.position - c), 2.2 * bb.radius(), 1e-6);
    EXPECT_GT(facing(p, c), 0.9999);
    EXPECT_GT(dmmr::rotate(p.rotation, {0, 1, 0}).z, 0);  // upright
  }
}

TEST(WalkthroughTest, AroundCirclesCloseLookingAtCentre) {
  osg::BoundingBox bb(-4, -3, 0, 4, 3, 2);
  auto w = sg::makeWalkthrough(bb, 48, sg::PathKind::Around);
  expectWellFormed(w, 48);
  dmmr::Vec3d c = toDmmr(bb.center());
  for (const auto& p : w.points) {
    dmmr::Vec3d d = p.position - c;
    EXPECT_NEAR(std::hypot(d.x, d.y), 0.4 * 10, 1e-9);  // 0.8 of half the XY diagonal
    EXPECT_NEAR(d.z, 0.5, 1e-9);
    EXPECT_GT(facing(p, c), 0.9999);
  }
}

TEST(WalkthroughTest, SingleFrameAndErrors) {
  osg::BoundingBox bb(0, 0, 0, 10, 10, 10);
  expectWellFormed(sg::makeWalkthrough(bb, 1, sg::PathKind::FlyThrough), 1);
  EXPECT_THROW(sg::makeWalkthrough(bb, 0, sg::PathKind::Orbit), dmmr::Error);
  EXPECT_THROW(sg::makeWalkthrough(osg::BoundingBox(), 10, sg::PathKind::Orbit), dmmr::Error);
}
