// Tests for planFrame() (server/plan.h) on a Scene built in memory: a town of
// boxes on a grid under row groups. The regions tile the frame, every culled
// object with a footprint lands in exactly the regions it overlaps, and every
// point of an object in view is drawn by the client owning its pixel.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <numeric>
#include <vector>

#include "camera.h"
#include "cull.h"
#include "plan.h"
#include "server_test_util.h"

namespace dmmr {
namespace {

using test::Rng;

// rows x cols boxes of random size (up to 2 units) on a 4-unit grid in the
// x-z plane, one group per row under a root group; weights 1..10000.
Scene gridScene(Rng& rng, int rows, int cols) {
  Scene s;
  s.dir = "(in memory)";
  s.skeleton.push_back(SkeletonNode{NodeKind::Group, kNone, 0, kNone, Box3d{}, "root"});
  for (int r = 0; r < rows; ++r) {
    uint32_t group = uint32_t(s.skeleton.size());
    s.skeleton.push_back(SkeletonNode{NodeKind::Group, 0, 0, kNone, Box3d{}, "row"});
    for (int c = 0; c < cols; ++c) {
      ObjectBounds o;
      Vec3d centre{c * 4.0, rng.real(0, 3), -r * 4.0};
      Vec3d half{rng.real(0.1, 1), rng.real(0.1, 3), rng.real(0.1, 1)};
      o.box = Box3d{centre - half, centre + half};
      o.sphere = Sphere3d{centre, length(half)};
      o.use_box = true;
      o.weight = uint64_t(rng.integer(1, 10000));
      uint32_t index = uint32_t(s.objects.size());
      s.objects.push_back(o);
      s.skeleton.push_back(SkeletonNode{NodeKind::Object, group, uint32_t(s.skeleton.size()) + 1,
                                        index, o.box, "box"});
      s.skeleton[group].box.expand(o.box);
      s.manifest.triangles += o.weight;
    }
    s.skeleton[group].end = uint32_t(s.skeleton.size());
    s.skeleton[0].box.expand(s.skeleton[group].box);
  }
  s.skeleton[0].end = uint32_t(s.skeleton.size());
  s.manifest.objects = s.objects.size();
  s.manifest.geometries = 1;
  s.manifest.bounds = s.skeleton[0].box;
  return s;
}

// High above gridScene's middle, looking straight down: every object in view.
Camera topDownCamera() {
  Camera c;
  c.eye = {18, 200, -18};
  c.rotation = Quatd{-std::sqrt(0.5), 0, 0, std::sqrt(0.5)};  // -90 degrees about X
  c.fovy_deg = 40;
  return c;
}

// A camera somewhere above or around the grid, looking roughly at it.
Camera randomCamera(Rng& rng, const Scene& s) {
  Camera c;
  Box3d b = s.manifest.bounds;
  c.eye = rng.inBox(Box3d{b.lo - Vec3d{20, 0, 20}, b.hi + Vec3d{20, 40, 20}});
  c.rotation = rng.rotation();
  c.fovy_deg = rng.real(30, 90);
  c.aspect = 4.0 / 3.0;
  c.near = 0.05;
  return c;
}

TEST(PlanFrame, RegionsTileTheFrameAndHoldEveryCulledObjectWithAFootprint) {
  Rng rng(31);
  Scene scene = gridScene(rng, 30, 30);
  const int width = 640, height = 480;
  const Rect frame{0, 0, width, height};
  int planned = 0;
  for (int view = 0; view < 60; ++view) {
    Camera camera = randomCamera(rng, scene);
    int clients = rng.integer(1, 9);
    SCOPED_TRACE(::testing::Message()
                 << "view " << view << " " << camera << ", " << clients << " clients");
    FramePlan plan = planFrame(scene, camera, width, height, clients);
    ASSERT_TRUE(test::tilesFrame(plan.regions, frame, clients));

    std::vector<uint32_t> culled;
    CullStats cs;
    cullObjects(scene.skeleton, scene.objects, frustumPlanes(camera), &culled, &cs);
    EXPECT_EQ(plan.objects_in_frustum, culled.size());
    EXPECT_EQ(plan.triangles_in_frustum, cs.triangles);
    EXPECT_GE(plan.cull_ms, 0);
    EXPECT_GE(plan.divide_ms, 0);

    std::vector<Footprint> items;
    Footprint f;
    for (uint32_t i : culled)
      if (footprint(scene.objects[i], i, camera, width, height, &f)) items.push_back(f);
    EXPECT_TRUE(test::assignsObjects(items, plan.regions));
    for (const Footprint& it : items) {
      bool held = false;
      for (const Region& r : plan.regions)
        held = held || std::binary_search(r.objects.begin(), r.objects.end(), it.object);
      EXPECT_TRUE(held) << it << " is in no region";
    }
    uint64_t listed = 0;
    for (const Region& r : plan.regions) listed += r.objects.size();
    planned += listed > 0;
  }
  EXPECT_GT(planned, 10);  // enough views saw part of the town
}

TEST(PlanFrame, EveryPointInViewIsDrawnByTheClientOwningItsPixel) {
  Rng rng(32);
  Scene scene = gridScene(rng, 20, 20);
  const int width = 320, height = 240;
  int checked = 0;
  for (int view = 0; view < 40; ++view) {
    Camera camera = randomCamera(rng, scene);
    int clients = rng.integer(2, 8);
    FramePlan plan = planFrame(scene, camera, width, height, clients);
    for (uint32_t i = 0; i < scene.objects.size(); ++i)
      for (int k = 0; k < 10; ++k) {
        Vec3d p = rng.inBox(scene.objects[i].box);
        if (!test::inView(camera, p, width, height)) continue;
        test::Projected q = test::project(camera, p, width, height);
        int px = test::pixelOf(q.x, width), py = test::pixelOf(q.y, height);
        int owner = test::regionAt(plan.regions, px, py);
        ASSERT_GE(owner, 0) << "pixel (" << px << ", " << py << ") belongs to no region";
        const std::vector<uint32_t>& list = plan.regions[size_t(owner)].objects;
        EXPECT_TRUE(std::binary_search(list.begin(), list.end(), i))
            << "view " << view << ": object " << i << " shows at pixel (" << px << ", " << py
            << ") of region " << plan.regions[size_t(owner)] << " but is not listed there";
        ++checked;
      }
  }
  EXPECT_GT(checked, 1000);
}

TEST(PlanFrame, ACameraFacingAwayFromTheSceneGivesEmptyRegions) {
  Rng rng(33);
  Scene scene = gridScene(rng, 10, 10);
  Camera camera;  // in front of the grid (which lies towards -Z), looking along +Z
  camera.eye = {20, 2, 10};
  camera.rotation = Quatd{0, 1, 0, 0};  // half a turn about Y
  FramePlan plan = planFrame(scene, camera, 200, 100, 4);
  ASSERT_TRUE(test::tilesFrame(plan.regions, Rect{0, 0, 200, 100}, 4));
  EXPECT_EQ(plan.objects_in_frustum, 0u);
  EXPECT_EQ(plan.triangles_in_frustum, 0u);
  for (const Region& r : plan.regions) EXPECT_TRUE(r.objects.empty()) << r;
}

TEST(PlanFrame, OneClientGetsTheWholeFrameAndEveryVisibleObject) {
  Rng rng(34);
  Scene scene = gridScene(rng, 10, 10);
  Camera camera = topDownCamera();
  FramePlan plan = planFrame(scene, camera, 256, 256, 1);
  ASSERT_EQ(plan.regions.size(), 1u);
  EXPECT_EQ(plan.regions[0].rect, (Rect{0, 0, 256, 256}));
  std::vector<uint32_t> every(scene.objects.size());
  for (uint32_t i = 0; i < every.size(); ++i) every[i] = i;
  EXPECT_EQ(plan.regions[0].objects, every);
  EXPECT_EQ(plan.regions[0].weight, scene.manifest.triangles);
  EXPECT_EQ(plan.objects_in_frustum, scene.objects.size());
}

TEST(PlanFrame, ReportsTheCpuTimeOfItsThreadsAndThePlannedWeights) {
  // A plan on one thread (few objects: no projection threads) cannot use more
  // CPU than the wall time it took (0.2 ms of slack: the clocks are read a
  // few statements apart), and does use some. The planned weight of each
  // region is what the division balanced: its weight, no pixel term here.
  Rng rng(35);
  Scene scene = gridScene(rng, 30, 30);
  ASSERT_EQ(footprintThreads(scene.objects.size()), 1u);
  Camera camera;
  camera.eye = {60, 200, -60};
  camera.rotation = Quatd{-std::sqrt(0.5), 0, 0, std::sqrt(0.5)};
  camera.fovy_deg = 50;
  for (int clients : {1, 4, 16}) {
    FramePlan plan = planFrame(scene, camera, 512, 512, clients);
    EXPECT_GT(plan.plan_cpu_ms, 0) << clients;
    EXPECT_LE(plan.plan_cpu_ms, plan.cull_ms + plan.divide_ms + 0.2) << clients;
    ASSERT_EQ(plan.planned.size(), plan.regions.size());
    for (size_t k = 0; k < plan.regions.size(); ++k)
      EXPECT_EQ(plan.planned[k], double(plan.regions[k].weight)) << clients << " region " << k;
    EXPECT_TRUE(plan.grid.factor.empty());  // no cost grid unless enabled
  }
}

TEST(FramePlanner, TheCostGridIsUsedOnlyForTheFrameSizeItLearnt) {
  Rng rng(36);
  Scene scene = gridScene(rng, 10, 10);
  FramePlanner planner(scene);
  Camera camera = topDownCamera();
  planner.enableCostGrid(4, 4);
  FramePlan first = planner.plan(camera, 256, 256, 2);
  EXPECT_EQ(first.grid, CostGrid::uniform(4, 4));
  // Client 1 took 3x its planned share: its cells weigh more from now on.
  std::vector<RegionCost> fb;
  for (size_t k = 0; k < first.regions.size(); ++k)
    fb.push_back({first.regions[k].rect, first.planned[k], k == 0 ? 3.0 : 1.0});
  planner.reportRegionCosts(256, 256, fb, first.grid);
  FramePlan second = planner.plan(camera, 256, 256, 2);
  EXPECT_NE(second.grid, CostGrid::uniform(4, 4));
  EXPECT_EQ(second.grid, planner.costGrid());
  // Client 1's region shrinks by pixels toward the measured balance.
  EXPECT_LT(second.regions[0].rect.area(), first.regions[0].rect.area())
      << first.regions[0].rect << " then " << second.regions[0].rect;
  // Another frame size starts from a uniform grid.
  EXPECT_EQ(planner.plan(camera, 300, 200, 2).grid, CostGrid::uniform(4, 4));
}

TEST(FramePlanner, WeighsObjectsByWhatClientsDrewLately) {
  Rng rng(35);
  Scene scene = gridScene(rng, 10, 10);
  Camera camera = topDownCamera();
  FramePlanner planner(scene);
  planner.planningFrame(0);
  FramePlan before = planner.plan(camera, 256, 256, 2);
  uint64_t all = 0;
  for (const Region& r : before.regions) all += r.weight;
  EXPECT_GE(all, scene.manifest.triangles);  // no feedback yet: triangles
  // Clients report drawing only object 0: every other object now weighs at
  // most kHiddenWeight, object 0 its triangles.
  planner.reportDrawn(0, {0});
  planner.planningFrame(1);
  FramePlan after = planner.plan(camera, 256, 256, 2);
  uint64_t heavy = scene.objects[0].weight, total = 0;
  for (const Region& r : after.regions) total += r.weight;
  EXPECT_LE(total, 2 * (heavy + FramePlanner::kHiddenWeight * scene.objects.size()));
  EXPECT_LT(total, all);
  // Regions still hold every object they overlap: weights move split lines,
  // never membership.
  std::vector<uint32_t> held;
  for (const Region& r : after.regions) held.insert(held.end(), r.objects.begin(), r.objects.end());
  std::sort(held.begin(), held.end());
  held.erase(std::unique(held.begin(), held.end()), held.end());
  EXPECT_EQ(held.size(), scene.objects.size());
  // Feedback older than kSeenFrames no longer counts as drawn.
  planner.planningFrame(FramePlanner::kSeenFrames + 1);
  FramePlan stale = planner.plan(camera, 256, 256, 2);
  uint64_t staleTotal = 0;
  for (const Region& r : stale.regions) staleTotal += r.weight;
  EXPECT_LE(staleTotal, 2 * FramePlanner::kHiddenWeight * scene.objects.size());
}

// A drawn object's rasterised triangles (CostSample::raster): its triangles
// where they are fewer than its footprint's pixels, spread over the
// footprint; one a pixel (kRasterCap) where they are more.
// Several regions a client: the regions tile the frame, and each client's are
// spread over it: the division's first split halves the region count, and
// each client has half its regions on each side of it.
TEST(FramePlanner, SeveralRegionsAClientAreSpreadOverTheFrame) {
  Rng rng(40);
  Scene scene = gridScene(rng, 30, 30);
  const Rect frame{0, 0, 640, 480};
  FramePlanner planner(scene);
  for (int clients : {2, 3, 4})
    for (int per : {2, 4}) {
      SCOPED_TRACE(::testing::Message() << clients << " clients, " << per << " regions each");
      FramePlan plan = planner.plan(topDownCamera(), 640, 480, clients, per);
      ASSERT_TRUE(test::tilesFrame(plan.regions, frame, clients * per));
      ASSERT_EQ(plan.planned.size(), plan.regions.size());
      // The first half of the regions fill one side of the first split.
      const size_t half = plan.regions.size() / 2;
      int x0 = 640, y0 = 480, x1 = 0, y1 = 0;
      int64_t area = 0;
      for (size_t j = 0; j < half; ++j) {
        const Rect& r = plan.regions[j].rect;
        x0 = std::min(x0, r.x), y0 = std::min(y0, r.y);
        x1 = std::max(x1, r.x + r.w), y1 = std::max(y1, r.y + r.h);
        area += r.area();
      }
      ASSERT_EQ(int64_t(x1 - x0) * (y1 - y0), area);
      const bool whole_width = x0 == 0 && x1 == 640, whole_height = y0 == 0 && y1 == 480;
      ASSERT_TRUE(whole_width || whole_height);
      ASSERT_LT(area, frame.area());
      for (int k = 0; k < clients; ++k) {
        int inside = 0;
        for (size_t j = 0; j < plan.regions.size(); ++j) {
          if (regionClient(j, clients) != k) continue;
          const Rect& r = plan.regions[j].rect;
          inside += r.x >= x0 && r.x + r.w <= x1 && r.y >= y0 && r.y + r.h <= y1;
        }
        EXPECT_EQ(inside, per / 2) << "client " << k;
      }
    }
}

// --pool-share: the clients' regions and the pool's parts tile the frame
// together, and each holds every culled object whose footprint meets it, so
// that frames stay exact whichever client draws a part.
TEST(FramePlanner, APoolsPartsAndTheRegionsTileTheFrameAndHoldEveryObjectTheyMeet) {
  Rng rng(44);
  Scene scene = gridScene(rng, 30, 30);
  const int width = 640, height = 480;
  const Rect frame{0, 0, width, height};
  FramePlanner planner(scene);
  int pooled = 0;
  for (int view = 0; view < 60; ++view) {
    Camera camera = randomCamera(rng, scene);
    const int clients = rng.integer(1, 6), parts = rng.integer(1, 9);
    const double share = rng.real(0.05, 0.9);
    SCOPED_TRACE(::testing::Message() << "view " << view << " " << camera << ", " << clients
                                      << " clients, pool " << share << " in " << parts);
    FramePlan plan = planner.plan(camera, width, height, clients, 1, share, parts);
    ASSERT_EQ(plan.regions.size(), size_t(clients));
    ASSERT_EQ(plan.pool.size(), size_t(parts));
    ASSERT_EQ(plan.planned.size(), plan.regions.size());
    std::vector<Region> all = plan.regions;
    all.insert(all.end(), plan.pool.begin(), plan.pool.end());
    ASSERT_TRUE(test::tilesFrame(all, frame, clients + parts));
    std::vector<uint32_t> culled;
    CullStats cs;
    cullObjects(scene.skeleton, scene.objects, frustumPlanes(camera), &culled, &cs);
    std::vector<Footprint> items;
    Footprint f;
    for (uint32_t i : culled)
      if (footprint(scene.objects[i], i, camera, width, height, &f)) items.push_back(f);
    EXPECT_TRUE(test::assignsObjects(items, all));
    for (const Region& r : plan.pool) pooled += !r.objects.empty();
  }
  EXPECT_GT(pooled, 30);  // the pools held work, not only empty rectangles
}

// The pool's share of the frame's weight follows pool_share; without a pool
// the plan is the plain division.
TEST(FramePlanner, ThePoolTakesItsShareOfTheFramesWeight) {
  Rng rng(45);
  Scene scene = gridScene(rng, 30, 30);
  FramePlanner planner(scene);
  const Camera camera = topDownCamera();
  auto poolFraction = [&](double share) {
    FramePlan plan = planner.plan(camera, 640, 480, 3, 1, share, 4);
    double pool = 0, regions = 0;
    for (const Region& r : plan.pool) pool += double(r.weight);
    for (const Region& r : plan.regions) regions += double(r.weight);
    return pool / (pool + regions);
  };
  double previous = 0;
  for (double share : {0.1, 0.25, 0.5}) {
    double got = poolFraction(share);
    // Objects straddling a cut count on both sides: the fraction is near the
    // share, not equal to it.
    EXPECT_NEAR(got, share, 0.1) << "share " << share;
    EXPECT_GT(got, previous) << "share " << share;
    previous = got;
  }
  FramePlan plain = planner.plan(camera, 640, 480, 3);
  EXPECT_TRUE(plain.pool.empty());
  FramePlan unpooled = planner.plan(camera, 640, 480, 3, 1, 0, 4);
  EXPECT_TRUE(unpooled.pool.empty());
  EXPECT_EQ(unpooled.regions, plain.regions);
}

TEST(FramePlanner, RasterCountsAtMostOneTriangleAFootprintPixel) {
  Rng rng(39);
  Scene scene = gridScene(rng, 4, 4);
  Camera camera = topDownCamera();
  const Rect frame{0, 0, 256, 256}, left{0, 0, 128, 256};
  for (uint64_t triangles : {uint64_t(7), uint64_t(1) << 40}) {
    for (ObjectBounds& o : scene.objects) o.weight = triangles;
    FramePlanner planner(scene);
    for (uint32_t o = 0; o < scene.objects.size(); ++o) {
      DrawnCover whole = planner.coverOf(camera, 256, 256, frame, {o});
      double area = whole.fill;
      ASSERT_GT(area, 0) << o;
      double expected = triangles > area ? area : double(triangles);
      EXPECT_NEAR(whole.raster, expected, 1e-9 * expected) << o;
      // A region gets the part of the footprint it holds.
      DrawnCover part = planner.coverOf(camera, 256, 256, left, {o});
      EXPECT_NEAR(part.raster, expected * part.fill / area, 1e-9 * expected) << o;
    }
  }
}

TEST(FramePlanner, ForecastsCountWhatTheWeightsCountAsDrawnLately) {
  Rng rng(36);
  Scene scene = gridScene(rng, 10, 10);
  Camera camera = topDownCamera();
  FramePlanner planner(scene);
  planner.planningFrame(0);
  FramePlan first = planner.plan(camera, 256, 256, 3);
  for (const Region& r : first.regions)  // no feedback yet: nothing drawn lately
    EXPECT_EQ(planner.forecast(camera, 256, 256, r), (RegionForecast{r.objects.size(), 0, 0, 0.0}));
  const std::vector<uint32_t> drawn = {0, 5, 42, 99};
  planner.reportDrawn(0, drawn);
  planner.planningFrame(1);
  FramePlan plan = planner.plan(camera, 256, 256, 3);
  uint64_t lately_total = 0;
  for (const Region& r : plan.regions) {
    RegionForecast expected{r.objects.size(), 0, 0, 0.0};
    std::vector<uint32_t> mine;
    for (uint32_t o : drawn)
      if (std::binary_search(r.objects.begin(), r.objects.end(), o)) {
        mine.push_back(o);
        ++expected.drawn_lately;
        expected.triangles_lately += scene.objects[o].weight;
      }
    expected.fill_lately = planner.coverOf(camera, 256, 256, r.rect, mine).fill;
    EXPECT_EQ(planner.forecast(camera, 256, 256, r), expected) << r;
    EXPECT_EQ(mine.empty(), expected.fill_lately == 0.0) << r;  // each drawn object covers pixels
    lately_total += expected.drawn_lately;
  }
  EXPECT_GE(lately_total, drawn.size());  // every drawn object is in some region
  // Older than kSeenFrames: no longer drawn lately, as for the weights.
  planner.planningFrame(FramePlanner::kSeenFrames + 1);
  for (const Region& r : plan.regions)
    EXPECT_EQ(planner.forecast(camera, 256, 256, r).drawn_lately, 0u) << r;
}

// The catching-up tests' cost model, and client `client`'s sample of `base`
// work with everything but the region's pixels times `more`, timed by it.
const CostModel kTruth{0.02, 0.0005, 0.003, 0.00001, 0.000004, 0, true};
CostSample timedSample(int client, double more, CostSample base) {
  base.client = client;
  base.drawn *= more;
  base.triangles *= more;
  base.tested *= more;
  base.fill *= more;
  base.ms = predictMs(kTruth, base);
  return base;
}

// Reports frames 0..frames-1 of 3 clients, client k's sample of frame f
// being sample(f, k), in that order.
void reportFrames(FramePlanner& planner, int frames,
                  const std::function<CostSample(int, int)>& sample) {
  for (int frame = 0; frame < frames; ++frame) {
    std::vector<CostSample> samples;
    for (int k = 0; k < 3; ++k) samples.push_back(sample(frame, k));
    planner.reportCosts(uint32_t(frame), samples);
  }
}

// Catching up: a client whose region held more work, every frame, than the
// others' (its time explained by the fitted model, so its speed stays 1) runs
// into debt and gets a smaller share of the next frames; off, shares are the
// speeds alone.
TEST(FramePlanner, AClientBehindTheOthersGetsASmallerShareUntilItCatchesUp) {
  Rng rng(37);
  Scene scene = gridScene(rng, 4, 4);
  FramePlanner planner(scene);
  reportFrames(planner, 12, [&](int, int k) {
    CostSample s;
    s.drawn = rng.real(50, 150);
    s.triangles = rng.real(1e4, 5e4);
    s.tested = rng.real(200, 900);
    s.pixels = rng.real(1e5, 3e5);
    s.fill = rng.real(1e5, 6e5);
    return timedSample(k, k == 0 ? 2.0 : 1.0, s);  // client 0: twice the work
  });
  ASSERT_TRUE(planner.costModel().fitted);
  EXPECT_EQ(planner.speeds(), (std::vector<double>{1, 1, 1}));  // the model explains the times
  std::vector<double> on = planner.shares(3);
  ASSERT_EQ(on.size(), 3u);
  EXPECT_LT(on[0], 0.9);
  EXPECT_GT(on[1], 1.0);
  EXPECT_GT(on[2], 1.0);
  EXPECT_GE(on[0], 0.5);  // never below half
  planner.setCatchUp(false);
  EXPECT_EQ(planner.shares(3), planner.speeds());
  EXPECT_TRUE(planner.shares(4).empty());  // fitted for 3 clients only
}

// With several regions a client, every region of a client is planned at
// that client's share: a client behind the others gets less in all.
TEST(FramePlanner, SeveralRegionsAClientTakeTheirClientsShare) {
  Rng rng(41);
  Scene scene = gridScene(rng, 30, 30);
  FramePlanner planner(scene);
  reportFrames(planner, 12, [&](int, int k) {
    CostSample s;
    s.drawn = rng.real(50, 150);
    s.triangles = rng.real(1e4, 5e4);
    s.tested = rng.real(200, 900);
    s.pixels = rng.real(1e5, 3e5);
    s.fill = rng.real(1e5, 6e5);
    return timedSample(k, k == 0 ? 2.0 : 1.0, s);  // client 0: twice the work
  });
  ASSERT_LT(planner.shares(3)[0], 0.9);
  // The largest of client 0's regions' planned weights, over the mean region's.
  auto largest = [&] {
    FramePlan plan = planner.plan(topDownCamera(), 640, 480, 3, 2);
    double most = 0, all = 0;
    for (size_t j = 0; j < plan.regions.size(); ++j) {
      all += plan.planned[j];
      if (regionClient(j, 3) == 0) most = std::max(most, plan.planned[j]);
    }
    return most * double(plan.regions.size()) / all;
  };
  const double behind = largest();
  planner.setCatchUp(false);  // equal shares
  const double even = largest();
  EXPECT_NEAR(even, 1.0, 0.15);
  EXPECT_LT(behind, even - 0.1);
}

// Frames planned but not yet reported already pay part of a debt: the next
// frame's share is cut less for each of them, and once they are reported
// (with no new times) the measured debt alone steers again.
TEST(FramePlanner, FramesInFlightPayPartOfTheDebt) {
  Rng rng(38);
  Scene scene = gridScene(rng, 4, 4);
  FramePlanner planner(scene);
  reportFrames(planner, 12, [](int frame, int k) {
    CostSample s;
    s.drawn = 50 + 10 * frame;
    s.triangles = 1e4 + 3e3 * frame;
    s.tested = 200 + 50 * (frame % 5);
    s.pixels = 1e5 + 1e4 * (frame % 3);
    s.fill = 1e5 + 4e4 * (frame % 4);
    // The same work for all, but client 0 has a quarter more in the last frame.
    return timedSample(k, k == 0 && frame == 11 ? 1.25 : 1.0, s);
  });
  ASSERT_TRUE(planner.costModel().fitted);
  planner.planningFrame(12);
  std::vector<double> measured = planner.shares(3);
  ASSERT_EQ(measured.size(), 3u);
  ASSERT_GT(measured[0], 0.5);  // not clamped: the test below would be empty
  ASSERT_LT(measured[0], 1.0);
  planner.plan(topDownCamera(), 256, 256, 3);
  planner.planningFrame(13);
  std::vector<double> one = planner.shares(3);
  EXPECT_GT(one[0], measured[0]);
  EXPECT_LT(one[1], measured[1]);
  planner.plan(topDownCamera(), 256, 256, 3);
  planner.planningFrame(14);
  EXPECT_GT(planner.shares(3)[0], one[0]);
  planner.reportCosts(13, {});
  EXPECT_EQ(planner.shares(3), measured);
}

// The objects in `camera`'s frustum, as the planner culls them.
std::vector<uint32_t> inFrustum(const Scene& scene, const Camera& camera) {
  std::vector<uint32_t> visible;
  CullStats cs;
  cullObjects(scene.skeleton, scene.objects, frustumPlanes(camera), &visible, &cs);
  return visible;
}

// Low over one corner of gridScene, looking down: a few objects in view.
Camera cornerCamera() {
  Camera c = topDownCamera();
  c.eye = {0, 12, 0};
  c.fovy_deg = 30;
  return c;
}

// Plans frames 0..frames-1 with `camera`, 2 clients, nothing reported.
void planFramesOver(FramePlanner& planner, const Camera& camera, uint32_t frames) {
  for (uint32_t f = 0; f < frames; ++f) {
    planner.planningFrame(f);
    planner.plan(camera, 256, 256, 2);
  }
}

// Of the objects a forecast counts as drawn lately in some region, how many
// (each counted once).
size_t expectedDrawn(const FramePlanner& planner, const Camera& camera, const FramePlan& plan) {
  std::vector<uint32_t> objects;
  for (const Region& r : plan.regions)
    for (uint32_t o : r.objects) {
      Region one{r.rect, {o}, 0};
      if (planner.forecast(camera, 256, 256, one).drawn_lately == 1) objects.push_back(o);
    }
  std::sort(objects.begin(), objects.end());
  return size_t(std::unique(objects.begin(), objects.end()) - objects.begin());
}

// --unseen drawn: an object that came into view after the latest frame the
// clients reported on has not been tested by anyone, so it weighs as drawn;
// one that was in view in a reported frame and not drawn is hidden. Off, both
// weigh as hidden.
TEST(FramePlanner, ObjectsComingIntoViewWeighAsDrawnUntilAClientReportsOnThem) {
  Rng rng(37);
  Scene scene = gridScene(rng, 10, 10);
  const Camera corner = cornerCamera();
  const Camera all = topDownCamera();
  const std::vector<uint32_t> seen = inFrustum(scene, corner), later = inFrustum(scene, all);
  ASSERT_GT(seen.size(), 0u);
  ASSERT_GT(later.size(), seen.size() + 20);
  for (bool prior : {false, true}) {
    FramePlanner planner(scene);
    planner.setUnseen(prior ? FramePlanner::Unseen::Drawn : FramePlanner::Unseen::Hidden);
    planFramesOver(planner, corner, 3);  // three frames over the corner, frame 0 reported
    planner.reportDrawn(0, {});          // every object in view at frame 0 was hidden
    planner.planningFrame(3);            // the camera pulls back: the whole grid in view
    FramePlan wide = planner.plan(all, 256, 256, 2);
    size_t in_regions = 0;  // of the objects new in view, those in some region
    for (uint32_t o : later) {
      if (std::binary_search(seen.begin(), seen.end(), o)) continue;
      for (const Region& r : wide.regions)
        if (std::binary_search(r.objects.begin(), r.objects.end(), o)) {
          ++in_regions;
          break;
        }
    }
    EXPECT_EQ(expectedDrawn(planner, all, wide), prior ? in_regions : 0u) << prior;
    // Frames 1 and 2 reported: the corner was in view then too, so it is
    // still known hidden; the rest is still untested.
    planner.reportDrawn(2, {});
    planner.planningFrame(4);
    EXPECT_EQ(expectedDrawn(planner, all, planner.plan(all, 256, 256, 2)), prior ? in_regions : 0u);
    // Frame 3 reported, nothing drawn: every object has now been tested.
    planner.reportDrawn(3, {});
    planner.planningFrame(5);
    EXPECT_EQ(expectedDrawn(planner, all, planner.plan(all, 256, 256, 2)), 0u) << prior;
    // Out of view and back: untested again until reported.
    planner.planningFrame(6);
    planner.plan(corner, 256, 256, 2);
    planner.planningFrame(7);
    EXPECT_EQ(expectedDrawn(planner, all, planner.plan(all, 256, 256, 2)), prior ? in_regions : 0u);
  }
}

// --unseen learnt: the fraction of the objects that came into view which
// were drawn in that first frame, once a later frame is reported.
TEST(FramePlanner, LearnsTheFractionOfObjectsComingIntoViewThatAreDrawn) {
  Rng rng(38);
  Scene scene = gridScene(rng, 10, 10);
  const Camera corner = cornerCamera();
  const Camera all = topDownCamera();
  const std::vector<uint32_t> seen = inFrustum(scene, corner), later = inFrustum(scene, all);
  std::vector<uint32_t> fresh, drawn;  // new in view at frame 3; every third of them drawn
  for (uint32_t o : later)
    if (!std::binary_search(seen.begin(), seen.end(), o)) fresh.push_back(o);
  for (size_t k = 0; k < fresh.size(); k += 3) drawn.push_back(fresh[k]);
  ASSERT_GT(fresh.size(), 20u);
  FramePlanner planner(scene);
  planner.setUnseen(FramePlanner::Unseen::Learnt);
  planFramesOver(planner, corner, 3);
  planner.reportDrawn(0, {});
  planner.planningFrame(3);
  planner.plan(all, 256, 256, 2);
  EXPECT_EQ(planner.unseenDrawnFraction(), 1.0);  // nothing resolved yet: frame 0 is the latest
  planner.reportDrawn(3, drawn);
  planner.reportDrawn(4, {});
  planner.planningFrame(5);
  planner.plan(all, 256, 256, 2);
  // The corner's objects (in view from frame 0, not drawn) and the fresh ones.
  const double p = double(drawn.size()) / double(seen.size() + fresh.size());
  EXPECT_DOUBLE_EQ(planner.unseenDrawnFraction(), p);
  planner.planningFrame(6);  // nothing new resolved: the counts decay alike
  planner.plan(all, 256, 256, 2);
  EXPECT_DOUBLE_EQ(planner.unseenDrawnFraction(), p);
  // An object coming into view now weighs that fraction of its triangles
  // (visible weights), not all of them and not kHiddenWeight: out of view
  // and back, the fresh objects are untested again.
  planner.planningFrame(7);
  planner.plan(corner, 256, 256, 2);
  planner.planningFrame(8);
  FramePlan back = planner.plan(all, 256, 256, 1);
  uint64_t expected = 0;
  for (uint32_t o : back.regions[0].objects) {
    uint64_t tris = scene.objects[o].weight;
    bool fresh_o = std::binary_search(fresh.begin(), fresh.end(), o);
    bool drawn_o = std::binary_search(drawn.begin(), drawn.end(), o);
    expected += drawn_o   ? tris
                : fresh_o ? std::max<uint64_t>(1, uint64_t(std::llround(p * double(tris))))
                          : 1;  // the corner: in view since frame 0, hidden
  }
  EXPECT_EQ(back.regions[0].weight, expected);
}

TEST(FramePlanner, HintsAreTheObjectsDrawnInTheLatestReportedFrames) {
  Rng rng(36);
  Scene scene = gridScene(rng, 4, 4);
  FramePlanner planner(scene);
  std::vector<uint32_t> all(scene.objects.size());
  std::iota(all.begin(), all.end(), 0u);
  EXPECT_TRUE(planner.drawnLately(all).empty());  // nothing reported yet
  planner.reportDrawn(3, {1, 4});
  planner.reportDrawn(4, {2});
  EXPECT_EQ(planner.drawnLately(all), (std::vector<uint32_t>{1, 2, 4}));
  EXPECT_EQ(planner.drawnLately({0, 2, 3}), (std::vector<uint32_t>{2}));  // of the list only
  planner.reportDrawn(3 + FramePlanner::kHintFrames, {7});                // frame 3 is now too old
  EXPECT_EQ(planner.drawnLately(all), (std::vector<uint32_t>{2, 7}));
}

}  // namespace
}  // namespace dmmr
