// Inputs beyond OSG's readers: glTF 2.0 (.gltf with external or data: URI
// buffers, .glb, textures) and FBX through assimp, compared with what assimp
// itself reports and with the known geometry; directories of models; and
// inputs read one at a time.
#include <gtest/gtest.h>

#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <algorithm>
#include <assimp/Exporter.hpp>
#include <assimp/Importer.hpp>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <osg/Geode>
#include <osg/Geometry>
#include <osg/MatrixTransform>
#include <osgDB/WriteFile>

#include "assimp_reader.h"
#include "atomic_file.h"
#include "error.h"
#include "formats.h"
#include "gltf_files.h"
#include "preprocess.h"
#include "scene.h"
#include "test_support.h"

namespace fs = std::filesystem;
using namespace dmmr;
using dmmr::test::TempDir;
using namespace dmmr::test::gltf;

namespace {

// ---- what assimp reports, and running the preprocessor ---------------------

struct Report {
  uint64_t triangles = 0;  // instances counted each
  Box3d box;               // world bounds, mapped to Z up as the preprocessor does
};

Report assimpReport(const std::string& path) {
  Assimp::Importer imp;
  const aiScene* s = imp.ReadFile(path, aiProcess_Triangulate | aiProcess_SortByPType);
  EXPECT_TRUE(s) << imp.GetErrorString();
  Report r;
  if (!s) return r;
  auto visit = [&](auto& self, const aiNode* n, aiMatrix4x4 m) -> void {
    m = m * n->mTransformation;
    for (unsigned i = 0; i < n->mNumMeshes; ++i) {
      const aiMesh* mesh = s->mMeshes[n->mMeshes[i]];
      for (unsigned f = 0; f < mesh->mNumFaces; ++f)
        r.triangles += mesh->mFaces[f].mNumIndices == 3;
      for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
        aiVector3D p = m * mesh->mVertices[v];
        r.box.expand(Vec3d{p.x, -p.z, p.y});
      }
    }
    for (unsigned i = 0; i < n->mNumChildren; ++i) self(self, n->mChildren[i], m);
  };
  visit(visit, s->mRootNode, aiMatrix4x4());
  return r;
}

PreprocessStats run(const std::vector<std::string>& inputs, const std::string& out,
                    bool skipUnreadable = false) {
  PreprocessOptions o;
  o.inputs = inputs;
  o.out = out;
  o.progress = false;
  o.skip_unreadable = skipUnreadable;
  return preprocess(o);
}

void expectNear(Vec3d a, Vec3d b, double eps = 1e-6) {
  EXPECT_NEAR(a.x, b.x, eps);
  EXPECT_NEAR(a.y, b.y, eps);
  EXPECT_NEAR(a.z, b.z, eps);
}

// The two-instance cube scene as the preprocessor must write it: glTF's
// Y up turned to Z up, (x, y, z) -> (x, -z, y).
void expectCubeScene(const std::string& model, const std::string& out) {
  PreprocessStats st = run({model}, out);
  Scene s = loadScene(out);
  EXPECT_EQ(st.objects, 2u) << model;
  EXPECT_EQ(st.geometries, 1u) << "a mesh used by two nodes stays one geometry";
  EXPECT_EQ(s.manifest.triangles, 24u);
  EXPECT_EQ(s.manifest.unique_triangles, 12u);
  // Known geometry: a at x 9..11, y -1..1; b 6 up in glTF's y.
  expectNear(s.manifest.bounds.lo, {9, -1, -1});
  expectNear(s.manifest.bounds.hi, {11, 1, 7});
  Report r = assimpReport(model);
  EXPECT_EQ(s.manifest.triangles, r.triangles);
  expectNear(s.manifest.bounds.lo, r.box.lo);
  expectNear(s.manifest.bounds.hi, r.box.hi);
  GeometryData g = loadGeometry(s, 0);
  ASSERT_EQ(g.submeshes.size(), 1u);
  EXPECT_FLOAT_EQ(g.submeshes[0].diffuse[0], 0.25f);
  EXPECT_FLOAT_EQ(g.submeshes[0].diffuse[2], 0.75f);
  EXPECT_EQ(g.vertexCount(), 8u) << "no vertices welded or added";
}

std::string errorOf(const std::vector<std::string>& inputs, const std::string& out) {
  testing::internal::CaptureStderr();
  std::string e = test::errorOf([&] { run(inputs, out); });
  testing::internal::GetCapturedStderr();
  EXPECT_FALSE(fs::exists(out));
  return e;
}

bool has(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

osg::ref_ptr<osg::Node> osgCube(osg::Vec3 c) {
  auto* v = new osg::Vec3Array;
  for (int i = 0; i < 8; ++i)
    v->push_back(c +
                 osg::Vec3((i & 1) ? 0.5f : -0.5f, (i & 2) ? 0.5f : -0.5f, (i & 4) ? 0.5f : -0.5f));
  const GLuint idx[36] = {0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4,
                          2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5};
  auto* geom = new osg::Geometry;
  geom->setVertexArray(v);
  geom->addPrimitiveSet(new osg::DrawElementsUInt(GL_TRIANGLES, 36, idx));
  osg::ref_ptr<osg::Geode> g = new osg::Geode;
  g->addDrawable(geom);
  return g;
}

}  // namespace

// ---- glTF ---------------------------------------------------------------------

TEST(Gltf, ExternalBufferAndANodeHierarchyMatchAssimpAndTheKnownCube) {
  TempDir dir;
  writeBytes(dir / "cube.bin", cubeBuffer());
  writeText(dir / "cube.gltf", gltfJson({"cube.bin", ""}, cubeBuffer().size()));
  expectCubeScene(dir / "cube.gltf", dir / "scene");
}

TEST(Gltf, UrisInExtrasAreNotFilesToRead) {
  TempDir dir;
  writeBytes(dir / "cube.bin", cubeBuffer());
  std::string json = gltfJson({"cube.bin", ""}, cubeBuffer().size());
  json.insert(1, R"("extras": {"uri": "http://example.com/about", "more": [{"uri": "/x"}]}, )");
  writeText(dir / "cube.gltf", json);
  expectCubeScene(dir / "cube.gltf", dir / "scene");
}

TEST(Gltf, BufferInASubdirectoryIsRead) {
  TempDir dir;
  fs::create_directories(dir / "data");
  writeBytes(dir / "data/cube.bin", cubeBuffer());
  writeText(dir / "cube.gltf", gltfJson({"data/cube.bin", ""}, cubeBuffer().size()));
  expectCubeScene(dir / "cube.gltf", dir / "scene");
}

TEST(Gltf, DataUriBuffer) {
  TempDir dir;
  std::string uri = "data:application/octet-stream;base64," + base64(cubeBuffer());
  writeText(dir / "cube.gltf", gltfJson({uri, ""}, cubeBuffer().size()));
  expectCubeScene(dir / "cube.gltf", dir / "scene");
}

TEST(Gltf, BinaryGlb) {
  TempDir dir;
  writeBytes(dir / "cube.glb", glbBytes());
  expectCubeScene(dir / "cube.glb", dir / "scene");
}

// glTF's texture coordinates start at the image's top; GL's, and dmmr's
// textures (bottom row first), at the bottom: v becomes 1 - v.
void expectTextured(const std::string& model, const std::string& out,
                    const std::vector<uint8_t>& pixels) {
  expectCubeScene(model, out);
  Scene s = loadScene(out);
  ASSERT_EQ(s.manifest.textures, 1u);
  TextureData t = loadTexture(s, 0);
  EXPECT_EQ(t.width, 2u);
  EXPECT_EQ(t.rgba, pixels);
  EXPECT_TRUE(t.repeat_s && t.repeat_t) << "glTF's default sampler repeats";
  GeometryData g = loadGeometry(s, 0);
  EXPECT_EQ(g.submeshes[0].texture, 0);
  std::vector<std::pair<float, float>> got, want;
  for (size_t i = 0; i < g.vertexCount(); ++i)
    got.push_back({g.texcoords[2 * i], g.texcoords[2 * i + 1]});
  for (const auto& uv : kUv) want.push_back({uv[0], 1 - uv[1]});
  std::sort(got.begin(), got.end());
  std::sort(want.begin(), want.end());
  EXPECT_EQ(got, want);
}

TEST(Gltf, ExternalTexture) {
  TempDir dir;
  fs::create_directories(dir / "tex");
  std::vector<uint8_t> px = writePng(dir / "tex/checker.png");
  writeBytes(dir / "cube.bin", cubeBuffer());
  writeText(dir / "cube.gltf", gltfJson({"cube.bin", "tex/checker.png"}, cubeBuffer().size()));
  expectTextured(dir / "cube.gltf", dir / "scene", px);
}

TEST(Gltf, EmbeddedDataUriTexture) {
  TempDir dir;
  std::vector<uint8_t> px = writePng(dir / "checker.png");
  std::string image = "data:image/png;base64," + base64(readFileBytes(dir / "checker.png"));
  fs::remove(dir / "checker.png");
  writeBytes(dir / "cube.bin", cubeBuffer());
  writeText(dir / "cube.gltf", gltfJson({"cube.bin", image}, cubeBuffer().size()));
  expectTextured(dir / "cube.gltf", dir / "scene", px);
}

TEST(Gltf, MissingTextureLoadsUntexturedWithAWarning) {
  TempDir dir;
  writeBytes(dir / "cube.bin", cubeBuffer());
  writeText(dir / "cube.gltf", gltfJson({"cube.bin", "gone.png"}, cubeBuffer().size()));
  testing::internal::CaptureStderr();
  PreprocessStats st = run({dir / "cube.gltf"}, dir / "scene");
  std::string err = testing::internal::GetCapturedStderr();
  EXPECT_TRUE(has(err, "gone.png")) << err;
  EXPECT_EQ(st.textures, 0u);
  EXPECT_EQ(st.triangles, 24u);
}

TEST(Gltf, FbxWrittenByAssimpMatchesAssimp) {
  TempDir dir;
  writeBytes(dir / "cube.glb", glbBytes());
  Assimp::Importer imp;
  const aiScene* s = imp.ReadFile(dir / "cube.glb", 0);
  ASSERT_TRUE(s) << imp.GetErrorString();
  Assimp::Exporter ex;
  ASSERT_EQ(ex.Export(s, "fbxa", dir / "cube.fbx"), AI_SUCCESS) << ex.GetErrorString();
  run({dir / "cube.fbx"}, dir / "scene");
  Scene scene = loadScene(dir / "scene");
  Report r = assimpReport(dir / "cube.fbx");
  EXPECT_EQ(scene.manifest.triangles, 24u);
  EXPECT_EQ(scene.manifest.triangles, r.triangles);
  expectNear(scene.manifest.bounds.lo, r.box.lo, 1e-4);
  expectNear(scene.manifest.bounds.hi, r.box.hi, 1e-4);
}

// ---- glTF errors: each names the file -------------------------------------------

TEST(GltfErrors, MissingBufferNamesIt) {
  TempDir dir;
  writeText(dir / "cube.gltf", gltfJson({"missing.bin", ""}, cubeBuffer().size()));
  std::string e = errorOf({dir / "cube.gltf"}, dir / "scene");
  EXPECT_TRUE(has(e, "cube.gltf")) << e;
  EXPECT_TRUE(has(e, "missing.bin")) << e;
}

TEST(GltfErrors, BufferEscapingTheDirectoryIsRefused) {
  TempDir dir;
  fs::create_directories(dir / "model");
  writeBytes(dir / "outside.bin", cubeBuffer());  // exists, but is not the model's to read
  writeText(dir / "model/cube.gltf", gltfJson({"../outside.bin", ""}, cubeBuffer().size()));
  std::string e = errorOf({dir / "model/cube.gltf"}, dir / "scene");
  EXPECT_TRUE(has(e, "cube.gltf")) << e;
  EXPECT_TRUE(has(e, "'../outside.bin'")) << e;
  EXPECT_TRUE(has(e, "outside the model's directory")) << e;
}

TEST(GltfErrors, AbsoluteAndUrlReferencesAreRefused) {
  TempDir dir;
  writeBytes(dir / "cube.bin", cubeBuffer());
  std::string abs = fs::absolute(dir / "cube.bin").string();
  writeText(dir / "a.gltf", gltfJson({abs, ""}, cubeBuffer().size()));
  std::string e = errorOf({dir / "a.gltf"}, dir / "s1");
  EXPECT_TRUE(has(e, "a.gltf") && has(e, abs) && has(e, "absolute paths")) << e;
  writeText(dir / "b.gltf", gltfJson({"http://127.0.0.1:9/cube.bin", ""}, cubeBuffer().size()));
  e = errorOf({dir / "b.gltf"}, dir / "s2");
  EXPECT_TRUE(has(e, "b.gltf") && has(e, "http://127.0.0.1:9/cube.bin") && has(e, "scheme")) << e;
}

TEST(GltfErrors, TextureEscapingTheDirectoryIsRefused) {
  TempDir dir;
  fs::create_directories(dir / "model");
  writePng(dir / "secret.png");
  writeBytes(dir / "model/cube.bin", cubeBuffer());
  writeText(dir / "model/cube.gltf", gltfJson({"cube.bin", "../secret.png"}, cubeBuffer().size()));
  std::string e = errorOf({dir / "model/cube.gltf"}, dir / "scene");
  EXPECT_TRUE(has(e, "cube.gltf") && has(e, "'../secret.png'")) << e;
}

TEST(GltfErrors, SymlinkOutOfTheDirectoryIsRefused) {
  TempDir dir;
  fs::create_directories(dir / "model");
  writeBytes(dir / "outside.bin", cubeBuffer());
  fs::create_symlink(fs::absolute(dir / "outside.bin"), dir / "model/cube.bin");
  writeText(dir / "model/cube.gltf", gltfJson({"cube.bin", ""}, cubeBuffer().size()));
  std::string e = errorOf({dir / "model/cube.gltf"}, dir / "scene");
  EXPECT_TRUE(has(e, "cube.gltf") && has(e, "outside the model's directory")) << e;
}

TEST(GltfErrors, TruncatedAndMalformedFilesNameTheFile) {
  TempDir dir;
  std::vector<uint8_t> glb = glbBytes();
  for (size_t cut : {size_t(6), size_t(30), glb.size() / 2, glb.size() - 10}) {
    std::vector<uint8_t> part(glb.begin(), glb.begin() + long(cut));
    std::string name = "cut" + std::to_string(cut) + ".glb";
    writeBytes(dir / name, part);
    std::string e = errorOf({dir / name}, dir / ("s" + std::to_string(cut)));
    EXPECT_TRUE(has(e, name)) << e;
  }
  writeText(dir / "bad.gltf", "{\"asset\": {\"version\": \"2.0\"}, \"meshes\": [");
  std::string e = errorOf({dir / "bad.gltf"}, dir / "s");
  EXPECT_TRUE(has(e, "bad.gltf")) << e;
  // An index past the vertices: the triangle is dropped (in both
  // instances), nothing is read out of bounds.
  std::vector<uint8_t> b = cubeBuffer();
  b[160] = 200;
  writeBytes(dir / "oob.bin", b);
  writeText(dir / "oob.gltf", gltfJson({"oob.bin", ""}, b.size()));
  testing::internal::CaptureStderr();
  PreprocessStats st = run({dir / "oob.gltf"}, dir / "s3");
  testing::internal::GetCapturedStderr();
  EXPECT_EQ(st.triangles, 22u);
}

TEST(ResolveReference, InsideTheDirectoryOnly) {
  TempDir dir;
  std::string r, why;
  EXPECT_TRUE(resolveReference(dir.path(), "a/b.bin", &r, &why));
  EXPECT_EQ(r, (fs::weakly_canonical(dir.path()) / "a/b.bin").string());
  EXPECT_TRUE(resolveReference(dir.path(), "a/../b.bin", &r, &why)) << "stays inside";
  EXPECT_TRUE(resolveReference(dir.path(), "a\\b.bin", &r, &why));
  EXPECT_FALSE(resolveReference(dir.path(), "../b.bin", &r, &why));
  EXPECT_FALSE(resolveReference(dir.path(), "a/../../b.bin", &r, &why));
  EXPECT_FALSE(resolveReference(dir.path(), "/etc/passwd", &r, &why));
  EXPECT_FALSE(resolveReference(dir.path(), "C:\\x.png", &r, &why));
  EXPECT_FALSE(resolveReference(dir.path(), "file:///etc/passwd", &r, &why));
  EXPECT_FALSE(resolveReference(dir.path(), "", &r, &why));
}

// ---- directories and many inputs ------------------------------------------------

TEST(Directories, EveryModelBelowIsReadInPathOrder) {
  TempDir dir;
  fs::create_directories(dir / "parts/sub");
  fs::create_directories(dir / "parts/.hidden");
  writeBytes(dir / "parts/a.bin", cubeBuffer());
  writeText(dir / "parts/a.gltf", gltfJson({"a.bin", ""}, cubeBuffer().size()));
  ASSERT_TRUE(osgDB::writeNodeFile(*osgCube({0, 0, 20}), dir / "parts/b.osgb"));
  ASSERT_TRUE(osgDB::writeNodeFile(*osgCube({0, 0, 40}), dir / "parts/sub/c.osgb"));
  ASSERT_TRUE(osgDB::writeNodeFile(*osgCube({0, 0, 60}), dir / "parts/.hidden/d.osgb"));
  writeText(dir / "parts/README.txt", "not a model\n");
  PreprocessStats st = run({dir / "parts"}, dir / "scene");
  EXPECT_EQ(st.inputs, 3u);
  EXPECT_EQ(st.triangles, 24u + 12u + 12u);
  Scene s = loadScene(dir / "scene");
  std::vector<std::string> want;
  for (const char* f : {"parts/a.gltf", "parts/b.osgb", "parts/sub/c.osgb"})
    want.push_back(fs::absolute(dir / f).string());
  EXPECT_EQ(s.manifest.inputs, want);
  // Objects in input order: the glTF's two, then b's, then c's.
  ASSERT_EQ(s.objects.size(), 4u);
  EXPECT_NEAR(s.objects[2].box.center().z, 20, 1e-9);
  EXPECT_NEAR(s.objects[3].box.center().z, 40, 1e-9);
  EXPECT_NEAR(s.manifest.bounds.hi.z, 40.5, 1e-9) << "the hidden directory is skipped";
}

TEST(Directories, EmptyOrModelLessDirectoryIsAnErrorNamingIt) {
  TempDir dir;
  fs::create_directories(dir / "empty");
  std::string e = errorOf({dir / "empty"}, dir / "s1");
  EXPECT_TRUE(has(e, "empty") && has(e, "no model file")) << e;
  fs::create_directories(dir / "textures");
  writePng(dir / "textures/a.png");
  writeBytes(dir / "textures/a.bin", cubeBuffer());
  e = errorOf({dir / "textures"}, dir / "s2");
  EXPECT_TRUE(has(e, "textures") && has(e, "no model file")) << e;
}

TEST(Directories, AnUnreadableModelFailsUnlessSkipped) {
  TempDir dir;
  fs::create_directories(dir / "parts");
  ASSERT_TRUE(osgDB::writeNodeFile(*osgCube({0, 0, 0}), dir / "parts/a.osgb"));
  writeText(dir / "parts/b.gltf", "{ this is not json");
  ASSERT_TRUE(osgDB::writeNodeFile(*osgCube({0, 0, 5}), dir / "parts/c.osgb"));
  std::string e = errorOf({dir / "parts"}, dir / "s1");
  EXPECT_TRUE(has(e, "b.gltf")) << e;
  testing::internal::CaptureStderr();
  PreprocessStats st = run({dir / "parts"}, dir / "s2", true);
  std::string err = testing::internal::GetCapturedStderr();
  EXPECT_TRUE(has(err, "warning: skipped") && has(err, "b.gltf")) << err;
  EXPECT_EQ(st.inputs, 2u);
  EXPECT_EQ(st.skipped_inputs, 1u);
  EXPECT_EQ(st.triangles, 24u);
  // Every input skipped: said so, not "no triangles".
  fs::create_directories(dir / "broken");
  writeText(dir / "broken/x.gltf", "{ not json");
  testing::internal::CaptureStderr();
  e = dmmr::test::errorOf([&] { run({dir / "broken"}, dir / "s3", true); });
  testing::internal::GetCapturedStderr();
  EXPECT_TRUE(has(e, "every input was skipped as unreadable (1)")) << e;
  EXPECT_FALSE(fs::exists(dir / "s3"));
  // A dangling symbolic link at the output is refused before any work.
  fs::create_symlink(dir / "nowhere", dir / "link");
  e = errorOf({dir / "parts"}, dir / "link");
  EXPECT_TRUE(has(e, "output already exists")) << e;
}

// Inputs are read, traversed and released one at a time, and a later input
// may be allocated where an earlier one was: nothing keyed on an earlier
// input's pointers may be taken for a later one's. Many small files of
// different cubes: every object must carry its own file's cube.
TEST(Directories, InputsReadOneAtATimeKeepTheirOwnGeometry) {
  TempDir dir;
  fs::create_directories(dir / "parts");
  const int n = 40;
  for (int i = 0; i < n; ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "parts/p%03d.osgb", i);
    ASSERT_TRUE(osgDB::writeNodeFile(*osgCube({float(3 * i), 0, 0}), dir / name));
  }
  PreprocessStats st = run({dir / "parts", dir / "parts/p000.osgb"}, dir / "scene");
  EXPECT_EQ(st.inputs, size_t(n + 1));
  EXPECT_EQ(st.geometries, size_t(n + 1)) << "one geometry per input: no sharing across inputs";
  Scene s = loadScene(dir / "scene");
  ASSERT_EQ(s.objects.size(), size_t(n + 1));
  for (int i = 0; i <= n; ++i) {
    double x = 3.0 * (i % n);
    EXPECT_NEAR(s.objects[i].box.lo.x, x - 0.5, 1e-9) << i;
    EXPECT_NEAR(s.objects[i].box.hi.x, x + 0.5, 1e-9) << i;
    EXPECT_EQ(s.objects[i].geometry, uint32_t(i));
  }
}

TEST(Directories, CommandLineTakesADirectory) {
  TempDir dir;
  fs::create_directories(dir / "parts");
  writeBytes(dir / "parts/cube.glb", glbBytes());
  ASSERT_TRUE(osgDB::writeNodeFile(*osgCube({0, 0, 9}), dir / "parts/cube.osgb"));
  int status = 0;
  std::string out = test::runCapture(
      test::tool("dmmr-preprocess") + " " + (dir / "parts") + " -o " + (dir / "scene"), &status);
  EXPECT_EQ(status, 0) << out;
  EXPECT_TRUE(has(out, "2 inputs, 3 objects")) << out;
  out = test::runCapture(
      test::tool("dmmr-preprocess") + " " + (dir / "nothing") + " -o " + (dir / "s2"), &status);
  EXPECT_EQ(status, 1);
  EXPECT_TRUE(has(out, "nothing: no such file")) << out;
}
