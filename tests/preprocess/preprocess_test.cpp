// The preprocessor against hand-computed bounds, instancing, bad input, and
// the real models beside the checkout.
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <cstring>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <osg/Billboard>
#include <osg/Geode>
#include <osg/Geometry>
#include <osg/Material>
#include <osg/MatrixTransform>
#include <osg/PagedLOD>
#include <osg/Texture2D>
#include <osgDB/ReadFile>
#include <osgDB/WriteFile>
#include <osgUtil/Statistics>

#include "atomic_file.h"
#include "error.h"
#include "formats.h"
#include "preprocess.h"
#include "scene.h"
#include "test_support.h"

namespace fs = std::filesystem;
using namespace dmmr;
using dmmr::test::TempDir;

namespace {

// An axis-aligned unit cube centred on `c` (12 triangles), optionally with
// normals; vertices at c +- 0.5.
osg::ref_ptr<osg::Geode> cube(osg::Vec3 c = {0, 0, 0}, bool normals = false) {
  auto* v = new osg::Vec3Array;
  for (int i = 0; i < 8; ++i)
    v->push_back(c +
                 osg::Vec3((i & 1) ? 0.5f : -0.5f, (i & 2) ? 0.5f : -0.5f, (i & 4) ? 0.5f : -0.5f));
  const GLuint idx[36] = {0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4,
                          2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5};
  auto* geom = new osg::Geometry;
  geom->setVertexArray(v);
  geom->addPrimitiveSet(new osg::DrawElementsUInt(GL_TRIANGLES, 36, idx));
  if (normals) {
    auto* n = new osg::Vec3Array;
    for (auto& p : *v) {
      osg::Vec3 d = p - c;
      d.normalize();
      n->push_back(d);
    }
    geom->setNormalArray(n, osg::Array::BIND_PER_VERTEX);
  }
  osg::ref_ptr<osg::Geode> g = new osg::Geode;
  g->addDrawable(geom);
  return g;
}

std::string writeModel(const TempDir& dir, osg::Node* node, const std::string& name) {
  std::string path = dir / name;
  EXPECT_TRUE(osgDB::writeNodeFile(*node, path)) << path;
  return path;
}

PreprocessStats run(const std::vector<std::string>& inputs, const std::string& out) {
  PreprocessOptions o;
  o.inputs = inputs;
  o.out = out;
  o.progress = false;
  return preprocess(o);
}

// Triangles as OpenSceneGraph itself counts them (instances counted each).
uint64_t osgTriangleCount(osg::Node* node) {
  osgUtil::StatsVisitor sv;
  node->accept(sv);
  uint64_t tris = 0;
  // The count map holds primitives per mode (quads as quads).
  for (const auto& [mode, count] : sv._instancedStats.getPrimitiveCountMap()) {
    switch (mode) {
      case GL_TRIANGLES:
      case GL_TRIANGLE_STRIP:
      case GL_TRIANGLE_FAN:
        tris += count;
        break;
      case GL_QUADS:
      case GL_QUAD_STRIP:
        tris += 2 * uint64_t(count);
        break;
      case GL_POLYGON:
        ADD_FAILURE() << "GL_POLYGON counts are not triangles in osgUtil";
        break;
      default:
        break;
    }
  }
  return tris;
}

void expectNear(Vec3d a, Vec3d b, double eps = 1e-9) {
  EXPECT_NEAR(a.x, b.x, eps);
  EXPECT_NEAR(a.y, b.y, eps);
  EXPECT_NEAR(a.z, b.z, eps);
}

}  // namespace

TEST(Preprocess, BoundsAndWeightsOfATranslatedScaledCube) {
  TempDir dir;
  osg::ref_ptr<osg::MatrixTransform> t =
      new osg::MatrixTransform(osg::Matrixd::scale(2, 2, 2) * osg::Matrixd::translate(10, 0, 0));
  t->addChild(cube());
  run({writeModel(dir, t.get(), "cube.osgb")}, dir / "scene");
  Scene s = loadScene(dir / "scene");
  ASSERT_EQ(s.objects.size(), 1u);
  const ObjectBounds& o = s.objects[0];
  EXPECT_EQ(o.weight, 12u);
  expectNear(o.box.lo, {9, -1, -1});
  expectNear(o.box.hi, {11, 1, 1});
  expectNear(o.sphere.center, {10, 0, 0});
  EXPECT_NEAR(o.sphere.radius, std::sqrt(3.0), 1e-6);  // half diagonal of a 2-unit cube
  EXPECT_TRUE(o.use_box);                              // 8 < 4/3 pi 3^1.5
  EXPECT_EQ(s.manifest.triangles, 12u);
  expectNear(s.manifest.bounds.lo, {9, -1, -1});
}

TEST(Preprocess, RotatedCubeGetsAConservativeBoxAndExactSphere) {
  TempDir dir;
  osg::ref_ptr<osg::MatrixTransform> t =
      new osg::MatrixTransform(osg::Matrixd::rotate(M_PI / 4, osg::Vec3d(0, 0, 1)));
  t->addChild(cube({3, 0, 0}));  // off-centre in its own frame
  run({writeModel(dir, t.get(), "cube.osgb")}, dir / "scene");
  Scene s = loadScene(dir / "scene");
  const ObjectBounds& o = s.objects[0];
  // Centre (3,0,0) rotated 45 degrees about Z; the rotated unit box spans
  // +-sqrt(2)/2 in x and y around it.
  double h = std::sqrt(0.5), c = 3 * std::sqrt(0.5);
  expectNear(o.sphere.center, {c, c, 0}, 1e-6);
  EXPECT_NEAR(o.sphere.radius, std::sqrt(0.75), 1e-6);
  expectNear(o.box.lo, {c - h, c - h, -0.5}, 1e-6);
  expectNear(o.box.hi, {c + h, c + h, 0.5}, 1e-6);
  // The geometry is stored recentred: its transform carries the offset.
  GeometryData g = loadGeometry(s, o.geometry);
  for (size_t i = 0; i < g.positions.size(); ++i) EXPECT_EQ(std::fabs(g.positions[i]), 0.5f);
}

TEST(Preprocess, InstancesShareOneGeometryFile) {
  TempDir dir;
  osg::ref_ptr<osg::Group> root = new osg::Group;
  osg::ref_ptr<osg::Geode> shared = cube({0, 0, 0}, true);
  for (int i = 0; i < 5; ++i) {
    auto* t = new osg::MatrixTransform(osg::Matrixd::translate(3.0 * i, 0, 0));
    t->addChild(shared);
    root->addChild(t);
  }
  std::string model = writeModel(dir, root.get(), "five.osgb");
  PreprocessStats st = run({model}, dir / "scene");
  Scene s = loadScene(dir / "scene");
  EXPECT_EQ(st.objects, 5u);
  EXPECT_EQ(st.geometries, 1u);
  EXPECT_EQ(s.manifest.triangles, 60u);
  EXPECT_EQ(s.manifest.unique_triangles, 12u);
  size_t files = 0;
  for (auto& e : fs::directory_iterator(dir / "scene/geometry")) files += e.is_regular_file();
  EXPECT_EQ(files, 1u);
  for (int i = 0; i < 5; ++i) {
    EXPECT_EQ(s.objects[i].geometry, 0u);
    expectNear(s.objects[i].sphere.center, {3.0 * i, 0, 0});
  }
}

TEST(Preprocess, StoresOnlyTheAttributesTheModelHas) {
  TempDir dir;
  osg::ref_ptr<osg::Group> root = new osg::Group;
  root->addChild(cube({0, 0, 0}, false));
  root->addChild(cube({2, 0, 0}, true));
  run({writeModel(dir, root.get(), "two.osgb")}, dir / "scene");
  Scene s = loadScene(dir / "scene");
  ASSERT_EQ(s.manifest.geometries, 2u);
  GeometryData bare = loadGeometry(s, s.objects[0].geometry);
  GeometryData withNormals = loadGeometry(s, s.objects[1].geometry);
  EXPECT_TRUE(bare.normals.empty());
  EXPECT_TRUE(bare.colors.empty());
  EXPECT_TRUE(bare.texcoords.empty());
  EXPECT_EQ(withNormals.normals.size(), withNormals.positions.size());
}

TEST(Preprocess, MaterialDiffuseIsKept) {
  TempDir dir;
  osg::ref_ptr<osg::Geode> g = cube();
  auto* m = new osg::Material;
  m->setDiffuse(osg::Material::FRONT_AND_BACK, osg::Vec4(0.25f, 0.5f, 0.75f, 1.f));
  g->getOrCreateStateSet()->setAttribute(m);
  run({writeModel(dir, g.get(), "m.osgb")}, dir / "scene");
  GeometryData geo = loadGeometry(loadScene(dir / "scene"), 0);
  ASSERT_EQ(geo.submeshes.size(), 1u);
  EXPECT_EQ(geo.submeshes[0].diffuse[0], 0.25f);
  EXPECT_EQ(geo.submeshes[0].diffuse[2], 0.75f);
}

TEST(Preprocess, NonFiniteVerticesAreDroppedWithTheirTrianglesAndCounted) {
  TempDir dir;
  osg::ref_ptr<osg::Geode> g = cube();
  auto* v = static_cast<osg::Vec3Array*>(g->getDrawable(0)->asGeometry()->getVertexArray());
  (*v)[7] = osg::Vec3(NAN, 0, 0);  // vertex 7 is used by 3 of the 12 triangles
  PreprocessStats st = run({writeModel(dir, g.get(), "nan.osgb")}, dir / "scene");
  EXPECT_EQ(st.nonfinite_vertices, 1u);
  EXPECT_EQ(st.dropped_triangles, 3u);
  EXPECT_EQ(st.triangles, 9u);
  GeometryData geo = loadGeometry(loadScene(dir / "scene"), 0);
  EXPECT_EQ(geo.vertexCount(), 7u);
  for (float f : geo.positions) EXPECT_TRUE(std::isfinite(f));
}

// Counted apart from the non-finite vertices' triangles, so that the warning
// names what happened.
TEST(Preprocess, TrianglesNamingAMissingVertexAreDroppedAndCountedApart) {
  TempDir dir;
  osg::ref_ptr<osg::Geode> g = cube();
  osg::Geometry* geom = g->getDrawable(0)->asGeometry();
  auto* bad = new osg::DrawElementsUInt(GL_TRIANGLES);
  for (unsigned i : {0u, 1u, 99u}) bad->push_back(i);
  geom->addPrimitiveSet(bad);
  PreprocessStats st = run({writeModel(dir, g.get(), "badindex.osgb")}, dir / "scene");
  EXPECT_EQ(st.bad_index_triangles, 1u);
  EXPECT_EQ(st.dropped_triangles, 0u);
  EXPECT_EQ(st.nonfinite_vertices, 0u);
  EXPECT_EQ(st.triangles, 12u);
}

// ABSOLUTE_RF is the camera's frame in OSG (a HUD): skipped and counted.
// ABSOLUTE_RF_INHERIT_VIEWPOINT places its subtree in the world by its own
// matrix, without its parents'.
TEST(Preprocess, AbsoluteReferenceFrames) {
  TempDir dir;
  osg::ref_ptr<osg::MatrixTransform> root =
      new osg::MatrixTransform(osg::Matrixd::translate(100, 0, 0));
  osg::ref_ptr<osg::MatrixTransform> hud =
      new osg::MatrixTransform(osg::Matrixd::translate(0, 5, 0));
  hud->setReferenceFrame(osg::Transform::ABSOLUTE_RF);
  hud->addChild(cube());
  osg::ref_ptr<osg::MatrixTransform> world =
      new osg::MatrixTransform(osg::Matrixd::translate(0, 0, 7));
  world->setReferenceFrame(osg::Transform::ABSOLUTE_RF_INHERIT_VIEWPOINT);
  world->addChild(cube());
  root->addChild(hud);
  root->addChild(world);
  PreprocessStats st = run({writeModel(dir, root.get(), "rf.osgb")}, dir / "scene");
  EXPECT_EQ(st.camera_fixed_subtrees, 1u);
  EXPECT_EQ(st.objects, 1u);
  Scene s = loadScene(dir / "scene");
  ASSERT_EQ(s.objects.size(), 1u);
  EXPECT_NEAR(s.objects[0].box.center().x, 0, 1e-9);
  EXPECT_NEAR(s.objects[0].box.center().z, 7, 1e-9);
}

// A reader that crashes (an OSG plugin on a malformed file) ends the run
// with a message naming the file and exit status 1, not a bare signal; the
// partial directory it leaves is removed by the next run.
TEST(PreprocessCli, AReaderCrashNamesTheFileAndTheNextRunCleansUp) {
  TempDir dir;
  std::string model = writeModel(dir, cube().get(), "crash.osgb");
  int status = 0;
  std::string out = dmmr::test::runCapture("DMMR_INJECT_FAULT=preprocess-read-crash " +
                                               dmmr::test::tool("dmmr-preprocess") + " " + model +
                                               " -o " + (dir / "scene") + " --no-progress",
                                           &status);
  EXPECT_EQ(status, 1) << out;
  EXPECT_NE(out.find(model + ": the reader of this format crashed"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir / "scene"));
  int partials = 0;
  for (const auto& e : fs::directory_iterator(dir.path()))
    partials += e.path().filename().string().rfind("scene.partial-", 0) == 0;
  EXPECT_EQ(partials, 1);
  out = dmmr::test::runCapture(dmmr::test::tool("dmmr-preprocess") + " " + model + " -o " +
                                   (dir / "scene") + " --no-progress",
                               &status);
  EXPECT_EQ(status, 0) << out;
  for (const auto& e : fs::directory_iterator(dir.path()))
    EXPECT_NE(e.path().filename().string().rfind("scene.partial-", 0), 0u) << e.path();
}

// A partial directory names its run by PID and start time, so that a
// later run removes it when the PID is free or now belongs to a process that
// started at another time (a reused PID), and keeps a live run's.
TEST(Preprocess, StalePartialsAreToldFromLiveRunsByPidAndStartTime) {
  TempDir dir;
  const fs::path out = dir / "scene";
  const long self = long(::getpid());
  pid_t child = ::fork();
  if (child == 0) ::_exit(0);
  ASSERT_GT(child, 0);
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  const std::string live = dmmr::partialSuffix(self);
  ASSERT_EQ(live.rfind(".partial-" + std::to_string(self) + "-", 0), 0u) << live;
  ASSERT_NE(live, ".partial-" + std::to_string(self) + "-0") << "this process's start time read";
  const std::string reused = ".partial-" + std::to_string(self) + "-1";  // another start
  const std::string dead = ".partial-" + std::to_string(child) + "-77";
  const std::string old_live = ".partial-" + std::to_string(self);
  const std::string old_dead = ".partial-" + std::to_string(child);
  const std::string other = ".partial-notapid";
  for (const std::string& suffix : {live, reused, dead, old_live, old_dead, other})
    fs::create_directories(out.string() + suffix + "/objects");
  dmmr::removeStalePartials(out);
  EXPECT_TRUE(fs::exists(out.string() + live)) << "a live run's";
  EXPECT_FALSE(fs::exists(out.string() + reused)) << "its PID now names another process";
  EXPECT_FALSE(fs::exists(out.string() + dead));
  EXPECT_TRUE(fs::exists(out.string() + old_live)) << "an older name: kept while the PID lives";
  EXPECT_FALSE(fs::exists(out.string() + old_dead));
  EXPECT_TRUE(fs::exists(out.string() + other)) << "not a partial name";
}

// Textures sharing one image but wrapping differently are separate texture
// files (each file holds its wrap modes); the same image and wrap modes
// again reuse the first file.
TEST(Preprocess, TexturesSharingAnImageKeepTheirOwnWrapModes) {
  TempDir dir;
  osg::ref_ptr<osg::Image> image = new osg::Image;
  image->allocateImage(2, 2, 1, GL_RGBA, GL_UNSIGNED_BYTE);
  std::memset(image->data(), 200, 16);
  osg::ref_ptr<osg::Group> root = new osg::Group;
  auto textured = [&](osg::Texture::WrapMode wrap, float x) {
    auto* g = new osg::Geometry;
    auto* v = new osg::Vec3Array;
    for (osg::Vec3 p : {osg::Vec3(x, 0, 0), osg::Vec3(x + 1, 0, 0), osg::Vec3(x, 0, 1)})
      v->push_back(p);
    auto* uv = new osg::Vec2Array;
    for (osg::Vec2 t : {osg::Vec2(0, 0), osg::Vec2(3, 0), osg::Vec2(0, 3)}) uv->push_back(t);
    g->setVertexArray(v);
    g->setTexCoordArray(0, uv, osg::Array::BIND_PER_VERTEX);
    g->addPrimitiveSet(new osg::DrawArrays(GL_TRIANGLES, 0, 3));
    auto* tex = new osg::Texture2D(image.get());
    tex->setWrap(osg::Texture::WRAP_S, wrap);
    tex->setWrap(osg::Texture::WRAP_T, wrap);
    g->getOrCreateStateSet()->setTextureAttributeAndModes(0, tex);
    auto* geode = new osg::Geode;
    geode->addDrawable(g);
    root->addChild(geode);
  };
  textured(osg::Texture::REPEAT, 0);
  textured(osg::Texture::CLAMP_TO_EDGE, 2);
  textured(osg::Texture::REPEAT, 4);
  PreprocessStats st = run({writeModel(dir, root.get(), "wrap.osgb")}, dir / "scene");
  EXPECT_EQ(st.textures, 2u);
  Scene s = loadScene(dir / "scene");
  ASSERT_EQ(s.manifest.textures, 2u);
  TextureData a = loadTexture(s, 0), b = loadTexture(s, 1);
  EXPECT_TRUE(a.repeat_s && a.repeat_t);
  EXPECT_FALSE(b.repeat_s || b.repeat_t);
  EXPECT_EQ(a.rgba, b.rgba);
}

// An osg::Billboard draws each drawable at its own position (as modelled:
// the turn to the eye depends on the view); counted for the warning.
TEST(Preprocess, BillboardDrawablesSitAtTheirPositions) {
  TempDir dir;
  osg::ref_ptr<osg::Billboard> bb = new osg::Billboard;
  osg::ref_ptr<osg::Geode> c = cube();
  bb->addDrawable(c->getDrawable(0), osg::Vec3(100, 0, 0));
  bb->addDrawable(c->getDrawable(0), osg::Vec3(0, 50, 0));  // the same drawable again
  PreprocessStats st = run({writeModel(dir, bb.get(), "bb.osgb")}, dir / "scene");
  EXPECT_EQ(st.billboards, 1u);
  EXPECT_EQ(st.objects, 2u);
  EXPECT_EQ(st.geometries, 1u) << "one drawable at two positions is one geometry";
  Scene s = loadScene(dir / "scene");
  ASSERT_EQ(s.objects.size(), 2u);
  EXPECT_NEAR(s.objects[0].box.center().x, 100, 1e-9);
  EXPECT_NEAR(s.objects[1].box.center().y, 50, 1e-9);
}

// Colours bound per primitive set colour each set's triangles; a vertex two
// sets share is stored once for each, in its set's colour.
TEST(Preprocess, ColoursPerPrimitiveSetColourTheirSetsTriangles) {
  TempDir dir;
  auto* g = new osg::Geometry;
  auto* v = new osg::Vec3Array;
  for (osg::Vec3 p :
       {osg::Vec3(0, 0, 0), osg::Vec3(1, 0, 0), osg::Vec3(0, 0, 1), osg::Vec3(1, 0, 1)})
    v->push_back(p);
  g->setVertexArray(v);
  auto* a = new osg::DrawElementsUInt(GL_TRIANGLES);
  for (unsigned i : {0u, 1u, 2u}) a->push_back(i);
  auto* b = new osg::DrawElementsUInt(GL_TRIANGLES);
  for (unsigned i : {1u, 3u, 2u}) b->push_back(i);
  g->addPrimitiveSet(a);
  g->addPrimitiveSet(b);
  auto* colours = new osg::Vec4Array;
  colours->push_back(osg::Vec4(1, 0, 0, 1));
  colours->push_back(osg::Vec4(0, 1, 0, 1));
  g->setColorArray(colours, osg::Array::BIND_PER_PRIMITIVE_SET);
  osg::ref_ptr<osg::Geode> geode = new osg::Geode;
  geode->addDrawable(g);
  run({writeModel(dir, geode.get(), "ps.osgb")}, dir / "scene");
  GeometryData geo = loadGeometry(loadScene(dir / "scene"), 0);
  ASSERT_EQ(geo.indices.size(), 6u);
  ASSERT_EQ(geo.vertexCount(), 6u) << "vertices 1 and 2 once for each set";
  ASSERT_EQ(geo.colors.size(), 4 * geo.vertexCount());
  for (size_t t = 0; t < 6; ++t) {
    const uint8_t* c = &geo.colors[4 * size_t(geo.indices[t])];
    EXPECT_EQ(c[0], t < 3 ? 255 : 0) << t;
    EXPECT_EQ(c[1], t < 3 ? 0 : 255) << t;
  }
}

// A PagedLOD's levels in files are not read (a viewer pages them in); the
// loaded child is taken and the files counted for the warning.
TEST(Preprocess, PagedLodLevelsInFilesAreCounted) {
  TempDir dir;
  osg::ref_ptr<osg::PagedLOD> lod = new osg::PagedLOD;
  lod->addChild(cube(), 100, 1e30);
  lod->setFileName(1, "fine.osgb");
  lod->setRange(1, 0, 100);
  PreprocessStats st = run({writeModel(dir, lod.get(), "paged.osgb")}, dir / "scene");
  EXPECT_EQ(st.unloaded_lod_files, 1u);
  EXPECT_EQ(st.objects, 1u);
}

TEST(Preprocess, TrianglesWithCoincidingCornersAreDroppedAndCounted) {
  TempDir dir;
  auto* v = new osg::Vec3Array;
  for (osg::Vec3 p : {osg::Vec3(0, 0, 0), osg::Vec3(1, 0, 0), osg::Vec3(0, 1, 0),
                      osg::Vec3(1, 0, 0) /* duplicate of 1 */, osg::Vec3(2, 0, 0)})
    v->push_back(p);
  auto* idx = new osg::DrawElementsUInt(GL_TRIANGLES);
  for (GLuint i : {0, 1, 2,   // kept
                   0, 0, 1,   // one vertex twice: dropped
                   1, 3, 2,   // two vertices at one position: dropped
                   0, 1, 4,   // collinear, zero area: kept (see preprocess.cpp)
                   3, 2, 0})  // a duplicate vertex in a proper triangle: kept
    idx->push_back(i);
  auto* geom = new osg::Geometry;
  geom->setVertexArray(v);
  geom->addPrimitiveSet(idx);
  osg::ref_ptr<osg::Geode> g = new osg::Geode;
  g->addDrawable(geom);
  PreprocessStats st = run({writeModel(dir, g.get(), "degenerate.osgb")}, dir / "scene");
  EXPECT_EQ(st.degenerate_triangles, 2u);
  EXPECT_EQ(st.triangles, 3u);
  GeometryData geo = loadGeometry(loadScene(dir / "scene"), 0);
  EXPECT_EQ(geo.triangleCount(), 3u);
  EXPECT_EQ(geo.vertexCount(), 5u) << "duplicate vertices are kept (they may differ in normals)";
}

TEST(Preprocess, FarFromOriginKeepsPrecisionByRecentring) {
  TempDir dir;
  // Vertices 1e6 from the origin in double, 1 mm apart: float positions at
  // 1e6 would be quantised to 6 cm; recentred they are exact to float.
  auto* v = new osg::Vec3dArray;
  v->push_back({1e6, 1e6, 0});
  v->push_back({1e6 + 0.001, 1e6, 0});
  v->push_back({1e6, 1e6 + 0.001, 0});
  auto* geom = new osg::Geometry;
  geom->setVertexArray(v);
  geom->addPrimitiveSet(new osg::DrawArrays(GL_TRIANGLES, 0, 3));
  osg::ref_ptr<osg::Geode> g = new osg::Geode;
  g->addDrawable(geom);
  run({writeModel(dir, g.get(), "far.osgb")}, dir / "scene");
  Scene s = loadScene(dir / "scene");
  GeometryData geo = loadGeometry(s, 0);
  for (size_t i = 0; i < 3; ++i) {
    Vec3d p{geo.positions[3 * i], geo.positions[3 * i + 1], geo.positions[3 * i + 2]};
    Vec3d w = s.objects[0].transform.transformPoint(p);
    Vec3d expect{(*v)[i].x(), (*v)[i].y(), (*v)[i].z()};
    expectNear(w, expect, 1e-7);
  }
}

TEST(Preprocess, SkeletonBoxesEncloseTheirSubtrees) {
  TempDir dir;
  osg::ref_ptr<osg::Group> root = new osg::Group;
  for (int i = 0; i < 3; ++i) {
    auto* t = new osg::MatrixTransform(osg::Matrixd::translate(0, 4.0 * i, 0));
    t->addChild(cube({1, 0, 0}));
    t->addChild(cube({-1, 0, 2}));
    root->addChild(t);
  }
  run({writeModel(dir, root.get(), "tree.osgb")}, dir / "scene");
  Scene s = loadScene(dir / "scene");
  size_t objectNodes = 0;
  for (size_t i = 0; i < s.skeleton.size(); ++i) {
    const SkeletonNode& n = s.skeleton[i];
    objectNodes += n.kind == NodeKind::Object;
    for (uint32_t c = uint32_t(i) + 1; c < n.end; ++c) {
      EXPECT_LE(n.box.lo.x, s.skeleton[c].box.lo.x);
      EXPECT_GE(n.box.hi.y, s.skeleton[c].box.hi.y);
    }
  }
  EXPECT_EQ(objectNodes, 6u);
}

TEST(Preprocess, OccludersAreLargeAndCheap) {
  std::vector<ObjectBounds> objs(10);
  for (int i = 0; i < 10; ++i) {
    objs[i].box = Box3d{{0, 0, 0}, {1.0 + i, 1, 1}};  // face area grows with i
    objs[i].weight = 100;
  }
  objs[9].weight = 1'000'000;  // biggest but too expensive
  std::vector<uint32_t> occ = selectOccluders(objs, 80, 10000);
  EXPECT_EQ(occ, (std::vector<uint32_t>{8}));
  EXPECT_EQ(selectOccluders(objs, 0, 10000).size(), 9u);
  EXPECT_TRUE(selectOccluders({}, 90, 10).empty());
}

TEST(Preprocess, ExistingOutputIsRefusedAndLeftAlone) {
  TempDir dir;
  std::string model = writeModel(dir, cube().get(), "c.osgb");
  fs::create_directories(dir / "scene");
  std::ofstream(dir / "scene/keep.txt") << "mine";
  try {
    run({model}, dir / "scene");
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("already exists"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(fs::exists(dir / "scene/keep.txt"));
}

TEST(Preprocess, MissingAndUnreadableModelsAreErrorsNamingTheFile) {
  TempDir dir;
  EXPECT_THROW(run({dir / "nope.obj"}, dir / "s1"), Error);
  std::ofstream(dir / "junk.osgb") << "this is not a model";
  try {
    run({dir / "junk.osgb"}, dir / "s2");
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("junk.osgb"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(dir / "s1"));
  EXPECT_FALSE(fs::exists(dir / "s2"));
}

TEST(Preprocess, EmptyModelIsAnErrorAndLeavesNoHalfScene) {
  TempDir dir;
  osg::ref_ptr<osg::Group> empty = new osg::Group;
  empty->addChild(new osg::Group);
  std::string model = writeModel(dir, empty.get(), "empty.osgb");
  EXPECT_THROW(run({model}, dir / "scene"), Error);
  EXPECT_FALSE(fs::exists(dir / "scene"));
  for (auto& e : fs::directory_iterator(dir.path()))
    EXPECT_EQ(e.path().filename().string().find("scene.partial"), std::string::npos);
}

TEST(Preprocess, CommandLineReportsErrorsWithNonZeroExit) {
  TempDir dir;
  int status = 0;
  std::string out = test::runCapture(
      test::tool("dmmr-preprocess") + " " + (dir / "missing.obj") + " -o " + (dir / "scene"),
      &status);
  EXPECT_EQ(status, 1);
  EXPECT_NE(out.find("missing.obj: no such file"), std::string::npos) << out;
}

// ---- geometry encodings (--encoding) -----------------------------------------

PreprocessStats runEncoded(const std::string& input, const std::string& out, Encoding e) {
  PreprocessOptions o;
  o.inputs = {input};
  o.out = out;
  o.progress = false;
  o.encoding = e;
  return preprocess(o);
}

TEST(Preprocess, EncodingIsRecordedInTheManifestAndEveryFileUsesIt) {
  TempDir dir;
  osg::ref_ptr<osg::Group> root = new osg::Group;
  root->addChild(cube({0, 0, 0}, true));
  root->addChild(cube({3, 0, 0}, false));
  std::string model = writeModel(dir, root.get(), "cubes.osgb");
  Scene f32;
  for (Encoding e : kEncodings) {
    std::string out = dir / encodingName(e);
    runEncoded(model, out, e);
    Scene s = loadScene(out);
    EXPECT_EQ(s.manifest.encoding, e);
    std::ifstream m(out + "/manifest.json");
    std::string text((std::istreambuf_iterator<char>(m)), std::istreambuf_iterator<char>());
    EXPECT_NE(text.find(std::string("\"encoding\": \"") + encodingName(e) + "\""),
              std::string::npos)
        << text;
    for (uint32_t g = 0; g < s.manifest.geometries; ++g) {
      std::vector<uint8_t> bytes = readFileBytes(out + "/" + geometryFileName(g));
      EXPECT_EQ(bytes.at(20), uint8_t(e)) << "the payload's encoding byte";
      GeometryData geo = loadGeometry(s, g);
      if (e == Encoding::Float32) continue;
      GeometryData ref = loadGeometry(loadScene(dir / "float32"), g);
      if (isLossless(e))
        EXPECT_EQ(geo, ref) << encodingName(e);
      else
        EXPECT_EQ(geo.indices, ref.indices) << encodingName(e);
    }
    // Objects, bounds and the rest do not depend on the encoding.
    if (e == Encoding::Float32) f32 = s;
    EXPECT_EQ(s.objects, f32.objects);
    EXPECT_EQ(s.skeleton, f32.skeleton);
  }
}

TEST(Preprocess, DefaultEncodingIsFloat32) {
  EXPECT_EQ(PreprocessOptions{}.encoding, Encoding::Float32);
}

TEST(Preprocess, FarFromOriginQuantizesAsAtTheOrigin) {
  // The same triangle fan in double at the origin and 10^6 away: recentred
  // in double, both quantize in the same local frame, with the same error
  // relative to the geometry's extent.
  auto fan = [](double offset) {
    auto* v = new osg::Vec3dArray;
    for (int i = 0; i < 200; ++i) {
      double a = i * 0.1;
      v->push_back(
          {offset + 10 * std::cos(a) * (1 + i * 0.01), offset + 7 * std::sin(a), 0.001 * i * i});
    }
    auto* geom = new osg::Geometry;
    geom->setVertexArray(v);
    geom->addPrimitiveSet(new osg::DrawArrays(GL_TRIANGLE_FAN, 0, 200));
    osg::ref_ptr<osg::Geode> g = new osg::Geode;
    g->addDrawable(geom);
    return g;
  };
  TempDir dir;
  double rel[2];
  for (int k = 0; k < 2; ++k) {
    std::string model =
        writeModel(dir, fan(k ? 1e6 : 0).get(), "fan" + std::to_string(k) + ".osgb");
    std::string exact = dir / ("exact" + std::to_string(k)), q = dir / ("q" + std::to_string(k));
    runEncoded(model, exact, Encoding::Float32);
    runEncoded(model, q, Encoding::Quantized);
    Scene se = loadScene(exact), sq = loadScene(q);
    GeometryData a = loadGeometry(se, 0), b = loadGeometry(sq, 0);
    ASSERT_EQ(a.positions.size(), b.positions.size());
    double err = 0, lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
    for (size_t i = 0; i < a.positions.size(); ++i) {
      err = std::max(err, std::fabs(double(a.positions[i]) - b.positions[i]));
      lo[i % 3] = std::min(lo[i % 3], double(a.positions[i]));
      hi[i % 3] = std::max(hi[i % 3], double(a.positions[i]));
    }
    rel[k] = err / std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
    // And the world positions the renderer computes stay within that error.
    for (size_t v = 0; v < b.vertexCount(); ++v) {
      Vec3d local{b.positions[3 * v], b.positions[3 * v + 1], b.positions[3 * v + 2]};
      Vec3d exactLocal{a.positions[3 * v], a.positions[3 * v + 1], a.positions[3 * v + 2]};
      Vec3d d = sq.objects[0].transform.transformPoint(local) -
                se.objects[0].transform.transformPoint(exactLocal);
      EXPECT_LE(length(d), 2 * err + 1e-9);
    }
  }
  EXPECT_GT(rel[0], 0);
  EXPECT_LT(rel[1], 1.5 * rel[0]) << rel[0] << " " << rel[1];
  EXPECT_LT(rel[0], 1.5 * rel[1]) << rel[0] << " " << rel[1];
  EXPECT_LT(rel[1], 1e-4);  // 100 cells for 200 vertices: a few 10^-5 of the extent
}

TEST(Preprocess, CommandLineTakesAnEncodingAndRefusesUnknownOnes) {
  TempDir dir;
  std::string model = writeModel(dir, cube({0, 0, 0}, true).get(), "cube.osgb");
  int status = 0;
  std::string out = test::runCapture(test::tool("dmmr-preprocess") + " " + model + " -o " +
                                         (dir / "scene") + " --encoding quantized-meshopt",
                                     &status);
  EXPECT_EQ(status, 0) << out;
  EXPECT_EQ(loadScene(dir / "scene").manifest.encoding, Encoding::QuantizedMeshopt);
  out = test::runCapture(
      test::tool("dmmr-preprocess") + " " + model + " -o " + (dir / "bad") + " --encoding float16",
      &status);
  EXPECT_NE(status, 0);
  EXPECT_NE(out.find("unknown encoding 'float16'"), std::string::npos) << out;
  EXPECT_NE(out.find("quantized-meshopt"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir / "bad"));
}

// Every real model beside the checkout: triangle counts match OSG's own.
class RealModel : public testing::TestWithParam<std::string> {};

TEST_P(RealModel, TriangleCountMatchesOpenSceneGraph) {
  std::string models = test::sharedModelsDir();
  if (models.empty()) GTEST_SKIP() << "../shared/models is absent; real-model tests skipped";
  std::string path = models + "/" + GetParam();
  osg::ref_ptr<osg::Node> node = osgDB::readRefNodeFile(path);
  ASSERT_TRUE(node) << path;
  uint64_t expected = osgTriangleCount(node.get());
  TempDir dir;
  PreprocessStats st = run({path}, dir / "scene");
  EXPECT_EQ(st.triangles, expected);
  EXPECT_GT(st.triangles, 1000u);
  Scene s = loadScene(dir / "scene");
  uint64_t sum = 0;
  for (const auto& o : s.objects) sum += o.weight;
  EXPECT_EQ(sum, expected);
  for (uint32_t g = 0; g < s.manifest.geometries; ++g) EXPECT_NO_THROW(loadGeometry(s, g));
}

INSTANTIATE_TEST_SUITE_P(SharedModels, RealModel,
                         testing::Values("skull/skull.obj", "koala/koala.obj",
                                         "scorpion/scorpion.obj", "osg-data-cow.osgt",
                                         "osg-data-dumptruck.osgt", "osg-data-cessna.osgt",
                                         "osg-data-lz.osgt"),
                         [](const testing::TestParamInfo<std::string>& i) {
                           std::string n = i.param.substr(i.param.find_last_of('/') + 1);
                           for (char& c : n)
                             if (!isalnum(static_cast<unsigned char>(c))) c = '_';
                           return n;
                         });
