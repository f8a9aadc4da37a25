// A textured glTF preprocesses and renders as the same model built in OSG:
// the same geometry file (positions, texture coordinates with glTF's v
// flipped to GL's, material), the same texture, identical frames, and the
// texture visible on screen.
#include <gtest/gtest.h>

#include <osg/Geode>
#include <osg/Geometry>
#include <osg/Material>
#include <osg/MatrixTransform>
#include <osg/Texture2D>
#include <osgDB/ReadFile>
#include <osgDB/WriteFile>

#include "compare.h"
#include "gltf_files.h"
#include "image.h"
#include "preprocess.h"
#include "reference.h"
#include "scene.h"
#include "scenegen.h"
#include "test_support.h"
#include "walkthrough.h"

using namespace dmmr;
using namespace dmmr::test::gltf;
using dmmr::test::TempDir;

namespace {

// The glTF cube scene as an OSG graph: Y up to Z up, root (scale 2, then
// translate (10, 0, 0)), a and b (translated (0, 3, 0)) sharing one geode.
osg::ref_ptr<osg::Node> osgEquivalent(const std::string& png) {
  std::vector<uint8_t> b = cubeBuffer();
  auto* v = new osg::Vec3Array;
  auto* uv = new osg::Vec2Array;
  for (int i = 0; i < 8; ++i) {
    float p[3];
    std::memcpy(p, b.data() + 12 * i, 12);
    v->push_back({p[0], p[1], p[2]});
    uv->push_back({kUv[i][0], 1 - kUv[i][1]});
  }
  auto* idx = new osg::DrawElementsUInt(GL_TRIANGLES);
  for (int i = 0; i < 36; ++i) idx->push_back(b[160 + 2 * i] | b[161 + 2 * i] << 8);
  auto* geom = new osg::Geometry;
  geom->setVertexArray(v);
  geom->setTexCoordArray(0, uv, osg::Array::BIND_PER_VERTEX);
  geom->addPrimitiveSet(idx);
  auto* mat = new osg::Material;
  mat->setDiffuse(osg::Material::FRONT_AND_BACK, osg::Vec4(0.25f, 0.5f, 0.75f, 1));
  auto* tex = new osg::Texture2D(osgDB::readRefImageFile(png).get());
  tex->setWrap(osg::Texture::WRAP_S, osg::Texture::REPEAT);
  tex->setWrap(osg::Texture::WRAP_T, osg::Texture::REPEAT);
  geom->getOrCreateStateSet()->setAttribute(mat);
  geom->getOrCreateStateSet()->setTextureAttribute(0, tex);
  osg::ref_ptr<osg::Geode> geode = new osg::Geode;
  geode->addDrawable(geom);
  auto* root =
      new osg::MatrixTransform(osg::Matrixd::scale(2, 2, 2) * osg::Matrixd::translate(10, 0, 0));
  root->addChild(geode);
  auto* bNode = new osg::MatrixTransform(osg::Matrixd::translate(0, 3, 0));
  bNode->addChild(geode);
  root->addChild(bNode);
  osg::ref_ptr<osg::MatrixTransform> zUp =
      new osg::MatrixTransform(osg::Matrixd(1, 0, 0, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 0, 0, 1));
  zUp->addChild(root);
  return zUp;
}

std::string preprocessAndRender(const TempDir& dir, const std::string& model,
                                const std::string& name) {
  PreprocessOptions p;
  p.inputs = {model};
  p.out = dir / (name + ".scene");
  p.progress = false;
  preprocess(p);
  ReferenceOptions r;
  r.scene = p.out;
  r.walkthrough = dir / "cube.path";
  r.out = dir / (name + ".frames");
  r.view.width = 160;
  r.view.height = 120;
  r.progress = false;
  runReference(r);
  return r.out;
}

}  // namespace

TEST(GltfRender, RendersAsTheSameModelBuiltInOsg) {
  TempDir dir;
  writePng(dir / "checker.png");
  writeBytes(dir / "cube.bin", cubeBuffer());
  writeText(dir / "cube.gltf", gltfJson({"cube.bin", "checker.png"}, cubeBuffer().size()));
  osg::ref_ptr<osg::Node> same = osgEquivalent(dir / "checker.png");
  ASSERT_TRUE(osgDB::writeNodeFile(*same, dir / "cube.osgb"));
  writeWalkthrough(dir / "cube.path", scenegen::makeWalkthrough(scenegen::sceneBounds(*same), 3,
                                                                scenegen::PathKind::Orbit));

  std::string a = preprocessAndRender(dir, dir / "cube.gltf", "gltf");
  std::string b = preprocessAndRender(dir, dir / "cube.osgb", "osg");
  Scene sa = loadScene(dir / "gltf.scene"), sb = loadScene(dir / "osg.scene");
  EXPECT_EQ(sa.objects, sb.objects);
  ASSERT_EQ(sa.manifest.geometries, 1u);
  EXPECT_EQ(loadGeometry(sa, 0), loadGeometry(sb, 0));
  ASSERT_EQ(sa.manifest.textures, 1u);
  EXPECT_EQ(loadTexture(sa, 0), loadTexture(sb, 0));

  std::vector<FrameDiff> d = compareDirectories(a, b);
  ASSERT_EQ(d.size(), 3u);
  for (const FrameDiff& f : d) EXPECT_EQ(f.diff.differing_pixels, 0) << f.name << " " << f.diff;
  // The cubes are on screen, and textured: the untextured glTF renders
  // differently.
  Image frame = readPng(a + "/" + d[0].name);
  int covered = 0;
  for (int y = 0; y < frame.height; ++y)
    for (int x = 0; x < frame.width; ++x) {
      const uint8_t* p = frame.pixel(x, y);
      covered += p[0] != frame.pixel(0, 0)[0] || p[1] != frame.pixel(0, 0)[1] ||
                 p[2] != frame.pixel(0, 0)[2];
    }
  EXPECT_GT(covered, 1000);
  writeText(dir / "plain.gltf", gltfJson({"cube.bin", ""}, cubeBuffer().size()));
  std::string c = preprocessAndRender(dir, dir / "plain.gltf", "plain");
  for (const FrameDiff& f : compareDirectories(a, c))
    EXPECT_GT(f.diff.differing_pixels, 500) << f.name << " " << f.diff;
}
