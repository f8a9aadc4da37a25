// The visibility stage's pure parts: the plan (occluders, marked, queried),
// the sorted-list union, and the near-plane test that decides which objects
// are taken without a query.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <set>
#include <vector>

#include "draw.h"
#include "visibility.h"

using namespace dmmr;

namespace {

using List = std::vector<uint32_t>;

// A random ascending subset of [0, n): each index kept with probability p.
List randomSubset(std::mt19937& rng, uint32_t n, double p) {
  std::bernoulli_distribution keep(p);
  List out;
  for (uint32_t i = 0; i < n; ++i)
    if (keep(rng)) out.push_back(i);
  return out;
}

bool contains(const List& sorted, uint32_t v) {
  return std::binary_search(sorted.begin(), sorted.end(), v);
}

// Checks every property of a plan against a direct computation.
void checkPlan(const List& region, const List& previous, const List& potential,
               const List& marked_until, uint32_t frame, const VisibilityPlan& p) {
  List occluders, marked, queried;
  for (uint32_t o : region) {
    if (contains(previous, o) || contains(potential, o))
      occluders.push_back(o);
    else if (o < marked_until.size() && frame < marked_until[o])
      marked.push_back(o);
    else
      queried.push_back(o);
  }
  EXPECT_EQ(p.occluders, occluders);
  EXPECT_EQ(p.marked, marked);
  EXPECT_EQ(p.queried, queried);
  for (const List* l : {&p.occluders, &p.marked, &p.queried})
    EXPECT_TRUE(std::adjacent_find(l->begin(), l->end(), std::greater_equal<uint32_t>()) ==
                l->end())
        << "not strictly ascending";
  // Disjoint, and together exactly the region.
  std::multiset<uint32_t> all;
  all.insert(p.occluders.begin(), p.occluders.end());
  all.insert(p.marked.begin(), p.marked.end());
  all.insert(p.queried.begin(), p.queried.end());
  EXPECT_EQ(List(all.begin(), all.end()), region);
}

}  // namespace

TEST(PlanVisibility, SmallHandWrittenCase) {
  List region = {1, 2, 3, 5, 8, 9, 12};
  List previous = {0, 2, 9, 10};   // 0 and 10 are outside the region
  List potential = {3, 4, 9, 13};  // 9 in both lists
  List marked_until(14, 0);
  marked_until[1] = 8;   // still marked at frame 7
  marked_until[5] = 7;   // expires exactly at frame 7
  marked_until[2] = 20;  // an occluder anyway
  VisibilityPlan p = planVisibility(region, previous, potential, marked_until, 7);
  EXPECT_EQ(p.occluders, (List{2, 3, 9}));
  EXPECT_EQ(p.marked, (List{1}));
  EXPECT_EQ(p.queried, (List{5, 8, 12}));
}

TEST(PlanVisibility, EmptyInputs) {
  VisibilityPlan p = planVisibility({}, {1, 2}, {3}, {5, 5, 5, 5}, 0);
  EXPECT_TRUE(p.occluders.empty() && p.marked.empty() && p.queried.empty());
  p = planVisibility({0, 1, 2}, {}, {}, {}, 0);  // nothing known: all queried
  EXPECT_EQ(p.queried, (List{0, 1, 2}));
  EXPECT_TRUE(p.occluders.empty() && p.marked.empty());
}

TEST(PlanVisibility, ShortMarkedUntilMeansNotMarked) {
  // Objects past the end of marked_until have never passed a query.
  VisibilityPlan p = planVisibility({0, 3, 4}, {}, {}, {9, 9, 9, 9}, 2);
  EXPECT_EQ(p.marked, (List{0, 3}));
  EXPECT_EQ(p.queried, (List{4}));
}

TEST(PlanVisibility, RandomizedPropertiesHold) {
  std::mt19937 rng(20240611);
  for (int round = 0; round < 500; ++round) {
    uint32_t n = 1 + rng() % 300;
    std::uniform_real_distribution<double> u(0, 1);
    List region = randomSubset(rng, n, u(rng));
    List previous = randomSubset(rng, n + 20, u(rng) * 0.5);  // may reach past the region
    List potential = randomSubset(rng, n, u(rng) * 0.3);
    uint32_t frame = rng() % 10;
    List marked_until(rng() % (n + 1));  // sometimes shorter than the object count
    for (uint32_t& m : marked_until) m = rng() % 14;
    SCOPED_TRACE("round " + std::to_string(round));
    checkPlan(region, previous, potential, marked_until, frame,
              planVisibility(region, previous, potential, marked_until, frame));
  }
}

TEST(MergeSorted, EdgeCases) {
  EXPECT_TRUE(mergeSorted({}).empty());
  EXPECT_TRUE(mergeSorted({{}, {}}).empty());
  EXPECT_EQ(mergeSorted({{3, 7}}), (List{3, 7}));
  EXPECT_EQ(mergeSorted({{1, 2}, {2, 3}, {}, {0, 3}}), (List{0, 1, 2, 3}));
  EXPECT_EQ(mergeSorted({{0xFFFFFFFFu}, {0}}), (List{0, 0xFFFFFFFFu}));
}

TEST(MergeSorted, MatchesStdSetOnRandomLists) {
  std::mt19937 rng(77);
  for (int round = 0; round < 300; ++round) {
    std::vector<List> lists(rng() % 5);
    std::set<uint32_t> expect;
    for (List& l : lists) {
      l = randomSubset(rng, 1 + rng() % 200, 0.3);
      expect.insert(l.begin(), l.end());
    }
    EXPECT_EQ(mergeSorted(lists), List(expect.begin(), expect.end())) << "round " << round;
  }
}

// Against the code mergeSorted replaced (sort and unique of the
// concatenation), on ascending lists that may repeat values within a list
// and share them across lists, of any length, near UINT32_MAX too.
TEST(MergeSorted, MatchesSortUniqueOfTheConcatenation) {
  std::mt19937 rng(1414);
  for (int round = 0; round < 2000; ++round) {
    std::vector<List> lists(rng() % 6);
    List all;
    uint32_t base = rng() % 4 == 0 ? 0xFFFFFFFFu - 1000 : 0;
    for (List& l : lists) {
      size_t n = rng() % 4 == 0 ? 0 : rng() % 300;
      for (size_t i = 0; i < n; ++i) l.push_back(base + rng() % 1000);
      std::sort(l.begin(), l.end());
      all.insert(all.end(), l.begin(), l.end());
    }
    std::sort(all.begin(), all.end());
    all.erase(std::unique(all.begin(), all.end()), all.end());
    ASSERT_EQ(mergeSorted(lists), all) << "round " << round;
  }
}

namespace {

// Camera at the origin looking down -Z (identity rotation): fovy 90 degrees
// and aspect 1 give tan(fovy/2) = 1 in both directions, so the near
// rectangle's corners lie at (+-n, +-n, -n), at distance n * sqrt(3).
Camera unitCamera(double near) {
  Camera c;
  c.eye = {0, 0, 0};
  c.rotation = Quatd{};
  c.fovy_deg = 90;
  c.aspect = 1;
  c.near = near;
  return c;
}

Box3d cube(Vec3d center, double half) {
  Box3d b;
  b.lo = center - Vec3d{half, half, half};
  b.hi = center + Vec3d{half, half, half};
  return b;
}

}  // namespace

// Frames so tall that the query boxes' pixel margin vanishes: these tests
// are about the near plane's geometry.
constexpr int kTall = 1 << 24;

// Last frame's list is a poor start when it holds under a quarter of the
// triangles of the frame before's: the camera stood behind something near.
TEST(GuessCollapsed, UnderAQuarterOfTheFrameBeforesTriangles) {
  EXPECT_TRUE(guessCollapsed(0, 100));
  EXPECT_TRUE(guessCollapsed(24, 100));
  EXPECT_FALSE(guessCollapsed(25, 100));
  EXPECT_FALSE(guessCollapsed(100, 100));
  EXPECT_FALSE(guessCollapsed(500, 100));  // the set grew
  EXPECT_FALSE(guessCollapsed(0, 0));      // nothing before either (first frames)
  EXPECT_FALSE(guessCollapsed(0, 3));      // too little before to tell
  EXPECT_TRUE(guessCollapsed(1, uint64_t(1) << 40));
}

TEST(BoxReachesNearPlane, EyeInsideTheBox) {
  Camera c = unitCamera(0.1);
  EXPECT_TRUE(boxReachesNearPlane(cube({0, 0, 0}, 1), c, kTall));
  EXPECT_TRUE(boxReachesNearPlane(cube({0.5, -0.3, 0.2}, 1), c, kTall));
  // A box the eye touches from outside.
  Box3d touching;
  touching.lo = {0, -1, -1};
  touching.hi = {2, 1, 1};
  EXPECT_TRUE(boxReachesNearPlane(touching, c, kTall));
}

TEST(BoxReachesNearPlane, FarBoxesDoNot) {
  Camera c = unitCamera(0.1);
  EXPECT_FALSE(boxReachesNearPlane(cube({0, 0, -10}, 1), c, kTall));   // far in front
  EXPECT_FALSE(boxReachesNearPlane(cube({0, 0, 10}, 1), c, kTall));    // far behind
  EXPECT_FALSE(boxReachesNearPlane(cube({0, 0, -1.2}, 1), c, kTall));  // 0.2 ahead: twice near
}

TEST(BoxReachesNearPlane, NearRectangleCornerDistance) {
  // Along the diagonal through the near rectangle's corner (n, n, -n): a tiny
  // box there at distance n*sqrt(3) must count; the function allows 1%
  // more. Beyond 1.02 * n * sqrt(3) it must not.
  for (double near : {0.1, 1e-3, 2.5}) {
    Camera c = unitCamera(near);
    Vec3d dir = normalize(Vec3d{1, 1, -1});
    double corner = near * std::sqrt(3.0);
    double tiny = near * 1e-6;
    // Place a tiny cube so that its nearest point to the eye is at `d`.
    auto at = [&](double d) { return cube(dir * (d + tiny * std::sqrt(3.0)), tiny); };
    SCOPED_TRACE("near " + std::to_string(near));
    EXPECT_TRUE(boxReachesNearPlane(at(corner * 0.999), c, kTall));  // on the rectangle
    EXPECT_TRUE(boxReachesNearPlane(at(corner * 1.000), c, kTall));  // its corner
    EXPECT_TRUE(boxReachesNearPlane(at(corner * 1.005), c, kTall));  // inside the 1% margin
    EXPECT_FALSE(boxReachesNearPlane(at(corner * 1.02), c, kTall));  // just beyond
    EXPECT_FALSE(boxReachesNearPlane(at(corner * 1.5), c, kTall));
  }
}

TEST(BoxReachesNearPlane, UsesAspectAndFov) {
  // fovy 60, aspect 2: ty = tan 30 = 0.57735, tx = 1.1547, corner distance
  // n * sqrt(1 + 1/3 + 4/3) = n * 1.63299. A box along +X at the same
  // distance as the corner must count, one at twice it must not; along the
  // view axis only ~1.633 n counts, not 1.7 n.
  Camera c = unitCamera(1.0);
  c.fovy_deg = 60;
  c.aspect = 2;
  double corner = std::sqrt(1 + 1.0 / 3 + 4.0 / 3);
  ASSERT_NEAR(corner, 1.63299, 1e-5);
  auto slab = [](double x0) {  // a flat box from x0 outwards, centred on the X axis
    Box3d b;
    b.lo = {x0, -0.01, -0.01};
    b.hi = {x0 + 1, 0.01, 0.01};
    return b;
  };
  EXPECT_TRUE(boxReachesNearPlane(slab(corner * 0.99), c, kTall));
  EXPECT_FALSE(boxReachesNearPlane(slab(corner * 1.05), c, kTall));
  Box3d ahead;
  ahead.lo = {-0.5, -0.5, -10};
  ahead.hi = {0.5, 0.5, -corner * 1.0};
  EXPECT_TRUE(boxReachesNearPlane(ahead, c, kTall));
  ahead.hi.z = -corner * 1.05;
  EXPECT_FALSE(boxReachesNearPlane(ahead, c, kTall));
}

TEST(BoxReachesNearPlane, CountsTheWideningOfQueryBoxes) {
  // Renderer::queryBox widens a box by 0.1% of its size (and a little more):
  // a box 200 m deep whose front is 5 cm from the eye (near 1 cm) has a query
  // box that swallows the eye, so it must be taken without a query. See
  // OcclusionQuery.BoxesNotTakenAtTheNearPlaneGiveAnHonestQuery for what a
  // query on it would say.
  Camera c = unitCamera(0.01);
  Box3d deep;
  deep.lo = {-100, -100, -200};
  deep.hi = {100, 100, -0.05};
  EXPECT_TRUE(boxReachesNearPlane(deep, c, kTall));
  // The same front face on a box 1 m deep does not come near.
  deep.lo.z = -1.05;
  EXPECT_FALSE(boxReachesNearPlane(deep, c, kTall));
}

TEST(BoxReachesNearPlane, CountsThePixelMarginOfQueryBoxes) {
  // A box 1 cm beyond the near rectangle's reach: clear of it in a tall
  // frame; in a 2-pixel-high frame an eighth of a pixel at its far side is
  // centimetres, and the widened query box reaches the near plane.
  Camera c = unitCamera(0.01);
  Box3d b = cube({0, 0, -0.07}, 0.05);  // front face at z = -0.02
  EXPECT_FALSE(boxReachesNearPlane(b, c, kTall));
  EXPECT_TRUE(boxReachesNearPlane(b, c, 2));
}

TEST(QueryBoxBounds, WidensByAnEighthOfAPixelAtTheFarSide) {
  Camera c = unitCamera(0.01);
  Box3d b = cube({0, 0, -10}, 0.0);  // a point 10 ahead
  Box3d q = queryBoxBounds(b, c, 1000);
  double pixel = 10 * 2 * std::tan(c.fovy_deg * M_PI / 360.0) / 1000;
  EXPECT_NEAR(q.extent().x / 2, pixel / 8 + 1e-4 + 1e-9, 1e-12);
  EXPECT_TRUE(q.lo.z < -10 && q.hi.z > -10);
}

namespace {

CullCost cost(double decide, double draw, uint64_t drawn, uint64_t region) {
  return CullCost{decide, draw, drawn, region};
}
// An unculled frame's region: any size but 0 (not counted).
constexpr uint64_t kRegion = 1000;

TEST(CullingGovernor, KeepsCullingWhileItPays) {
  CullingGovernor g(4, 16, 3);
  for (int f = 0; f < 100; ++f) {
    ASSERT_TRUE(g.culls());
    g.culled(cost(5, 10, 1000, 100000));  // saves ~990 ms for 5
  }
}

TEST(CullingGovernor, StopsAfterPatienceThenProbesWithGrowingPauses) {
  CullingGovernor g(4, 16, 3);
  CullCost bad = cost(20, 100, 990, 1000);  // saves ~1 ms for 20
  EXPECT_LT(CullingGovernor::net(bad), 0);
  g.culled(bad);
  g.culled(bad);
  EXPECT_TRUE(g.culls());
  g.culled(bad);  // the third in a row
  std::vector<int> pauses;
  for (int round = 0; round < 5; ++round) {
    int off = 0;
    while (!g.culls()) {
      g.unculled(kRegion);
      ++off;
    }
    pauses.push_back(off);
    for (int k = 0; k < 3; ++k) {  // full patience again after a pause
      EXPECT_TRUE(g.culls());
      g.culled(bad);
    }
  }
  EXPECT_EQ(pauses, (std::vector<int>{4, 8, 16, 16, 16}));
  // A probe that pays keeps culling on and resets the pause.
  while (!g.culls()) g.unculled(kRegion);
  g.culled(cost(1, 10, 10, 100000));
  EXPECT_TRUE(g.culls());
  g.culled(bad);
  g.culled(bad);
  EXPECT_TRUE(g.culls());
  g.culled(bad);
  int off = 0;
  while (!g.culls()) {
    g.unculled(kRegion);
    ++off;
  }
  EXPECT_EQ(off, 4);
}

// A pause decided on small regions (everything in them visible) ends when a
// region grows past kRegrowth times the largest of them: the split lines
// moved, or the camera came near a model, and drawing it all blind costs.
TEST(CullingGovernor, APauseEndsWhenTheRegionGrowsManyTimesOver) {
  CullingGovernor g(16, 32, 3);
  g.culled(cost(20, 100, 990, 1000));
  g.culled(cost(20, 100, 1990, 2000));  // the largest of the three
  g.culled(cost(20, 100, 1490, 1500));
  ASSERT_FALSE(g.culls());
  g.region(2000 * CullingGovernor::kRegrowth);  // grown, but not past the bound
  EXPECT_FALSE(g.culls());
  g.unculled(kRegion);
  g.region(2000 * CullingGovernor::kRegrowth + 1);
  EXPECT_TRUE(g.culls()) << "a region past kRegrowth times the pause's ends it";
  // Full patience again: two bad frames do not pause, the third does.
  g.culled(cost(20, 100, 990, 1000));
  g.culled(cost(20, 100, 990, 1000));
  EXPECT_TRUE(g.culls());
  g.culled(cost(20, 100, 990, 1000));
  EXPECT_FALSE(g.culls());
  // A probe that does not pay counts its region: this pause ends only past
  // kRegrowth times the probe's larger region.
  for (int f = 0; f < 4; ++f) g.unculled(kRegion);
  ASSERT_TRUE(g.probes());
  g.probed(cost(20, 100, 9990, 10000));
  EXPECT_FALSE(g.culls());
  g.region(10000 * CullingGovernor::kRegrowth);
  EXPECT_FALSE(g.culls());
  g.region(10000 * CullingGovernor::kRegrowth + 1);
  EXPECT_TRUE(g.culls());
  // A hook's pause without a region is not ended by one.
  g.pauseFor(10);
  g.region(UINT64_MAX);
  EXPECT_FALSE(g.culls());
}

TEST(CullingGovernor, ProbesEveryFewFramesOfAPauseAndAProbeThatPaysEndsIt) {
  CullingGovernor g(16, 32, 3, 4);
  CullCost bad = cost(20, 100, 990, 1000), good = cost(1, 10, 10, 100000);
  EXPECT_FALSE(g.probes()) << "no pause, nothing to probe";
  for (int k = 0; k < 3; ++k) g.culled(bad);
  ASSERT_FALSE(g.culls());
  std::vector<bool> due;
  for (int f = 0; f < 4; ++f) {
    due.push_back(g.probes());
    g.unculled(kRegion);
  }
  EXPECT_EQ(due, (std::vector<bool>{false, false, false, false}));
  EXPECT_TRUE(g.probes()) << "the pause's 5th frame";
  g.probed(bad);  // would not pay: the pause goes on, the next probe 4 frames on
  EXPECT_FALSE(g.culls());
  g.unculled(kRegion);
  EXPECT_FALSE(g.probes());
  for (int f = 0; f < 3; ++f) g.unculled(kRegion);
  EXPECT_TRUE(g.probes());
  g.probed(good);
  EXPECT_TRUE(g.culls()) << "a probe that pays ends the pause";
  EXPECT_FALSE(g.probes());
  g.unculled(kRegion);  // the probed frame itself was drawn in full
  EXPECT_TRUE(g.culls());
  // A hook's pause is probed the same way.
  g.pauseFor(100);
  for (int f = 0; f < 4; ++f) g.unculled(kRegion);
  EXPECT_TRUE(g.probes());
}

TEST(CullingGovernor, FramesCulledAheadOfAPauseDoNotExtendIt) {
  CullingGovernor g(4, 64, 3);
  CullCost bad = cost(20, 100, 990, 1000);
  for (int k = 0; k < 3; ++k) g.culled(bad);
  ASSERT_FALSE(g.culls());
  for (int k = 0; k < 2; ++k) g.culled(bad);  // still in the pipeline when it stopped
  int off = 0;
  while (!g.culls()) {
    g.unculled(kRegion);
    ++off;
  }
  EXPECT_EQ(off, 4);
}

// Under tiles many of a client's jobs are background: a region without
// triangles says nothing about culling, so it neither starts, lengthens,
// shortens nor probes a pause, nor breaks a run of frames that did not pay.
TEST(CullingGovernor, FramesOfEmptyRegionsAreNotCounted) {
  CullingGovernor g(4, 64, 3, 2);
  CullCost bad = cost(20, 100, 990, 1000), empty = cost(0.5, 0, 0, 0);
  EXPECT_LT(CullingGovernor::net(empty), 0) << "counted, it would not pay";
  for (int k = 0; k < 10; ++k) g.culled(empty);
  EXPECT_TRUE(g.culls()) << "empty regions started a pause";
  g.culled(bad);
  g.culled(bad);
  g.culled(empty);  // neither ends the run of bad frames nor counts in it
  EXPECT_TRUE(g.culls()) << "an empty region counted as the third bad frame";
  g.culled(bad);
  ASSERT_FALSE(g.culls());
  for (int k = 0; k < 100; ++k) g.unculled(0);
  EXPECT_FALSE(g.culls()) << "empty regions used up the pause";
  EXPECT_FALSE(g.probes()) << "empty regions counted towards a probe";
  g.unculled(kRegion);
  g.unculled(kRegion);
  ASSERT_TRUE(g.probes());
  g.probed(cost(1, 10, 0, 0));  // an empty region's probe: not counted
  EXPECT_TRUE(g.probes()) << "the probe is still due";
  EXPECT_FALSE(g.culls());
  g.unculled(kRegion);
  g.unculled(kRegion);
  EXPECT_TRUE(g.culls()) << "the pause of 4 counted frames is over";
}

TEST(CullingGovernor, ANothingDrawnFramePaysWhenTheRegionHadTriangles) {
  EXPECT_GT(CullingGovernor::net(cost(3, 0, 0, 5000)), 0);
  EXPECT_LT(CullingGovernor::net(cost(3, 0, 0, 0)), 0);
}

}  // namespace

namespace {

// Feeds a trial frames finishing `split` ms apart under split stages and
// `fused` ms apart under fused ones; returns it once decided (or after 40).
StageTrial runTrial(double split, double fused, uint32_t block = 4) {
  StageTrial t(block);
  double now = 0;
  for (uint32_t f = 0; f < 40 && !t.decided(); ++f) {
    now += t.modeFor(f) == StageMode::Fused ? fused : split;
    t.finished(f, now);
  }
  return t;
}

TEST(StageTrial, AlternatesBlocksAfterTheLoadingFrame) {
  StageTrial t(2);
  std::vector<StageMode> modes;
  for (uint32_t f = 0; f < 11; ++f) modes.push_back(t.modeFor(f));
  using M = StageMode;
  EXPECT_EQ(modes, (std::vector<M>{M::Split, M::Split, M::Split, M::Fused, M::Fused, M::Split,
                                   M::Split, M::Fused, M::Fused, M::Split, M::Split}));
}

TEST(StageTrial, KeepsTheFasterMode) {
  StageTrial a = runTrial(40, 25);
  ASSERT_TRUE(a.decided());
  EXPECT_EQ(a.chosen(), StageMode::Fused);
  EXPECT_DOUBLE_EQ(a.fusedMs(), 25);
  EXPECT_DOUBLE_EQ(a.splitMs(), 40);
  EXPECT_EQ(a.modeFor(100), StageMode::Fused);
  StageTrial b = runTrial(20, 30);
  ASSERT_TRUE(b.decided());
  EXPECT_EQ(b.chosen(), StageMode::Split);
}

TEST(StageTrial, IgnoresTheIntervalsAcrossSwitches) {
  // Each block's first frame comes late (the pipeline refills): it must not count.
  StageTrial t(3);
  double now = 0;
  std::vector<double> gaps = {500, 300, 30, 30, 400, 20, 20, 300, 30, 30, 400, 20, 20};
  for (uint32_t f = 0; f < gaps.size(); ++f) t.finished(f, now += gaps[f]);
  ASSERT_TRUE(t.decided());
  EXPECT_EQ(t.chosen(), StageMode::Fused);
  EXPECT_DOUBLE_EQ(t.splitMs(), 30);
  EXPECT_DOUBLE_EQ(t.fusedMs(), 20);
}

TEST(StageTrial, UndecidedUntilBothBlocksAreIn) {
  StageTrial t(4);
  for (uint32_t f = 0; f < 12; ++f) t.finished(f, f * 10.0);
  EXPECT_FALSE(t.decided());
  EXPECT_EQ(t.modeFor(30), StageMode::Split);
}

}  // namespace

// ---- part draws ---------------------------------------------------------------

TEST(PartsMeeting, RectanglesInAndOutOfTheRegion) {
  Rect region{10, 20, 30, 40};  // pixels 10..39 x 20..59
  std::array<ScreenBound, 5> parts{};
  parts[0] = ScreenBound{false, 0, 0, 9, 100};    // left of it
  parts[1] = ScreenBound{false, 39, 59, 80, 80};  // its last pixel
  parts[2] = ScreenBound{false, 15, 25, 14, 30};  // empty
  parts[3] = ScreenBound{true};                   // reaches the near plane
  parts[4] = ScreenBound{false, 40, 20, 50, 59};  // right of it
  EXPECT_EQ(partsMeeting(parts.data(), parts.size(), region), 0b01010);
  EXPECT_EQ(partsMeeting(parts.data(), 0, region), 0);
}

// A fixed-seed property test of partsInRegion against an independent
// rasterisation: random objects (rotated, scaled, some far from the origin)
// whose geometry box is split into 8 parts, random regions, and random
// triangles inside each part; every pixel centre of the region a triangle
// covers must belong to a part in the mask. Also checks that the mask
// leaves parts out at all (or the test would pass on kAllParts).
TEST(PartsInRegion, EveryCoveredPixelOfTheRegionIsInAPartOfTheMask) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  const int width = 96, height = 64;
  Camera camera;
  camera.aspect = double(width) / height;
  camera.fovy_deg = 50;
  camera.near = 0.05;
  const double f = 1 / std::tan(camera.fovy_deg * M_PI / 360);
  size_t covered = 0, partial_masks = 0;
  for (int trial = 0; trial < 300; ++trial) {
    Vec3d offset = trial % 3 == 0 ? Vec3d{1e6, -2e6, 5e5} : Vec3d{0, 0, 0};
    camera.eye = offset;
    Quatd q{u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5, u(rng) + 0.2};
    double n = std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
    q = {q.x / n, q.y / n, q.z / n, q.w / n};
    ObjectBounds o;
    o.weight = 4 * kMinPartTriangles;
    o.transform =
        Mat4d::translate(offset + Vec3d{8 * (u(rng) - 0.5), 6 * (u(rng) - 0.5), -4 - 8 * u(rng)}) *
        Mat4d::rotation(q) * Mat4d::scale({0.5 + 2 * u(rng), 0.5 + 2 * u(rng), 0.5 + 2 * u(rng)});
    Box3d local{{-1, -1, -1}, {1, 1, 1}};
    o.box = transformBox(o.transform, local);
    std::vector<Box3d> octants;
    for (int k = 0; k < 8; ++k) {
      Box3d b;
      for (int a = 0; a < 3; ++a) {
        b.lo[a] = (k >> a & 1) ? 0.0 : -1.0;
        b.hi[a] = (k >> a & 1) ? 1.0 : 0.0;
      }
      octants.push_back(b);
    }
    GeometryParts g = quantizeParts(local, octants);
    g.triangles.assign(8, 1);
    Rect region{int(u(rng) * width * 0.7), int(u(rng) * height * 0.7), 0, 0};
    region.w = 1 + int(u(rng) * (width - region.x - 1));
    region.h = 1 + int(u(rng) * (height - region.y - 1));
    ScreenProjector projector(camera, width, height);
    ScreenBound ob = projector.bound(queryBoxBounds(o.box, camera, height));
    uint8_t mask = partsInRegion(o, g, projector, camera, width, height, ob, region);
    if (mask != kAllParts && mask != 0) ++partial_masks;
    Mat4d view = viewMatrix(camera);
    for (int k = 0; k < 8; ++k)
      for (int t = 0; t < 6; ++t) {
        double px[3], py[3];
        bool in_front = true;
        for (int c = 0; c < 3; ++c) {
          Vec3d p;
          for (int a = 0; a < 3; ++a)
            p[a] = octants[size_t(k)].lo[a] +
                   u(rng) * (octants[size_t(k)].hi[a] - octants[size_t(k)].lo[a]);
          Vec3d e = view.transformPoint(o.transform.transformPoint(p));
          if (-e.z <= camera.near) in_front = false;
          px[c] = (f / camera.aspect * e.x / -e.z + 1) / 2 * width;
          py[c] = (f * e.y / -e.z + 1) / 2 * height;
        }
        if (!in_front) continue;  // such objects reach the near plane: all parts
        auto edge = [&](int a, int b, double x, double y) {
          return (px[b] - px[a]) * (y - py[a]) - (py[b] - py[a]) * (x - px[a]);
        };
        double area = edge(0, 1, px[2], py[2]);
        if (area == 0) continue;
        for (int y = region.y; y < region.y1(); ++y)
          for (int x = region.x; x < region.x1(); ++x) {
            double cx = x + 0.5, cy = y + 0.5;
            double e0 = edge(0, 1, cx, cy), e1 = edge(1, 2, cx, cy), e2 = edge(2, 0, cx, cy);
            bool inside =
                area > 0 ? (e0 >= 0 && e1 >= 0 && e2 >= 0) : (e0 <= 0 && e1 <= 0 && e2 <= 0);
            if (!inside) continue;
            ++covered;
            ASSERT_TRUE(mask >> k & 1)
                << "trial " << trial << ": part " << k << " covers pixel (" << x << ", " << y
                << ") of " << region << ", mask " << int(mask);
          }
      }
  }
  EXPECT_GT(covered, 10000u);
  EXPECT_GT(partial_masks, 30u);
}

TEST(PartsInRegion, WholeWhereThePartsCannotHelp) {
  const int width = 96, height = 64;
  Camera camera;
  camera.aspect = double(width) / height;
  ObjectBounds o;
  o.weight = kMinPartTriangles;
  o.transform = Mat4d::translate({0, 0, -10});
  Box3d local{{-1, -1, -1}, {1, 1, 1}};
  o.box = transformBox(o.transform, local);
  GeometryParts g =
      quantizeParts(local, {Box3d{{-1, -1, -1}, {0, 1, 1}}, Box3d{{0, -1, -1}, {1, 1, 1}}});
  g.triangles = {5, 5};
  ScreenProjector projector(camera, width, height);
  ScreenBound ob = projector.bound(queryBoxBounds(o.box, camera, height));
  Rect left{0, 0, width / 2 - 4, height};  // the object's left half, roughly
  EXPECT_EQ(partsInRegion(o, g, projector, camera, width, height, ob, left), 0b01);
  Rect right{width / 2 + 4, 0, width / 2 - 4, height};
  EXPECT_EQ(partsInRegion(o, g, projector, camera, width, height, ob, right), 0b10);
  Rect whole{0, 0, width, height};  // it lies inside, off the frame's edge
  EXPECT_EQ(partsInRegion(o, g, projector, camera, width, height, ob, whole), kAllParts);
  Rect corner{0, 0, 3, 3};  // misses it
  EXPECT_EQ(partsInRegion(o, g, projector, camera, width, height, ob, corner), 0);
  GeometryParts unordered = g;
  unordered.triangles.clear();
  EXPECT_EQ(partsInRegion(o, unordered, projector, camera, width, height, ob, left), kAllParts);
  ObjectBounds small = o;
  small.weight = kMinPartTriangles - 1;
  EXPECT_EQ(partsInRegion(small, g, projector, camera, width, height, ob, left), kAllParts);
}
