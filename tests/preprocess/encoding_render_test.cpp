// Geometry encodings end to end: a generated plant preprocessed with each
// encoding and rendered by dmmr-reference's code. The exact encodings give
// identical frames, the quantized ones stay within the PSNR, and the
// plant placed 10^6 units from the origin quantizes and renders as it does
// at the origin.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <osg/MatrixTransform>
#include <osgDB/WriteFile>

#include "compare.h"
#include "formats.h"
#include "preprocess.h"
#include "reference.h"
#include "scene.h"
#include "scenegen.h"
#include "test_support.h"
#include "walkthrough.h"

using namespace dmmr;
using dmmr::test::TempDir;
namespace sg = dmmr::scenegen;

namespace {

constexpr double kFar = 1e6;

class EncodingRender : public testing::Test {
 protected:
  // One plant, its fly-through, and the same translated by (1e6, -1e6, 1e6)
  // (a transform above the plant, as a georeferenced model is placed).
  static void SetUpTestSuite() {
    dir_ = new TempDir;
    osg::ref_ptr<osg::Node> plant = sg::makePlant({3, 30000, 300});
    Walkthrough w = sg::makeWalkthrough(sg::sceneBounds(*plant), 4, sg::PathKind::FlyThrough);
    osg::ref_ptr<osg::MatrixTransform> far =
        new osg::MatrixTransform(osg::Matrixd::translate(kFar, -kFar, kFar));
    far->addChild(plant);
    ASSERT_TRUE(osgDB::writeNodeFile(*plant, path("plant.osgb")));
    ASSERT_TRUE(osgDB::writeNodeFile(*far, path("far.osgb")));
    writeWalkthrough(path("plant.path"), w);
    for (auto& p : w.points) p.position = p.position + Vec3d{kFar, -kFar, kFar};
    writeWalkthrough(path("far.path"), w);
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  static std::string path(const std::string& name) { return *dir_ / name; }

  // Preprocesses `model` with `e` (once) and renders its walkthrough; returns
  // the frame directory.
  static std::string render(const std::string& model, Encoding e) {
    std::string scene = path(model + "." + encodingName(e));
    std::string frames = scene + ".frames";
    if (std::filesystem::exists(frames)) return frames;
    PreprocessOptions p;
    p.inputs = {path(model + ".osgb")};
    p.out = scene;
    p.progress = false;
    p.encoding = e;
    preprocess(p);
    ReferenceOptions r;
    r.scene = scene;
    r.walkthrough = path(model + ".path");
    r.out = frames;
    r.view.width = 192;
    r.view.height = 144;
    r.progress = false;
    runReference(r);
    return frames;
  }

  static std::vector<FrameDiff> diffs(const std::string& a, const std::string& b) {
    std::vector<FrameDiff> d = compareDirectories(a, b);
    EXPECT_EQ(d.size(), 4u);
    return d;
  }

  // Largest error of the quantized positions against the float32 ones,
  // relative to each geometry's extent, over all geometries.
  static double worstRelativeError(const std::string& model) {
    Scene exact = loadScene(path(model + ".float32"), false);
    Scene q = loadScene(path(model + ".quantized-meshopt"), false);
    double worst = 0;
    for (uint32_t g = 0; g < exact.manifest.geometries; ++g) {
      GeometryData a = loadGeometry(exact, g), b = loadGeometry(q, g);
      double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300}, err = 0;
      for (size_t i = 0; i < a.positions.size(); ++i) {
        lo[i % 3] = std::min(lo[i % 3], double(a.positions[i]));
        hi[i % 3] = std::max(hi[i % 3], double(a.positions[i]));
        err = std::max(err, std::fabs(double(a.positions[i]) - b.positions[i]));
      }
      double extent = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
      if (extent > 0) worst = std::max(worst, err / extent);
    }
    return worst;
  }

  static TempDir* dir_;
};
TempDir* EncodingRender::dir_ = nullptr;

TEST_F(EncodingRender, ExactEncodingsRenderIdenticalFrames) {
  std::string f32 = render("plant", Encoding::Float32);
  for (const FrameDiff& d : diffs(f32, render("plant", Encoding::Meshopt)))
    EXPECT_EQ(d.diff.differing_pixels, 0) << d.name << ": " << d.diff;
}

TEST_F(EncodingRender, QuantizedEncodingsStayNearTheExactFrames) {
  // The 45 dB over the walkthrough as a whole. Single frames can dip
  // lower: each geometry is quantized on its own, so where two objects meet
  // (a wall's end against another wall) a seam exact in float32 moves by
  // the quantization error and a line of pixels can change hands.
  std::string f32 = render("plant", Encoding::Float32);
  for (Encoding e : {Encoding::Quantized, Encoding::QuantizedMeshopt}) {
    std::vector<ImageDiff> all;
    for (const FrameDiff& d : diffs(f32, render("plant", e))) {
      EXPECT_GE(d.diff.psnr, 38) << encodingName(e) << " " << d.name << ": " << d.diff;
      EXPECT_LE(d.diff.differing_pixels, d.diff.pixels / 20) << d.name << ": " << d.diff;
      all.push_back(d.diff);
    }
    EXPECT_GE(combineDiffs(all).psnr, 45) << encodingName(e);
  }
}

TEST_F(EncodingRender, FarFromTheOriginQuantizesAndRendersAsAtTheOrigin) {
  std::string nearFrames = render("plant", Encoding::QuantizedMeshopt);
  std::string farFrames = render("far", Encoding::QuantizedMeshopt);
  render("plant", Encoding::Float32);
  render("far", Encoding::Float32);
  double a = worstRelativeError("plant"), b = worstRelativeError("far");
  EXPECT_GT(a, 0);
  EXPECT_LE(b, 1.5 * a) << "origin " << a << ", 10^6 away " << b;
  EXPECT_LE(a, 1.5 * b) << "origin " << a << ", 10^6 away " << b;
  for (const FrameDiff& d : diffs(nearFrames, farFrames))
    EXPECT_GE(d.diff.psnr, 50) << d.name << ": " << d.diff;
}

}  // namespace
