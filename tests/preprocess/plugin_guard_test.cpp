// Models from strangers: only allowed model and image formats load while the
// preprocessor reads; network references, scripts and unusual plugins are
// refused with a warning and the model loads without them.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <osg/Geode>
#include <osg/ProxyNode>
#include <osg/ShapeDrawable>
#include <osg/Texture2D>
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
