// Models from strangers: only allowed model and image formats load while the
// preprocessor reads; network references, scripts and unusual plugins are
// refused with a warning and the model loads without them.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <osg/Geode>
#include <osg/ProxyNode>
#include <osg/ShapeDrawable>
#include <osg/Texture2D>
#include <osgDB/ReadFile>
#include <osgDB/Registry>
#include <osgDB/WriteFile>

#include "plugin_guard.h"
#include "preprocess.h"
#include "scene.h"
#include "test_support.h"

using namespace dmmr;
using dmmr::test::TempDir;

TEST(AllowedReference, ModelsAndImagesByExtensionOnly) {
  std::string why;
  EXPECT_TRUE(allowedReference("a/b/model.OSGB", ReadKind::Node, &why));
  EXPECT_TRUE(allowedReference("plant.obj", ReadKind::Node, &why));
  EXPECT_TRUE(allowedReference("tex/wall.png", ReadKind::Image, &why));
  EXPECT_TRUE(allowedReference("wall.JPG", ReadKind::Object, &why));
  EXPECT_FALSE(allowedReference("wall.png", ReadKind::Node, &why));
  EXPECT_FALSE(allowedReference("model.osgb", ReadKind::Image, &why));
}

TEST(AllowedReference, RefusesNetworkScriptsPseudoLoadersAndArchives) {
  std::string why;
  EXPECT_FALSE(allowedReference("http://example.com/model.osgb", ReadKind::Node, &why));
  EXPECT_NE(why.find("network"), std::string::npos);
  EXPECT_FALSE(allowedReference("https://example.com/t.png", ReadKind::Image, &why));
  EXPECT_FALSE(allowedReference("evil.lua", ReadKind::Node, &why));
  EXPECT_NE(why.find("'.lua' is not an allowed"), std::string::npos) << why;
  EXPECT_FALSE(allowedReference("model.osg.0,0,1.trans", ReadKind::Node, &why));
  EXPECT_FALSE(allowedReference("model.osg.2.scale", ReadKind::Node, &why));
  EXPECT_FALSE(allowedReference("data.zip", ReadKind::Node, &why));
  EXPECT_FALSE(allowedReference("noextension", ReadKind::Node, &why));
  EXPECT_NE(why.find("no extension"), std::string::npos);
  EXPECT_FALSE(allowedReference("dir.osgb/file", ReadKind::Node, &why));
  EXPECT_FALSE(allowedReference("shader.vert", ReadKind::Other, &why));
}

// A model whose texture is a URL and which pulls in a script and a
// pseudo-loader through proxy nodes: it loads, without those, with warnings.
TEST(PluginGuard, AModelReferencingAUrlAndAScriptLoadsWithoutThem) {
  TempDir dir;
  osg::ref_ptr<osg::Group> root = new osg::Group;
  auto* geode = new osg::Geode;
  geode->addDrawable(new osg::ShapeDrawable(new osg::Box({0, 0, 0}, 1)));
  osg::ref_ptr<osg::Image> image = new osg::Image;
  image->setFileName("http://127.0.0.1:9/texture.png");
  auto* texture = new osg::Texture2D(image.get());
  geode->getOrCreateStateSet()->setTextureAttributeAndModes(0, texture);
  root->addChild(geode);
  for (const char* name : {"payload.lua", "child.osgt.0,0,5.trans", "http://127.0.0.1:9/m.osgb"}) {
    auto* proxy = new osg::ProxyNode;
    proxy->setFileName(0, name);
    proxy->setLoadingExternalReferenceMode(osg::ProxyNode::LOAD_IMMEDIATELY);
    root->addChild(proxy);
  }
  std::string model = dir / "hostile.osgt";
  osg::ref_ptr<osgDB::Options> write = new osgDB::Options("WriteImageHint=UseExternal");
  ASSERT_TRUE(osgDB::writeNodeFile(*root, model, write.get()));
  std::ofstream(dir / "payload.lua") << "os.execute('touch " << (dir / "pwned") << "')\n";

  PreprocessOptions o;
  o.inputs = {model};
  o.out = dir / "scene";
  o.progress = false;
  testing::internal::CaptureStderr();
  preprocess(o);
  std::string err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("refused to read 'http://127.0.0.1:9/texture.png'"), std::string::npos) << err;
  EXPECT_NE(err.find("payload.lua"), std::string::npos) << err;
  EXPECT_NE(err.find(".trans"), std::string::npos) << err;
  EXPECT_NE(err.find("http://127.0.0.1:9/m.osgb"), std::string::npos) << err;
  EXPECT_FALSE(std::filesystem::exists(dir / "pwned"));
  Scene scene = loadScene(o.out);
  EXPECT_EQ(scene.manifest.objects, 1u) << "the box still loads";
}

// Files a model names are read only from its directory or below: an OBJ's
// mtllib and texture outside it (by a relative or an absolute path), and a
// ProxyNode's model outside it, are refused with a warning naming them; the
// same files beside the model are read. /dev/zero as an mtllib (which hung
// the read) is refused as not a regular file.
TEST(PluginGuard, FilesOutsideTheModelsDirectoryAreNotRead) {
  TempDir dir;
  std::filesystem::create_directories(dir / "model");
  std::filesystem::create_directories(dir / "outside");
  osg::ref_ptr<osg::Image> image = new osg::Image;
  image->allocateImage(2, 2, 1, GL_RGBA, GL_UNSIGNED_BYTE);
  std::fill(image->data(), image->data() + 16, 128);
  for (const char* png : {"outside/t.png", "model/t.png"})
    ASSERT_TRUE(osgDB::writeImageFile(*image, dir / png));
  for (const char* mtl : {"outside/m.mtl", "model/m.mtl"})
    std::ofstream(dir / mtl) << "newmtl skin\nKd 1 1 1\nmap_Kd t.png\n";
  std::ofstream(dir / "model/absolute.mtl")
      << "newmtl skin\nmap_Kd " << (dir / "outside/t.png") << "\n";
  const std::string quad =
      "v 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
      "usemtl skin\nf 1/1 2/2 3/3 4/4\n";
  std::ofstream(dir / "model/out.obj") << "mtllib ../outside/m.mtl\n" << quad;
  std::ofstream(dir / "model/abs.obj") << "mtllib absolute.mtl\n" << quad;
  std::ofstream(dir / "model/zero.obj") << "mtllib /dev/zero\n" << quad;
  std::ofstream(dir / "model/in.obj") << "mtllib m.mtl\n" << quad;
  auto run = [&](const std::string& model, const std::string& out, std::string* err) {
    PreprocessOptions o;
    o.inputs = {dir / model};
    o.out = dir / out;
    o.progress = false;
    testing::internal::CaptureStderr();
    PreprocessStats st = preprocess(o);
    *err = testing::internal::GetCapturedStderr();
    return st;
  };
  std::string err;
  EXPECT_EQ(run("model/in.obj", "s-in", &err).textures, 1u) << "beside the model: read";
  EXPECT_EQ(run("model/out.obj", "s-out", &err).textures, 0u);
  EXPECT_NE(err.find("refused to read '../outside/m.mtl'"), std::string::npos) << err;
  EXPECT_NE(err.find("outside the model's directory"), std::string::npos) << err;
  EXPECT_EQ(run("model/abs.obj", "s-abs", &err).textures, 0u);
  EXPECT_NE(err.find("outside/t.png"), std::string::npos) << err;
  // Given the directory above both, the model may name files in that tree.
  EXPECT_GE(run(".", "s-tree", &err).textures, 2u) << err;
  EXPECT_EQ(err.find("refused to read '../outside/m.mtl'"), std::string::npos) << err;
  EXPECT_EQ(run("model/zero.obj", "s-zero", &err).textures, 0u);
  EXPECT_NE(err.find("refused to read '/dev/zero'"), std::string::npos) << err;

  osg::ref_ptr<osg::Group> root = new osg::Group;
  auto* proxy = new osg::ProxyNode;
  proxy->setFileName(0, "../outside/box.osgb");
  proxy->setLoadingExternalReferenceMode(osg::ProxyNode::LOAD_IMMEDIATELY);
  root->addChild(proxy);
  auto* geode = new osg::Geode;
  geode->addDrawable(new osg::ShapeDrawable(new osg::Box({0, 0, 0}, 1)));
  root->addChild(geode);
  osg::ref_ptr<osg::Geode> far = new osg::Geode;
  far->addDrawable(new osg::ShapeDrawable(new osg::Box({5, 0, 0}, 1)));
  ASSERT_TRUE(osgDB::writeNodeFile(*far, dir / "outside/box.osgb"));
  ASSERT_TRUE(osgDB::writeNodeFile(*root, dir / "model/proxy.osgt"));
  EXPECT_EQ(run("model/proxy.osgt", "s-proxy", &err).objects, 1u) << "the outside box is not read";
  EXPECT_NE(err.find("../outside/box.osgb"), std::string::npos) << err;
}

TEST(PluginGuard, AnInputInAFormatOutsideTheListIsRefused) {
  TempDir dir;
  std::ofstream(dir / "model.lua") << "return 1\n";
  PreprocessOptions o;
  o.inputs = {dir / "model.lua"};
  o.out = dir / "scene";
  o.progress = false;
  testing::internal::CaptureStderr();
  std::string e = test::errorOf([&] { preprocess(o); });
  testing::internal::GetCapturedStderr();
  EXPECT_NE(e.find("model.lua"), std::string::npos) << e;
}

TEST(PluginGuard, RestoresTheRegistryCallbackItReplaced) {
  osgDB::ReadFileCallback* before = osgDB::Registry::instance()->getReadFileCallback();
  {
    PluginGuard guard;
    EXPECT_NE(osgDB::Registry::instance()->getReadFileCallback(), before);
  }
  EXPECT_EQ(osgDB::Registry::instance()->getReadFileCallback(), before);
}
