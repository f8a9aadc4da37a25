// OBJ indices checked before OSG's plugin reads them (obj_check.h): an index
// past the vertices made the plugin read past its arrays.
#include <gtest/gtest.h>

#include <sstream>

#include "obj_check.h"
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
