// Tests for divideFrame (server/divide.h): the regions tile the frame, each
// region holds exactly the objects whose footprints overlap it, and the
// weights balance as the paper's Algorithm 1 promises. Random inputs come from
// fixed seeds.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <vector>

#include "divide.h"
#include "server_test_util.h"

namespace dmmr {
namespace {

using test::Rng;

Footprint fp(uint32_t object, int x0, int x1, int y0, int y1, uint64_t weight) {
  Footprint f;
  f.object = object;
  f.x0 = x0;
  f.x1 = x1;
  f.y0 = y0;
  f.y1 = y1;
  f.weight = weight;
  return f;
}

// n footprints of 1..max_size pixels a side placed anywhere in the frame grown
// by `spill` pixels on every side (so some cross its edges or miss it), with
// weights 0..1000 and distinct object indices in shuffled order.
std::vector<Footprint> randomFootprints(Rng& rng, Rect frame, int n, int max_size, int spill) {
  std::vector<uint32_t> ids(static_cast<size_t>(n));
  std::iota(ids.begin(), ids.end(), 0u);
  rng.shuffle(ids);
  std::vector<Footprint> out;
  for (int i = 0; i < n; ++i) {
    int w = rng.integer(1, max_size), h = rng.integer(1, max_size);
    int x = rng.integer(frame.x - spill - w, frame.x1() + spill);
    int y = rng.integer(frame.y - spill - h, frame.y1() + spill);
    out.push_back(fp(ids[size_t(i)], x, x + w, y, y + h, uint64_t(rng.integer(0, 1000))));
  }
  return out;
}

uint64_t maxWeight(const std::vector<Region>& regions) {
  uint64_t m = 0;
  for (const Region& r : regions) m = std::max(m, r.weight);
  return m;
}

const std::vector<Rect> kFrames = {{0, 0, 1, 1},       {0, 0, 1, 7},      {0, 0, 7, 1},
                                   {0, 0, 3, 5},       {0, 0, 2, 2},      {0, 0, 3, 3},
                                   {0, 0, 1, 1000},    {0, 0, 1000, 1},   {0, 0, 203, 157},
                                   {0, 0, 1024, 1024}, {17, -5, 203, 157}};
const std::vector<int> kClients = {1, 2, 3, 4, 5, 6, 7, 8, 9, 16, 17};

// ---- tiling ---------------------------------------------------------------

TEST(DivideFrame, RegionsTileTheFrameForEveryClientCountAndFrameShape) {
  Rng rng(1);
  for (Rect frame : kFrames)
    for (int clients : kClients) {
      SCOPED_TRACE(::testing::Message() << frame << " with " << clients << " clients");
      std::vector<Footprint> none;
      EXPECT_TRUE(test::tilesFrame(divideFrame(none, frame, clients), frame, clients));
      int spread = std::max(frame.w, frame.h);
      std::vector<Footprint> items =
          randomFootprints(rng, frame, 300, std::max(1, spread / 8), std::max(2, spread / 10));
      std::vector<Region> regions = divideFrame(items, frame, clients);
      EXPECT_TRUE(test::tilesFrame(regions, frame, clients));
      EXPECT_TRUE(test::assignsObjects(items, regions));
    }
}

TEST(DivideFrame, ExtraClientsBeyondThePixelCountGetEmptyRegionsWithNoObjects) {
  Rng rng(2);
  for (Rect frame : {Rect{0, 0, 1, 1}, Rect{0, 0, 1, 7}, Rect{0, 0, 7, 1}, Rect{0, 0, 3, 5}})
    for (int clients : {8, 9, 16, 17}) {
      SCOPED_TRACE(::testing::Message() << frame << " with " << clients << " clients");
      std::vector<Footprint> items = randomFootprints(rng, frame, 50, 3, 1);
      std::vector<Region> regions = divideFrame(items, frame, clients);
      ASSERT_TRUE(test::tilesFrame(regions, frame, clients));  // empty ones hold nothing
      EXPECT_TRUE(test::assignsObjects(items, regions));
      EXPECT_GE(clients - test::nonEmpty(regions), clients - frame.area());
    }
}

TEST(DivideFrame, AOnePixelLineGivesEveryClientPixelsUpToItsLength) {
  for (int length = 1; length <= 20; ++length)
    for (int clients : kClients)
      for (Rect frame : {Rect{0, 0, 1, length}, Rect{0, 0, length, 1}}) {
        SCOPED_TRACE(::testing::Message() << frame << " with " << clients << " clients");
        std::vector<Region> regions = divideFrame({}, frame, clients);
        ASSERT_TRUE(test::tilesFrame(regions, frame, clients));
        EXPECT_EQ(test::nonEmpty(regions), std::min(length, clients));
      }
}

// The count of clients is halved at every split, so a frame with barely more
// pixels than clients can leave a client without pixels (2x3 for 6 clients
// splits 3:3 rows into 1 and 2 rows, 2 and 4 pixels). With twice as many
// pixels as clients there is always room.
TEST(DivideFrame, EveryClientGetsPixelsWhenTheFrameHasTwiceAsManyPixelsAsClients) {
  for (int w = 1; w <= 24; ++w)
    for (int h = 1; h <= 24; ++h)
      for (int clients = 1; clients <= 17; ++clients) {
        if (w * h < 2 * clients) continue;
        Rect frame{0, 0, w, h};
        std::vector<Region> regions = divideFrame({}, frame, clients);
        ASSERT_TRUE(test::tilesFrame(regions, frame, clients)) << frame << " " << clients;
        EXPECT_EQ(test::nonEmpty(regions), clients) << frame << " with " << clients << " clients";
      }
}

// With the weight piled into a corner the best balanced line would leave a
// side fewer pixels than clients; the split keeps a pixel per client on each
// side instead. That is not always enough for the halving splits below it
// when a side of the frame is under 4 pixels (3x47 for 16 clients: a 3x3
// corner for 8 clients cannot be cut 4:4), so those frames are left out.
TEST(DivideFrame, EveryClientGetsPixelsWhenTheWeightSitsInACornerOfAFrameOfFourPixelsOrMore) {
  Rng rng(9);
  for (int trial = 0; trial < 3000; ++trial) {
    Rect frame{0, 0, rng.integer(4, 40), rng.integer(4, 40)};
    int clients = rng.integer(2, 17);
    if (frame.area() < 2 * clients) continue;
    std::vector<Footprint> items;
    for (uint32_t i = 0; i < 20; ++i) {
      int x = rng.integer(0, std::min(2, frame.w - 1)),
          y = rng.integer(0, std::min(2, frame.h - 1));
      items.push_back(fp(i, x, x + 1, y, y + 1, uint64_t(rng.integer(1, 1000))));
    }
    items.push_back(fp(20, 0, frame.w, 0, frame.h, 1));
    std::vector<Region> regions = divideFrame(items, frame, clients);
    ASSERT_TRUE(test::tilesFrame(regions, frame, clients)) << frame << " " << clients;
    ASSERT_TRUE(test::assignsObjects(items, regions)) << frame << " " << clients;
    EXPECT_EQ(test::nonEmpty(regions), clients) << frame << " with " << clients << " clients";
  }
}

TEST(DivideFrame, NoClientsGetNoRegions) {
  std::vector<Footprint> items = {fp(0, 0, 10, 0, 10, 5)};
  EXPECT_TRUE(divideFrame(items, Rect{0, 0, 64, 64}, 0).empty());
  EXPECT_TRUE(divideFrame(items, Rect{0, 0, 64, 64}, -3).empty());
}

// ---- object assignment ----------------------------------------------------

TEST(DivideFrame, AFootprintLandsInExactlyTheRegionsItOverlaps) {
  Rng rng(3);
  for (int trial = 0; trial < 200; ++trial) {
    Rect frame{rng.integer(-50, 50), rng.integer(-50, 50), rng.integer(1, 400),
               rng.integer(1, 400)};
    int clients = rng.integer(1, 17);
    int n = rng.integer(0, 400);
    int spread = std::max(frame.w, frame.h);
    std::vector<Footprint> items =
        randomFootprints(rng, frame, n, rng.integer(1, spread), rng.integer(0, spread));
    SCOPED_TRACE(::testing::Message() << "trial " << trial << ": " << frame << ", " << n
                                      << " footprints, " << clients << " clients");
    std::vector<Region> regions = divideFrame(items, frame, clients);
    ASSERT_TRUE(test::tilesFrame(regions, frame, clients));
    ASSERT_TRUE(test::assignsObjects(items, regions));
    for (const Footprint& f : items) {
      int holders = 0;
      for (const Region& r : regions)
        holders += std::binary_search(r.objects.begin(), r.objects.end(), f.object);
      if (test::overlaps(f, frame)) {
        EXPECT_GE(holders, 1) << f << " overlaps the frame but no region holds it";
      } else {
        EXPECT_EQ(holders, 0) << f << " misses the frame but a region holds it";
      }
    }
  }
}

TEST(DivideFrame, AFootprintWithNoPixelsLandsNowhere) {
  std::vector<Footprint> items = {fp(0, 10, 10, 5, 20, 7), fp(1, 10, 20, 30, 30, 7),
                                  fp(2, 40, 50, 40, 50, 1)};
  for (int clients : kClients) {
    std::vector<Region> regions = divideFrame(items, Rect{0, 0, 64, 64}, clients);
    EXPECT_TRUE(test::assignsObjects(items, regions)) << clients << " clients";
  }
}

// ---- balance on hand-made cases --------------------------------------------

TEST(DivideFrame, TwoEqualObjectsFarApartGoToTwoClientsSplitAtTheMiddle) {
  std::vector<Footprint> items = {fp(0, 100, 120, 500, 520, 50), fp(1, 900, 920, 500, 520, 50)};
  std::vector<Region> regions = divideFrame(items, Rect{0, 0, 1024, 1024}, 2);
  // Every line between the objects balances them; the tie goes to the middle.
  EXPECT_EQ(regions[0], (Region{Rect{0, 0, 512, 1024}, {0}, 50}));
  EXPECT_EQ(regions[1], (Region{Rect{512, 0, 512, 1024}, {1}, 50}));
}

TEST(DivideFrame, NoObjectsSplitTheFrameByArea) {
  std::vector<Region> two = divideFrame({}, Rect{0, 0, 1024, 768}, 2);
  EXPECT_EQ(two[0], (Region{Rect{0, 0, 512, 768}, {}, 0}));
  EXPECT_EQ(two[1], (Region{Rect{512, 0, 512, 768}, {}, 0}));
  std::vector<Region> four = divideFrame({}, Rect{0, 0, 1024, 1024}, 4);
  EXPECT_EQ(four[0].rect, (Rect{0, 0, 512, 512}));
  EXPECT_EQ(four[1].rect, (Rect{0, 512, 512, 512}));
  EXPECT_EQ(four[2].rect, (Rect{512, 0, 512, 512}));
  EXPECT_EQ(four[3].rect, (Rect{512, 512, 512, 512}));
  std::vector<Region> three = divideFrame({}, Rect{0, 0, 900, 300}, 3);
  EXPECT_EQ(three[0].rect, (Rect{0, 0, 300, 300}));  // one client of three: a third
}

TEST(DivideFrame, FourEqualClustersInTheQuadrantsGiveOneClusterToEachOfFourClients) {
  Rng rng(4);
  const int centres[4][2] = {{200, 200}, {800, 250}, {250, 800}, {760, 780}};
  std::vector<Footprint> items;
  for (int c = 0; c < 4; ++c)
    for (int k = 0; k < 25; ++k) {
      int x = centres[c][0] + rng.integer(-60, 60), y = centres[c][1] + rng.integer(-60, 60);
      items.push_back(
          fp(uint32_t(c * 25 + k), x, x + rng.integer(1, 20), y, y + rng.integer(1, 20), 10));
    }
  std::vector<Region> regions = divideFrame(items, Rect{0, 0, 1024, 1024}, 4);
  ASSERT_TRUE(test::tilesFrame(regions, Rect{0, 0, 1024, 1024}, 4));
  ASSERT_TRUE(test::assignsObjects(items, regions));
  std::vector<int> clientOfCluster;
  for (int c = 0; c < 4; ++c) {
    std::vector<uint32_t> cluster(25);
    std::iota(cluster.begin(), cluster.end(), uint32_t(c * 25));
    int r = test::regionAt(regions, centres[c][0], centres[c][1]);
    ASSERT_GE(r, 0);
    EXPECT_EQ(regions[size_t(r)], (Region{regions[size_t(r)].rect, cluster, 250}))
        << "cluster " << c;
    clientOfCluster.push_back(r);
  }
  std::sort(clientOfCluster.begin(), clientOfCluster.end());
  EXPECT_EQ(clientOfCluster, (std::vector<int>{0, 1, 2, 3}));
}

// One object as heavy as the 1000 light ones together, alone at the left.
std::vector<Footprint> heavyAndLight() {
  Rng rng(5);
  std::vector<Footprint> items = {fp(0, 10, 30, 400, 600, 1000)};
  for (uint32_t i = 1; i <= 1000; ++i) {
    int x = rng.integer(100, 1020), y = rng.integer(0, 1020);
    items.push_back(fp(i, x, x + 4, y, y + 4, 1));
  }
  return items;
}

TEST(DivideFrame, AHeavyObjectGetsOneOfTwoClientsAndTheLightOnesTheOther) {
  std::vector<Footprint> items = heavyAndLight();
  std::vector<uint32_t> light(1000);
  std::iota(light.begin(), light.end(), 1u);
  std::vector<Region> two = divideFrame(items, Rect{0, 0, 1024, 1024}, 2);
  ASSERT_TRUE(test::tilesFrame(two, Rect{0, 0, 1024, 1024}, 2));
  EXPECT_EQ(two[0].objects, (std::vector<uint32_t>{0}));
  EXPECT_EQ(two[0].weight, 1000u);
  EXPECT_EQ(two[1].objects, light);
  EXPECT_EQ(two[1].weight, 1000u);
}

// Three clients: the one-client side should take just the heavy object
// (load 1000) and the light ones split over the other two (about 500 each).
// Disabled: the documented cost |l - l*| + |r - r*| + min(nl,nr) |l/nl - r/nr|
// prefers a line through the heavy object (l = 1000, r = 2000: cost 333 + 667
// + 0 = 1000) to the line beside it (l = r = 1000: 333 + 333 + 500 = 1166),
// because the duplicate raises r towards its target and evens the per-client
// averages. The next split cuts through it again, so all three clients draw
// it (loads 1000, 1502, 1500). See the report; enable once the cost counts
// duplicated weight for uneven splits.
TEST(DivideFrame, AHeavyObjectIsNotDuplicatedToEvenOutAnUnevenSplit) {
  std::vector<Footprint> items = heavyAndLight();
  std::vector<Region> three = divideFrame(items, Rect{0, 0, 1024, 1024}, 3);
  ASSERT_TRUE(test::tilesFrame(three, Rect{0, 0, 1024, 1024}, 3));
  ASSERT_TRUE(test::assignsObjects(items, three));
  EXPECT_EQ(three[0].objects, (std::vector<uint32_t>{0}));
  EXPECT_NEAR(double(three[1].weight), 500.0, 25.0);
  EXPECT_NEAR(double(three[2].weight), 500.0, 25.0);
}

TEST(DivideFrame, WithThreeClientsTheOneClientSideGetsAThirdOfTheWeight) {
  Rng rng(6);
  std::vector<Footprint> items;
  uint64_t total = 0;
  for (uint32_t i = 0; i < 3000; ++i) {
    int x = rng.integer(0, 1021), y = rng.integer(0, 1021);
    uint64_t w = uint64_t(rng.integer(1, 100));
    items.push_back(fp(i, x, x + 2, y, y + 2, w));
    total += w;
  }
  std::vector<Region> regions = divideFrame(items, Rect{0, 0, 1024, 1024}, 3);
  ASSERT_TRUE(test::tilesFrame(regions, Rect{0, 0, 1024, 1024}, 3));
  ASSERT_TRUE(test::assignsObjects(items, regions));
  // regions[0] is the left side of the first (vertical) split.
  EXPECT_EQ(regions[0].rect.x, 0);
  EXPECT_EQ(regions[0].rect.h, 1024);
  for (const Region& r : regions) EXPECT_NEAR(double(r.weight) / double(total), 1.0 / 3, 0.02);
  EXPECT_NEAR(regions[0].rect.w, 1024 / 3, 40);
}

TEST(DivideFrame, AnObjectStraddlingTheSplitCountsOnBothSides) {
  std::vector<Footprint> items = {fp(0, 100, 110, 100, 110, 10), fp(1, 900, 910, 100, 110, 10),
                                  fp(2, 0, 1024, 500, 510, 5)};
  std::vector<Region> regions = divideFrame(items, Rect{0, 0, 1024, 1024}, 2);
  EXPECT_EQ(regions[0], (Region{Rect{0, 0, 512, 1024}, {0, 2}, 15}));
  EXPECT_EQ(regions[1], (Region{Rect{512, 0, 512, 1024}, {1, 2}, 15}));
}

TEST(DivideFrame, AmongLinesDuplicatingTheSameWeightTheSplitBalancesTheSides) {
  // S spans the frame, so every line duplicates it; the line then balances
  // the rest (A+B against C+D) rather than take the middle of the frame.
  std::vector<Footprint> items = {fp(0, 0, 1024, 0, 1024, 100), fp(1, 100, 110, 10, 20, 10),
                                  fp(2, 600, 610, 10, 20, 10), fp(3, 700, 710, 10, 20, 10),
                                  fp(4, 800, 810, 10, 20, 10)};
  std::vector<Region> regions = divideFrame(items, Rect{0, 0, 1024, 1024}, 2);
  EXPECT_EQ(regions[0], (Region{Rect{0, 0, 610, 1024}, {0, 1, 2}, 120}));
  EXPECT_EQ(regions[1], (Region{Rect{610, 0, 414, 1024}, {0, 3, 4}, 120}));
}

TEST(DivideFrame, ZeroWeightObjectsStillSteerTheSplit) {
  // Weights of zero count as one when splitting (an object always costs
  // something to draw) but add nothing to a region's weight.
  std::vector<Footprint> items;
  for (uint32_t i = 0; i < 10; ++i) items.push_back(fp(i, int(i), int(i) + 1, 0, 1, 0));
  std::vector<Region> regions = divideFrame(items, Rect{0, 0, 100, 1}, 2);
  EXPECT_EQ(regions[0], (Region{Rect{0, 0, 5, 1}, {0, 1, 2, 3, 4}, 0}));
  EXPECT_EQ(regions[1], (Region{Rect{5, 0, 95, 1}, {5, 6, 7, 8, 9}, 0}));
}

// ---- degenerate input -------------------------------------------------------

TEST(DivideFrame, AMillionObjectsOnOnePixelAllGoToTheClientOwningIt) {
  constexpr uint32_t kObjects = 1'000'000;
  std::vector<Footprint> items;
  for (uint32_t i = 0; i < kObjects; ++i) items.push_back(fp(i, 300, 301, 400, 401, 3));
  Rect frame{0, 0, 1024, 1024};
  for (int clients : {2, 7, 8, 17}) {
    std::vector<Region> regions = divideFrame(items, frame, clients);
    ASSERT_TRUE(test::tilesFrame(regions, frame, clients)) << clients << " clients";
    EXPECT_EQ(test::nonEmpty(regions), clients);
    int owner = test::regionAt(regions, 300, 400);
    ASSERT_GE(owner, 0);
    for (size_t r = 0; r < regions.size(); ++r)
      EXPECT_EQ(regions[r].objects.size(), int(r) == owner ? kObjects : 0u)
          << "region " << r << " of " << clients;
    EXPECT_EQ(regions[size_t(owner)].weight, 3u * kObjects);
  }
}

TEST(DivideFrame, MoreClientsThanObjectsStillGivesEveryClientPixels) {
  std::vector<Footprint> items = {fp(0, 10, 20, 10, 20, 100), fp(1, 500, 520, 500, 520, 100),
                                  fp(2, 1000, 1024, 0, 1024, 100)};
  Rect frame{0, 0, 1024, 1024};
  for (int clients : {4, 5, 8, 16, 17}) {
    std::vector<Region> regions = divideFrame(items, frame, clients);
    ASSERT_TRUE(test::tilesFrame(regions, frame, clients)) << clients << " clients";
    EXPECT_TRUE(test::assignsObjects(items, regions)) << clients << " clients";
    EXPECT_EQ(test::nonEmpty(regions), clients);
  }
}

TEST(DivideFrame, AnEmptyItemListStillTilesTheFrame) {
  for (Rect frame : kFrames)
    for (int clients : kClients) {
      std::vector<Region> regions = divideFrame({}, frame, clients);
      EXPECT_TRUE(test::tilesFrame(regions, frame, clients)) << frame << " " << clients;
      for (const Region& r : regions) EXPECT_EQ(r.weight, 0u);
    }
}

TEST(DivideFrame, AOnePixelWideFrameWithSevenClientsGetsSevenRowBands) {
  Rng rng(7);
  Rect frame{0, 0, 1, 301};
  std::vector<Footprint> items;
  for (uint32_t i = 0; i < 500; ++i) {
    int y = rng.integer(-5, 305);
    items.push_back(fp(i, 0, 1, y, y + rng.integer(1, 10), uint64_t(rng.integer(1, 9))));
  }
  std::vector<Region> regions = divideFrame(items, frame, 7);
  ASSERT_TRUE(test::tilesFrame(regions, frame, 7));
  EXPECT_TRUE(test::assignsObjects(items, regions));
  for (const Region& r : regions) {
    EXPECT_EQ(r.rect.x, 0);
    EXPECT_EQ(r.rect.w, 1);
    EXPECT_GE(r.rect.h, 1);
  }
}

TEST(DivideFrame, AOnePixelFrameWithSevenClientsGivesThePixelAndEverythingToTheFirst) {
  std::vector<Footprint> items = {fp(4, 0, 1, 0, 1, 2), fp(9, -3, 5, -1, 1, 3),
                                  fp(1, 0, 2, 0, 2, 4), fp(7, 1, 2, 0, 1, 100)};  // last misses
  std::vector<Region> regions = divideFrame(items, Rect{0, 0, 1, 1}, 7);
  ASSERT_TRUE(test::tilesFrame(regions, Rect{0, 0, 1, 1}, 7));
  EXPECT_EQ(regions[0], (Region{Rect{0, 0, 1, 1}, {1, 4, 9}, 9}));
  for (size_t i = 1; i < regions.size(); ++i) {
    EXPECT_TRUE(regions[i].rect.empty());
    EXPECT_TRUE(regions[i].objects.empty());
  }
}

// ---- balance on random input ------------------------------------------------

// 1000 objects of 1..16 pixels a side, uniformly placed over 1024x1024, with
// weights 1..1000. An ideal share is total/clients, about 62,000 for 8
// clients, 60 times the heaviest object, and a line crosses about 8 objects
// (1% of them), so each split can land within a few percent of its target
// and three levels of splits compound to some 10%. The measured worst over
// these seeds is printed; the bound 1.25 leaves room for other seeds while
// still catching a split that gives one side a whole extra share's worth.
TEST(DivideFrame, RandomSpreadObjectsBalanceWithinAQuarterOfTheIdealShare) {
  Rect frame{0, 0, 1024, 1024};
  double worst = 0;
  for (uint64_t seed = 100; seed < 120; ++seed) {
    Rng rng(seed);
    std::vector<Footprint> items;
    uint64_t total = 0;
    for (uint32_t i = 0; i < 1000; ++i) {
      int w = rng.integer(1, 16), h = rng.integer(1, 16);
      int x = rng.integer(0, 1024 - w), y = rng.integer(0, 1024 - h);
      uint64_t weight = uint64_t(rng.integer(1, 1000));
      items.push_back(fp(i, x, x + w, y, y + h, weight));
      total += weight;
    }
    for (int clients = 2; clients <= 8; ++clients) {
      std::vector<Region> regions = divideFrame(items, frame, clients);
      ASSERT_TRUE(test::tilesFrame(regions, frame, clients));
      ASSERT_TRUE(test::assignsObjects(items, regions));
      double ratio = double(maxWeight(regions)) / (double(total) / clients);
      worst = std::max(worst, ratio);
      EXPECT_LT(ratio, 1.25) << "seed " << seed << ", " << clients << " clients";
    }
  }
  RecordProperty("worst_ratio", std::to_string(worst));
  std::printf("worst max-region weight over ideal share: %.4f\n", worst);
}

// Clustered input is harder (whole clusters move across a line at once), but
// no region should take more than about twice its share when no single
// object outweighs a share.
TEST(DivideFrame, RandomClusteredObjectsBalanceWithinTwiceTheIdealShare) {
  Rect frame{0, 0, 1024, 1024};
  double worst = 0;
  for (uint64_t seed = 200; seed < 220; ++seed) {
    Rng rng(seed);
    std::vector<Footprint> items;
    uint64_t total = 0;
    int clusters = rng.integer(3, 12);
    for (int c = 0; c < clusters; ++c) {
      int cx = rng.integer(100, 924), cy = rng.integer(100, 924), r = rng.integer(20, 100);
      for (int k = 0; k < 200; ++k) {
        int x = cx + rng.integer(-r, r), y = cy + rng.integer(-r, r);
        uint64_t weight = uint64_t(rng.integer(1, 100));
        items.push_back(
            fp(uint32_t(items.size()), x, x + rng.integer(1, 8), y, y + rng.integer(1, 8), weight));
        total += weight;
      }
    }
    for (int clients = 2; clients <= 8; ++clients) {
      std::vector<Region> regions = divideFrame(items, frame, clients);
      ASSERT_TRUE(test::tilesFrame(regions, frame, clients));
      ASSERT_TRUE(test::assignsObjects(items, regions));
      double ratio = double(maxWeight(regions)) / (double(total) / clients);
      worst = std::max(worst, ratio);
      EXPECT_LT(ratio, 2.0) << "seed " << seed << ", " << clients << " clients";
    }
  }
  std::printf("worst max-region weight over ideal share (clustered): %.4f\n", worst);
}

TEST(DivideFrame, DividingIsDeterministicAndIgnoresInputOrder) {
  Rng rng(8);
  Rect frame{0, 0, 640, 480};
  std::vector<Footprint> items = randomFootprints(rng, frame, 2000, 40, 20);
  std::vector<Footprint> shuffled = items;
  rng.shuffle(shuffled);
  for (int clients : {2, 5, 8}) {
    std::vector<Region> a = divideFrame(items, frame, clients);
    EXPECT_EQ(a, divideFrame(items, frame, clients));
    EXPECT_EQ(a, divideFrame(shuffled, frame, clients));
  }
}

}  // namespace
}  // namespace dmmr

namespace dmmr {
namespace {

// ---- division costs: pixel weight and client speeds ---------------------------

TEST(DivideCosts, NoCostsGiveExactlyThePlainDivision) {
  Rng rng(31);
  for (const Rect& frame : kFrames)
    for (int clients : kClients) {
      std::vector<Footprint> items = randomFootprints(rng, frame, 300, 40, 5);
      EXPECT_EQ(divideFrame(items, frame, clients, DivisionCosts{}),
                divideFrame(items, frame, clients));
      DivisionCosts equal;
      equal.speeds.assign(size_t(clients), 2.5);  // equal, whatever the unit
      EXPECT_EQ(divideFrame(items, frame, clients, equal), divideFrame(items, frame, clients));
    }
}

TEST(DivideCosts, AFasterClientGetsTheLargerShareInProportion) {
  // Uniform weight: 1024 one-pixel-wide columns of weight 10.
  std::vector<Footprint> items;
  for (int x = 0; x < 1024; ++x) items.push_back(fp(uint32_t(x), x, x + 1, 0, 64, 10));
  DivisionCosts c;
  c.speeds = {1, 3};
  std::vector<Region> r = divideFrame(items, Rect{0, 0, 1024, 64}, 2, c);
  ASSERT_EQ(r.size(), 2u);
  EXPECT_EQ(r[0].rect.w, 256);  // a quarter of the weight to the client of speed 1
  EXPECT_EQ(r[1].rect.w, 768);
  EXPECT_TRUE(test::tilesFrame(r, Rect{0, 0, 1024, 64}, 2));
}

TEST(DivideCosts, SpeedsStillTileTheFrameWithEveryOverlappingObject) {
  Rng rng(32);
  for (const Rect& frame : kFrames)
    for (int clients : kClients) {
      std::vector<Footprint> items = randomFootprints(rng, frame, 200, 60, 10);
      DivisionCosts c;
      for (int k = 0; k < clients; ++k) c.speeds.push_back(0.25 + rng.integer(0, 100) / 25.0);
      c.pixel_weight = rng.integer(0, 3);
      std::vector<Region> regions = divideFrame(items, frame, clients, c);
      EXPECT_TRUE(test::tilesFrame(regions, frame, clients)) << frame << " " << clients;
      for (const Region& reg : regions)
        for (const Footprint& f : items) {
          bool overlaps = f.x0 < reg.rect.x1() && f.x1 > reg.rect.x && f.y0 < reg.rect.y1() &&
                          f.y1 > reg.rect.y && !reg.rect.empty();
          bool listed = std::binary_search(reg.objects.begin(), reg.objects.end(), f.object);
          EXPECT_EQ(overlaps, listed) << reg.rect << " object " << f.object;
        }
    }
}

// ---- fill: weight spread over a footprint's pixels ----------------------------

Footprint filled(uint32_t object, int x0, int x1, int y0, int y1, uint64_t weight, double fill) {
  Footprint f = fp(object, x0, x1, y0, y1, weight);
  f.fill = fill;
  return f;
}

TEST(DivideFill, AFrameFillingObjectIsSplitInProportionToItsPixels) {
  std::vector<Footprint> items = {filled(0, 0, 1024, 0, 64, 1, 1.0)};
  std::vector<Region> r = divideFrame(items, Rect{0, 0, 1024, 64}, 2);
  // Counted whole (weight 1) on both sides, its fill half and half.
  EXPECT_EQ(r[0], (Region{Rect{0, 0, 512, 64}, {0}, 1 + 512 * 64}));
  EXPECT_EQ(r[1], (Region{Rect{512, 0, 512, 64}, {0}, 1 + 512 * 64}));
}

TEST(DivideFill, FillPullsTheSplitTowardTheFilledSide) {
  // A large object over the left half, its fill as heavy as the 512 small
  // objects on the right: the line lands at the half. Without its fill the
  // small objects alone would decide, and the left client would get them too.
  std::vector<Footprint> items = {filled(0, 0, 512, 0, 64, 1, 1.0)};
  for (int x = 512; x < 1024; ++x) items.push_back(fp(uint32_t(x), x, x + 1, 0, 64, 64));
  Rect frame{0, 0, 1024, 64};
  int withFill = divideFrame(items, frame, 2)[0].rect.w;
  EXPECT_NEAR(withFill, 512, 1);
  items[0].fill = 0;
  EXPECT_GT(divideFrame(items, frame, 2)[0].rect.w, 700);
}

TEST(DivideFill, RegionWeightsAreTheObjectsWeightsAndTheFillInsideThem) {
  Rng rng(41);
  for (const Rect& frame : kFrames)
    for (int clients : kClients) {
      std::vector<Footprint> items = randomFootprints(rng, frame, 200, 80, 10);
      for (Footprint& f : items) f.fill = rng.integer(0, 4) == 0 ? 0.0 : rng.integer(1, 50) / 7.0;
      std::vector<Region> regions = divideFrame(items, frame, clients);
      ASSERT_TRUE(test::tilesFrame(regions, frame, clients)) << frame << " " << clients;
      for (const Region& reg : regions) {
        uint64_t weight = 0;
        double fill = 0;
        for (const Footprint& f : items) {
          bool overlaps = f.x0 < reg.rect.x1() && f.x1 > reg.rect.x && f.y0 < reg.rect.y1() &&
                          f.y1 > reg.rect.y && !reg.rect.empty();
          bool listed = std::binary_search(reg.objects.begin(), reg.objects.end(), f.object);
          EXPECT_EQ(overlaps, listed) << reg.rect << " object " << f.object;
          if (!listed) continue;
          weight += f.weight;
          int w = std::min(f.x1, reg.rect.x1()) - std::max(f.x0, reg.rect.x);
          int h = std::min(f.y1, reg.rect.y1()) - std::max(f.y0, reg.rect.y);
          fill += f.fill * std::max(0, w) * std::max(0, h);
        }
        EXPECT_EQ(reg.weight, weight + uint64_t(std::llround(fill))) << reg.rect;
      }
    }
}

TEST(DivideFill, RandomFilledObjectsBalanceTheirFill) {
  // Fill alone (object weights 0): every region's fill within a quarter of
  // the ideal share, as for plain weights on spread objects.
  for (uint64_t seed = 1; seed <= 5; ++seed) {
    Rng rng(seed);
    Rect frame{0, 0, 1024, 768};
    std::vector<Footprint> items;
    for (uint32_t i = 0; i < 400; ++i) {
      int w = rng.integer(20, 300), h = rng.integer(20, 300);
      int x = rng.integer(0, 1024 - w), y = rng.integer(0, 768 - h);
      items.push_back(filled(i, x, x + w, y, y + h, 0, 1.0));
    }
    double total = 0;
    for (const Footprint& f : items) total += double(f.x1 - f.x0) * (f.y1 - f.y0);
    for (int clients : {2, 4, 8}) {
      std::vector<Region> regions = divideFrame(items, frame, clients);
      for (const Region& r : regions)
        EXPECT_NEAR(double(r.weight) / (total / clients), 1.0, 0.25)
            << "seed " << seed << " clients " << clients << " " << r;
    }
  }
}

TEST(DivideCosts, PixelWeightPullsTheSplitTowardEqualAreas) {
  // All the objects' weight sits in the left eighth: by objects alone one
  // client gets that sliver; with a heavy pixel weight the halves near equal.
  std::vector<Footprint> items;
  for (int x = 0; x < 128; ++x) items.push_back(fp(uint32_t(x), x, x + 1, 0, 64, 100));
  Rect frame{0, 0, 1024, 64};
  int plain = divideFrame(items, frame, 2)[0].rect.w;
  DivisionCosts c;
  c.pixel_weight = 10;  // 640 a column against the objects' 100
  int weighted = divideFrame(items, frame, 2, c)[0].rect.w;
  EXPECT_LE(plain, 70);
  EXPECT_GT(weighted, 400);
  EXPECT_LT(weighted, 512);  // the objects still count: left gets less area
}

}  // namespace
}  // namespace dmmr
