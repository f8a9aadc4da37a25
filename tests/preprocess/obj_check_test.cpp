// OBJ indices checked before OSG's plugin reads them (obj_check.h): an index
// past the vertices made the plugin read past its arrays.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "obj_check.h"
#include "preprocess.h"
#include "test_support.h"

namespace {
std::string errorOf(const std::string& text) {
  return dmmr::test::errorOf([&] {
    std::istringstream in(text);
    dmmr::checkObjIndices(in, "m.obj");
  });
}
const std::string kQuad = "v 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1\nvt 0 0\nvn 0 1 0\n";
}  // namespace

TEST(ObjCheck, IndicesWithinTheFileAreAccepted) {
  EXPECT_EQ(errorOf(kQuad + "f 1 2 3 4\nf -4 -3 -2\nf 1/1 2/1/1 3//1\nl 1 2\np 4\n"), "");
  EXPECT_EQ(errorOf("f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"), "") << "vertices after the face";
  EXPECT_EQ(errorOf(kQuad + "f 1 2 3 # a comment\r\n"), "");
  EXPECT_EQ(errorOf("# no faces\nvn 0 0 1\n"), "");
}

TEST(ObjCheck, AnIndexPastTheVerticesNamesItsLine) {
  std::string e = errorOf(kQuad + "f 1 3 9\n");
  EXPECT_NE(e.find("m.obj:7: vertex index 9 is past the file's 4 vertices"), std::string::npos)
      << e;
  e = errorOf(kQuad + "f 1/2 2/1 3/1\n");
  EXPECT_NE(e.find("texture coordinate index 2 is past the file's 1 texture coordinate"),
            std::string::npos)
      << e;
  e = errorOf(kQuad + "f 1//5 2//1 3//1\n");
  EXPECT_NE(e.find("normal index 5 is past"), std::string::npos) << e;
}

TEST(ObjCheck, ZeroNegativePastTheStartAndJunkAreRefused) {
  EXPECT_NE(errorOf(kQuad + "f 0 1 2\n").find("m.obj:7: '0' is not a vertex index"),
            std::string::npos);
  EXPECT_NE(
      errorOf(kQuad + "f -9 1 2\n").find("vertex index -9 reaches before the first (4 so far)"),
      std::string::npos);
  EXPECT_NE(errorOf(kQuad + "f 1 2 abc\n").find("'abc' is not a vertex index"), std::string::npos);
  EXPECT_NE(errorOf(kQuad + "f 1 3 99999999999999999999\n").find("is not a vertex index"),
            std::string::npos);
}

TEST(ObjCheck, LinesCutShortAreRefused) {
  std::string e = errorOf(kQuad + "f 1 2 3\nf 1 3");
  EXPECT_NE(e.find("m.obj:8: a face of 2 vertices (3 or more needed); is the file cut short?"),
            std::string::npos)
      << e;
  e = errorOf(kQuad + "f 1 2 3\nv 1 # two\n");
  EXPECT_NE(e.find("m.obj:8: a vertex position of 1 coordinates"), std::string::npos) << e;
  e = errorOf(kQuad + "vn 0 1\n");
  EXPECT_NE(e.find("m.obj:7: a normal of 2 coordinates"), std::string::npos) << e;
  // Lines and points may have fewer; texture coordinates 1 to 3.
  EXPECT_EQ(errorOf(kQuad + "l 1 2\np 3\nvt 0.5\nv 1 2 3 1\n"), "");
}

// The check runs on the preprocessor's way in whatever the extension's case
// (OSG reads .OBJ and .Obj as OBJ): a bad index in m.OBJ stops the run with
// the file and line, and no scene is written.
TEST(ObjCheck, ThePreprocessorChecksAnObjWhateverItsExtensionsCase) {
  dmmr::test::TempDir dir;
  for (const char* name : {"m.OBJ", "n.Obj"}) {
    std::ofstream(dir / name) << kQuad << "f 1 3 9\n";
    dmmr::PreprocessOptions o;
    o.inputs = {dir / name};
    o.out = dir / (std::string(name) + ".scene");
    o.progress = false;
    std::string e = dmmr::test::errorOf([&] { dmmr::preprocess(o); });
    EXPECT_NE(e.find(std::string(name) + ":7: vertex index 9 is past the file's 4 vertices"),
              std::string::npos)
        << e;
    EXPECT_FALSE(std::filesystem::exists(o.out)) << name;
  }
}
