// The headless backends and the shared drawing code: both backends give the
// same pixels, scissored regions reproduce the full frame exactly, and
// dmmr-reference handles good and bad input.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <osg/Geode>
#include <osg/Geometry>
#include <osg/MatrixTransform>
#include <osg/ShapeDrawable>
#include <osgDB/WriteFile>

#include "compare.h"
#include "draw.h"
#include "error.h"
#include "gl_context.h"
#include "image.h"
#include "preprocess.h"
#include "reference.h"
#include "scene.h"
#include "test_support.h"

namespace fs = std::filesystem;
using namespace dmmr;
using dmmr::test::TempDir;

namespace {

// A small scene: spheres and boxes (with and without normals) spread in
// front of a camera at the origin looking down -Y... built with OSG shapes.
std::string makeScene(const TempDir& dir) {
  osg::ref_ptr<osg::Group> root = new osg::Group;
  for (int i = 0; i < 12; ++i) {
    auto* geode = new osg::Geode;
    osg::Shape* shape = (i % 2) ? static_cast<osg::Shape*>(new osg::Sphere({0, 0, 0}, 0.6f))
                                : static_cast<osg::Shape*>(new osg::Box({0, 0, 0}, 1.0f));
    auto* sd = new osg::ShapeDrawable(shape);
    sd->setColor(osg::Vec4(0.2f + 0.06f * i, 0.8f - 0.05f * i, 0.5f, 1.f));
    geode->addDrawable(sd);
    auto* t = new osg::MatrixTransform(
        osg::Matrixd::rotate(0.3 * i, osg::Vec3d(0, 0, 1)) *
        osg::Matrixd::translate(-3 + 0.55 * i, 6 + (i % 3), 0.4 * (i % 4) - 0.6));
    t->addChild(geode);
    root->addChild(t);
  }
  std::string model = dir / "shapes.osgb";
  EXPECT_TRUE(osgDB::writeNodeFile(*root, model));
  PreprocessOptions o;
  o.inputs = {model};
  o.out = dir / "scene";
  o.progress = false;
  preprocess(o);
  return o.out;
}

// Camera at the origin looking down +Y (rotation +90 degrees about X).
ControlPoint lookAlongY(double x = 0) {
  return {0, {x, 0, 0}, {std::sqrt(0.5), 0, 0, std::sqrt(0.5)}};
}

// Renders all objects of `scene` into each region in turn (clearing only
// that region) and returns the whole frame, top row first.
Image render(GlContext& ctx, const Scene& scene, const ControlPoint& cp, int w, int h,
             const std::vector<Rect>& regions) {
  Renderer r(ctx.gl(), w, h);
  std::vector<GpuMesh> meshes;
  for (uint32_t g = 0; g < scene.manifest.geometries; ++g)
    meshes.push_back(r.upload(loadGeometry(scene, g)));
  Camera cam = cameraAt(cp, w, h, 45, defaultNear(scene));
  for (const Rect& reg : regions) {
    r.beginFrame(cam, reg);
    for (const ObjectBounds& o : scene.objects) r.draw(meshes[o.geometry], o.transform, o.box, {});
  }
  std::vector<uint8_t> px;
  r.readPixels({0, 0, w, h}, &px);
  for (auto& m : meshes) r.release(m);
  Image img = Image{w, h, px};
  return flipRows(img);
}

}  // namespace

TEST(Backends, OSMesaAndEglRenderIdenticalPixels) {
  TempDir dir;
  Scene scene = loadScene(makeScene(dir));
  Image a, b;
  {
    auto ctx = createContext({Backend::OSMesa, -1});
    a = render(*ctx, scene, lookAlongY(), 256, 192, {{0, 0, 256, 192}});
  }
  {
    auto ctx = createContext({Backend::EGL, -1});
    b = render(*ctx, scene, lookAlongY(), 256, 192, {{0, 0, 256, 192}});
  }
  ImageDiff d = compareImages(a, b);
  EXPECT_EQ(d.differing_pixels, 0) << d;
  // And the frame is not trivially empty: many pixels differ from the corner
  // (background) colour.
  int64_t covered = 0;
  for (int64_t i = 0; i < a.pixelCount(); ++i)
    covered += std::memcmp(&a.rgba[size_t(i) * 4], &a.rgba[0], 3) != 0;
  EXPECT_GT(covered, a.pixelCount() / 20);
}

TEST(Backends, ScissoredRegionsReproduceTheFullFrameExactly) {
  TempDir dir;
  Scene scene = loadScene(makeScene(dir));
  auto ctx = createContext({Backend::OSMesa, -1});
  const int w = 203, h = 157;  // odd sizes: regions of unequal, odd widths
  Image full = render(*ctx, scene, lookAlongY(0.3), w, h, {{0, 0, w, h}});
  std::vector<Rect> quads = {
      {0, 0, 71, 60}, {71, 0, w - 71, 60}, {0, 60, 1, h - 60}, {1, 60, w - 1, h - 60}};
  Image pieces = render(*ctx, scene, lookAlongY(0.3), w, h, quads);
  ImageDiff d = compareImages(full, pieces);
  EXPECT_EQ(d.differing_pixels, 0) << d;
}

TEST(Backends, UnknownBackendNameIsAnError) {
  EXPECT_THROW(parseBackend("vulkan"), Error);
}

TEST(Reference, RendersEveryFrameOfAWalkthrough) {
  TempDir dir;
  std::string scene = makeScene(dir);
  Walkthrough w;
  for (int i = 0; i < 3; ++i) w.points.push_back(lookAlongY(0.2 * i));
  w.points[1].time = 1;
  w.points[2].time = 2;
  writeWalkthrough(dir / "path", w);
  ReferenceOptions o;
  o.scene = scene;
  o.walkthrough = dir / "path";
  o.out = dir / "frames";
  o.stats = dir / "stats.csv";
  o.view.width = 96;
  o.view.height = 64;
  o.progress = false;
  runReference(o);
  for (int i = 0; i < 3; ++i) {
    Image img = readPng(dir / ("frames/" + frameFileName(size_t(i))));
    EXPECT_EQ(img.width, 96);
    EXPECT_EQ(img.height, 64);
  }
  // Frames move with the camera.
  ImageDiff d01 =
      compareImageFiles(dir / "frames/frame_000000.png", dir / "frames/frame_000001.png");
  EXPECT_GT(d01.differing_pixels, 0);
  std::ifstream csv(dir / "stats.csv");
  std::string line;
  int lines = 0;
  while (std::getline(csv, line)) ++lines;
  EXPECT_EQ(lines, 4);  // header + 3 frames
}

TEST(Reference, MalformedWalkthroughLineIsReportedWithItsNumber) {
  TempDir dir;
  std::string scene = makeScene(dir);
  std::ofstream(dir / "bad.path") << "0 0 0 0 0 0 0 1\n1 0 0 0 0 0 zero 1\n";
  int status = 0;
  std::string out =
      test::runCapture(test::tool("dmmr-reference") + " --scene " + scene + " --walkthrough " +
                           (dir / "bad.path") + " --out " + (dir / "frames") + " --no-progress",
                       &status);
  EXPECT_EQ(status, 1);
  EXPECT_NE(out.find("bad.path:2:"), std::string::npos) << out;
}

TEST(Reference, CorruptSceneIsRefusedNamingTheFile) {
  TempDir dir;
  std::string scene = makeScene(dir);
  {
    std::fstream f(scene + "/bounds.bin", std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(30);
    f.put('\x7f');
  }
  int status = 0;
  std::ofstream(dir / "p.path") << "0 0 0 0 0 0 0 1\n";
  std::string out =
      test::runCapture(test::tool("dmmr-reference") + " --scene " + scene + " --walkthrough " +
                           (dir / "p.path") + " --out " + (dir / "frames") + " --no-progress",
                       &status);
  EXPECT_EQ(status, 1);
  EXPECT_NE(out.find("bounds.bin"), std::string::npos) << out;
}

// --flush-triangles: auto or a count (shared with dmmr-render,
// cli_options.h); flushing after every draw gives the same frames as never.
TEST(Reference, FlushTrianglesTakesAutoOrACountAndChangesNoPixel) {
  TempDir dir;
  std::string scene = makeScene(dir);
  std::ofstream(dir / "p.path") << "0 0 0 0 0 0 0 1\n1 0.2 0 0 0 0 0 1\n";
  auto run = [&](const std::string& flush, const std::string& out, int* status) {
    return test::runCapture(test::tool("dmmr-reference") + " --scene " + scene + " --walkthrough " +
                                (dir / "p.path") + " --out " + (dir / out) +
                                " --width 96 --height 64 --no-progress --flush-triangles " + flush,
                            status);
  };
  int status = 0;
  for (const char* flush : {"0", "1", "auto"}) {
    std::string log = run(flush, std::string("f") + flush, &status);
    ASSERT_EQ(status, 0) << flush << ": " << log;
  }
  for (const char* other : {"f1", "fauto"}) {
    std::vector<FrameDiff> diffs = compareDirectories(dir / "f0", dir / other);
    EXPECT_EQ(diffs.size(), 2u);
    for (const FrameDiff& d : diffs)
      EXPECT_EQ(d.diff.differing_pixels, 0) << other << " " << d.name;
  }
  for (const char* bad : {"-1", "x", "12k"}) {
    std::string log = run(bad, "bad", &status);
    EXPECT_NE(status, 0) << bad;
    EXPECT_NE(log.find("--flush-triangles"), std::string::npos) << log;
  }
}
