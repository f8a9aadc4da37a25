// Numerically hard scenes through dmmr-reference's code (the clients share
// it): scenes far from the origin, a huge depth range, and cameras inside
// objects. Each asserts against the same scene in an easy place or against
// the analytic answer.
#include <gtest/gtest.h>

#include <cmath>
#include <osg/Geode>
#include <osg/Geometry>
#include <osg/MatrixTransform>
#include <osgDB/WriteFile>

#include "compare.h"
#include "image.h"
#include "preprocess.h"
#include "reference.h"
#include "scenegen.h"
#include "test_support.h"
#include "walkthrough.h"

using namespace dmmr;
using dmmr::test::TempDir;

namespace {

constexpr int kW = 160, kH = 120;

std::string preprocessNode(const TempDir& dir, osg::Node* node, const std::string& name) {
  std::string model = dir / (name + ".osgb");
  EXPECT_TRUE(osgDB::writeNodeFile(*node, model));
  PreprocessOptions o;
  o.inputs = {model};
  o.out = dir / (name + ".scene");
  o.progress = false;
  preprocess(o);
  return o.out;
}

std::string renderReference(const TempDir& dir, const std::string& scene, const Walkthrough& w,
                            const std::string& name, double near = 0) {
  std::string path = dir / (name + ".path");
  writeWalkthrough(path, w);
  ReferenceOptions o;
  o.scene = scene;
  o.walkthrough = path;
  o.out = dir / name;
  o.view.width = kW;
  o.view.height = kH;
  o.view.near = near;
  o.progress = false;
  runReference(o);
  return o.out;
}

// A flat quad facing +Z at height z, covering [-s, s]^2, in one colour.
osg::Node* quad(double z, double s, const osg::Vec4& colour) {
  auto* g = new osg::Geometry;
  auto* v = new osg::Vec3Array;
  for (auto [x, y] : {std::pair{-s, -s}, {s, -s}, {s, s}, {-s, s}})
    v->push_back({float(x), float(y), 0});
  g->setVertexArray(v);
  auto* c = new osg::Vec4Array;
  c->push_back(colour);
  g->setColorArray(c, osg::Array::BIND_OVERALL);
  g->addPrimitiveSet(new osg::DrawArrays(GL_QUADS, 0, 4));
  auto* geode = new osg::Geode;
  geode->addDrawable(g);
  // The translation lives in a transform, as in real models: the quad's
  // vertices stay small and the preprocessor keeps z in double.
  auto* t = new osg::MatrixTransform(osg::Matrixd::translate(0, 0, z));
  t->addChild(geode);
  return t;
}

}  // namespace

// The same plant at the origin and moved 10^6 and 10^7 units away along all
// three axes, with the camera path moved alike: positions stay in each
// geometry's local float frame, transforms and the camera are composed in
// double, and only camera-relative values reach the GPU.
TEST(HardScenes, FarFromTheOriginRendersAsAtTheOrigin) {
  TempDir dir;
  scenegen::PlantParams params;
  params.seed = 3;
  params.triangles = 40'000;
  params.geodes = 300;
  osg::ref_ptr<osg::Node> plant = scenegen::makePlant(params);
  Walkthrough path =
      scenegen::makeWalkthrough(scenegen::sceneBounds(*plant), 4, scenegen::PathKind::FlyThrough);
  std::string atOrigin =
      renderReference(dir, preprocessNode(dir, plant.get(), "origin"), path, "origin-frames");
  for (double offset : {1e6, 1e7}) {
    osg::Vec3d d(offset, -offset, offset);
    osg::ref_ptr<osg::MatrixTransform> moved = new osg::MatrixTransform(osg::Matrixd::translate(d));
    moved->addChild(plant.get());
    Walkthrough far = path;
    for (ControlPoint& p : far.points) p.position = p.position + Vec3d{d.x(), d.y(), d.z()};
    std::string name = "far" + std::to_string(int(std::log10(offset)));
    std::string frames =
        renderReference(dir, preprocessNode(dir, moved.get(), name), far, name + "-frames");
    for (const FrameDiff& f : compareDirectories(atOrigin, frames)) {
      EXPECT_GE(f.diff.psnr, 50.0) << "offset " << offset << " " << f.name << " " << f.diff;
      EXPECT_LT(f.diff.differing_pixels, kW * kH / 100) << "offset " << offset << " " << f.name;
    }
  }
}

// Two quads 1 cm apart, 10 km from a camera whose near plane is at 1 cm: a
// 24-bit standard depth buffer (near 0.01, far 10^6) cannot tell them apart;
// reversed-Z float depth must, whichever is drawn first.
TEST(HardScenes, SurfacesOneCentimetreApartAtTenKilometresDoNotFight) {
  const double n = 0.01, f = 1e6, z_near = 10000.0, z_far = 10000.01;
  auto standard24 = [&](double z) {  // window depth of a standard projection, quantised
    return std::llround((f / (f - n)) * (1 - n / z) * ((1 << 24) - 1));
  };
  ASSERT_EQ(standard24(z_near), standard24(z_far)) << "the premise: 24-bit depth fights here";

  TempDir dir;
  for (bool nearFirst : {true, false}) {
    osg::ref_ptr<osg::Group> root = new osg::Group;
    osg::Node* red = quad(-z_near, 20000, {1, 0, 0, 1});
    osg::Node* green = quad(-z_far, 20000, {0, 1, 0, 1});
    root->addChild(nearFirst ? red : green);
    root->addChild(nearFirst ? green : red);
    std::string name = nearFirst ? "near-first" : "far-first";
    std::string scene = preprocessNode(dir, root.get(), name);
    Walkthrough w;
    w.points.push_back({0, {0, 0, 0}, {0, 0, 0, 1}});  // at the origin, looking down -Z
    Image img =
        readPng(renderReference(dir, scene, w, name + "-frames", n) + "/" + frameFileName(0));
    size_t red_px = 0, green_px = 0;
    for (int y = 0; y < img.height; ++y)
      for (int x = 0; x < img.width; ++x) {
        const uint8_t* p = img.pixel(x, y);
        red_px += p[0] > 100 && p[1] < 50;
        green_px += p[1] > 100 && p[0] < 50;
      }
    EXPECT_EQ(green_px, 0u) << name << ": the far surface shows through";
    EXPECT_EQ(red_px, size_t(kW) * kH) << name;
  }
}
