// Surface effects chosen by name (client/effects.h) on a hand-made skeleton.
#include <gtest/gtest.h>

#include "effects.h"

using namespace dmmr;

namespace {

// root
//   "building"            (group)
//     "window-1"          object 0
//     "wall"              object 1
//   "pool"                (group)
//     "water"             object 2
//   "mirror-ball"         object 3
std::vector<SkeletonNode> skeleton() {
  auto node = [](NodeKind k, uint32_t parent, uint32_t object, const char* name) {
    SkeletonNode n;
    n.kind = k;
    n.parent = parent;
    n.object = object;
    n.name = name;
    return n;
  };
  return {node(NodeKind::Group, kNone, kNone, ""),    node(NodeKind::Group, 0, kNone, "building"),
          node(NodeKind::Object, 1, 0, "window-1"),   node(NodeKind::Object, 1, 1, "wall"),
          node(NodeKind::Group, 0, kNone, "pool"),    node(NodeKind::Object, 4, 2, "water"),
          node(NodeKind::Object, 0, 3, "mirror-ball")};
}

}  // namespace

TEST(Effects, NoPatternsMarkNothing) {
  auto e = effectsByName(skeleton(), 4, {}, {});
  EXPECT_EQ(e, std::vector<SurfaceEffect>(4, SurfaceEffect::None));
}

TEST(Effects, AnObjectsOwnNameOrAnAncestorsMatches) {
  auto e = effectsByName(skeleton(), 4, {"mirror-*"}, {"window*", "pool"});
  EXPECT_EQ(e[0], SurfaceEffect::Glass);  // its own name
  EXPECT_EQ(e[1], SurfaceEffect::None);   // a sibling
  EXPECT_EQ(e[2], SurfaceEffect::Glass);  // its group's name
  EXPECT_EQ(e[3], SurfaceEffect::Mirror);
}

TEST(Effects, GlassWinsOverMirrorAndPatternsAreCaseSensitive) {
  auto e = effectsByName(skeleton(), 4, {"building"}, {"window-?"});
  EXPECT_EQ(e[0], SurfaceEffect::Glass);
  EXPECT_EQ(e[1], SurfaceEffect::Mirror);
  e = effectsByName(skeleton(), 4, {"WALL"}, {});
  EXPECT_EQ(e[1], SurfaceEffect::None);
}
