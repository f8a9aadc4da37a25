// Tile pools for --balance tiles-static / tiles-dynamic, and the link model,
// on plain data.
#include <gtest/gtest.h>

#include <algorithm>
#include <deque>
#include <random>

#include "tiles.h"

using namespace dmmr;
using Ids = std::vector<uint32_t>;

namespace {
// Every pixel of `frame` in exactly one tile, and no tile outside it.
bool coversExactly(const std::vector<Rect>& tiles, const Rect& frame) {
  std::vector<int> hits(size_t(frame.area()), 0);
  for (const Rect& t : tiles)
    for (int y = t.y; y < t.y + t.h; ++y)
      for (int x = t.x; x < t.x + t.w; ++x) {
        if (x < frame.x || y < frame.y || x >= frame.x + frame.w || y >= frame.y + frame.h)
          return false;
        ++hits[size_t((y - frame.y) * frame.w + (x - frame.x))];
      }
  return std::all_of(hits.begin(), hits.end(), [](int h) { return h == 1; });
}
}  // namespace

TEST(MakeTiles, RowOrderWithTheLastRowAndColumnCut) {
  std::vector<Rect> t = makeTiles({0, 0, 300, 200}, 128, 128);
  ASSERT_EQ(t.size(), 6u);
  EXPECT_EQ(t[0], (Rect{0, 0, 128, 128}));
  EXPECT_EQ(t[2], (Rect{256, 0, 44, 128}));
  EXPECT_EQ(t[3], (Rect{0, 128, 128, 72}));
  EXPECT_EQ(t[5], (Rect{256, 128, 44, 72}));
}

TEST(MakeTiles, CoverEveryFrameShapeExactly) {
  for (Rect frame :
       {Rect{0, 0, 1, 1}, Rect{0, 0, 7, 5}, Rect{10, 20, 64, 64}, Rect{0, 0, 513, 257}})
    for (auto [w, h] : {std::pair{1, 1}, {32, 32}, {128, 64}, {1000, 1000}}) {
      std::vector<Rect> t = makeTiles(frame, w, h);
      EXPECT_TRUE(coversExactly(t, frame)) << frame << " tile " << w << "x" << h;
      for (const Rect& r : t) EXPECT_TRUE(r.w >= 1 && r.h >= 1 && r.w <= w && r.h <= h);
    }
  EXPECT_TRUE(makeTiles({0, 0, 0, 0}, 32, 32).empty());
}

TEST(GridTileSize, FollowsTheFrameSize) {
  auto size = [](int w, int h, int tiles) {
    std::pair<int, int> s;
    gridTileSize(w, h, tiles, &s.first, &s.second);
    return s;
  };
  EXPECT_EQ(size(512, 512, 64), std::pair(64, 64));  // 4 clients x 16
  EXPECT_EQ(size(1024, 1024, 64), std::pair(128, 128));
  EXPECT_EQ(size(1024, 768, 64), std::pair(114, 96));  // 9 x 8 tiles
  EXPECT_EQ(size(300, 200, 1), std::pair(300, 200));   // one tile: the frame
  EXPECT_EQ(size(1, 1, 1000), std::pair(1, 1));        // more tiles than pixels
  EXPECT_EQ(size(4096, 2, 64), std::pair(64, 2));      // a strip: one row
}

// Fixed seed: over frames of aspect up to 4 and at least 64 pixels a tile,
// the tiles number 0.75x-1.5x what was asked and are at most 2:1.
TEST(GridTileSize, AboutTheTilesAskedNearSquareOnRandomFrames) {
  std::mt19937 rng(1607);
  int checked = 0;
  while (checked < 20000) {
    int w = 16 + int(rng() % 4081), h = 16 + int(rng() % 4081), tiles = 16 + int(rng() % 1009);
    if (int64_t(tiles) * 64 > int64_t(w) * h || std::max(w, h) > 4 * std::min(w, h)) continue;
    ++checked;
    int tw = 0, th = 0;
    gridTileSize(w, h, tiles, &tw, &th);
    size_t n = makeTiles({0, 0, w, h}, tw, th).size();
    ASSERT_GE(double(n), 0.75 * tiles) << w << "x" << h << " " << tiles;
    ASSERT_LE(double(n), 1.5 * tiles) << w << "x" << h << " " << tiles;
    ASSERT_LE(std::max(tw, th), 2 * std::min(tw, th)) << w << "x" << h << " " << tiles;
  }
}

TEST(DealTiles, RowsIsThePapersRoundRobin) {
  auto d = dealTiles(7, 3, 3, TileOrder::Rows);
  EXPECT_EQ(d[0], (Ids{0, 3, 6}));
  EXPECT_EQ(d[1], (Ids{1, 4}));
  EXPECT_EQ(d[2], (Ids{2, 5}));
}

TEST(DealTiles, InterleavedSplitsAColumnAmongClients) {
  // 4 columns, 2 clients: in rows order client 0 owns columns 0 and 2
  // whole; interleaved, each column alternates.
  auto rows = dealTiles(16, 4, 2, TileOrder::Rows);
  auto inter = dealTiles(16, 4, 2, TileOrder::Interleaved);
  EXPECT_EQ(rows[0], (Ids{0, 2, 4, 6, 8, 10, 12, 14}));
  EXPECT_EQ(inter[0], (Ids{0, 2, 5, 7, 8, 10, 13, 15}));
}

TEST(DealTiles, EveryTileToExactlyOneClient) {
  for (TileOrder order : {TileOrder::Rows, TileOrder::Interleaved})
    for (int clients : {1, 2, 3, 8, 17})
      for (size_t tiles : {0u, 1u, 5u, 64u, 101u}) {
        auto d = dealTiles(tiles, 8, clients, order);
        ASSERT_EQ(d.size(), size_t(clients));
        Ids all;
        size_t lo = tiles, hi = 0;
        for (auto& c : d) {
          EXPECT_TRUE(std::is_sorted(c.begin(), c.end()));
          all.insert(all.end(), c.begin(), c.end());
          lo = std::min(lo, c.size());
          hi = std::max(hi, c.size());
        }
        std::sort(all.begin(), all.end());
        Ids expect(tiles);
        for (size_t i = 0; i < tiles; ++i) expect[i] = uint32_t(i);
        EXPECT_EQ(all, expect);
        if (order == TileOrder::Rows) {
          EXPECT_LE(hi - std::min(lo, hi), 1u);
        }
      }
}

TEST(TilePool, FillsEachWindowThenRefillsAsTilesReturn) {
  TilePool pool(5, 2, 2);
  EXPECT_EQ(pool.refill(0), (Ids{0, 1}));
  EXPECT_EQ(pool.refill(1), (Ids{2, 3}));
  EXPECT_TRUE(pool.refill(0).empty()) << "window full";
  pool.done(1, 3);
  EXPECT_EQ(pool.refill(1), Ids{4});
  EXPECT_TRUE(pool.refill(0).empty()) << "pool dry";
  std::vector<int> owners;
  for (uint32_t t = 0; t < 5; ++t) owners.push_back(pool.owner(t));
  EXPECT_EQ(owners, (std::vector<int>{0, 0, 1, 1, 1}));
  for (auto [c, t] : {std::pair{0, 0u}, {0, 1u}, {1, 2u}}) pool.done(c, t);
  EXPECT_FALSE(pool.finished());
  pool.done(1, 4);
  EXPECT_TRUE(pool.finished());
}

// Tiles are forgotten once every tile before them is back: out-of-order
// returns keep the later ones until the gap closes.
TEST(TilePool, ForgetsTilesOnceAllBeforeThemAreBack) {
  TilePool pool(4, 1, 4);
  EXPECT_EQ(pool.refill(0), (Ids{0, 1, 2, 3}));
  pool.done(0, 1);
  pool.done(0, 2);
  EXPECT_EQ(pool.forgotten(), 0u);  // tile 0 is still out
  EXPECT_EQ(pool.held(), 4u);
  EXPECT_EQ(pool.owner(3), 0);
  pool.done(0, 0);
  EXPECT_EQ(pool.forgotten(), 3u);
  EXPECT_EQ(pool.held(), 1u);
  pool.add(2);
  EXPECT_EQ(pool.size(), 6u);
  EXPECT_EQ(pool.owner(4), -1);  // not yet handed out
  pool.done(0, 3);
  EXPECT_EQ(pool.refill(0), (Ids{4, 5}));
  pool.done(0, 5);
  pool.done(0, 4);
  EXPECT_TRUE(pool.finished());
  EXPECT_EQ(pool.held(), 0u);
  EXPECT_EQ(pool.forgotten(), 6u);
}

// A long run as the server drives it (a frame's tiles added while the last
// frame's are still out, each client answering in order, clients in random
// turns): the pool's bookkeeping stays within about two frames' tiles
// however many frames go by, while the numbering goes on.
TEST(TilePool, HoldsAboutTwoFramesOfTilesOverALongRun) {
  const int clients = 3, window = 2;
  const size_t per_frame = 64, frames = 3000;
  TilePool pool(per_frame, clients, window);
  std::vector<std::deque<uint32_t>> given(clients);
  std::mt19937 rng(14);
  size_t most = 0;
  for (size_t f = 0; f < frames; ++f) {
    pool.add(per_frame);
    for (size_t returned = 0; returned < per_frame;) {
      for (int k = 0; k < clients; ++k)
        for (uint32_t t : pool.refill(k)) given[size_t(k)].push_back(t);
      auto& g = given[rng() % clients];
      if (g.empty()) continue;
      pool.done(int(&g - given.data()), g.front());
      g.pop_front();
      ++returned;
    }
    most = std::max(most, pool.held());
  }
  EXPECT_EQ(pool.size(), (frames + 1) * per_frame);
  EXPECT_FALSE(pool.finished());  // the last frame's tiles are still out
  EXPECT_LE(most, 2 * per_frame);
  EXPECT_GE(most, per_frame);
}

// Clients finishing in random order: every tile is handed out once, no
// window is ever exceeded, and the pool finishes.
TEST(TilePool, RandomCompletionOrderKeepsItsInvariants) {
  std::mt19937 rng(42);
  for (int trial = 0; trial < 50; ++trial) {
    int clients = 1 + int(rng() % 8), window = 1 + int(rng() % 4);
    size_t tiles = rng() % 200;
    TilePool pool(tiles, clients, window);
    std::vector<std::pair<int, uint32_t>> out;
    std::vector<int> given(tiles, 0);
    for (int c = 0; c < clients; ++c)
      for (uint32_t t : pool.refill(c)) out.push_back({c, t}), ++given[t];
    while (!out.empty()) {
      size_t i = rng() % out.size();
      auto [c, t] = out[i];
      out.erase(out.begin() + long(i));
      pool.done(c, t);
      for (uint32_t n : pool.refill(c)) out.push_back({c, n}), ++given[n];
      for (int k = 0; k < clients; ++k) ASSERT_LE(pool.inFlight(k), window);
    }
    EXPECT_TRUE(pool.finished());
    EXPECT_TRUE(std::all_of(given.begin(), given.end(), [](int g) { return g == 1; }));
  }
}

TEST(LinkModel, LatencyPlusSizeOverBandwidthPlusJitter) {
  LinkModel lan{0.0001, 1e9, 0};
  EXPECT_DOUBLE_EQ(linkSeconds(125'000'000, lan, 0.5), 1.0001);
  LinkModel wifi{0.005, 100e6, 0.002};
  EXPECT_DOUBLE_EQ(linkSeconds(0, wifi, 0), 0.005);
  EXPECT_DOUBLE_EQ(linkSeconds(1'250'000, wifi, 0.5), 0.005 + 0.1 + 0.001);
}

TEST(ObjectsPerTile, MatchesBruteForceOverlapOnRandomFootprints) {
  std::mt19937 rng(21);
  for (int trial = 0; trial < 200; ++trial) {
    Rect frame{0, 0, 1 + int(rng() % 300), 1 + int(rng() % 200)};
    int tw = 1 + int(rng() % 90), th = 1 + int(rng() % 90);
    std::vector<Footprint> items;
    for (uint32_t o = 0; o < 60; ++o) {
      if (rng() % 4 == 0) continue;  // not every object is in view
      int x0 = int(rng() % 340) - 20, y0 = int(rng() % 240) - 20;
      // Some footprints are empty (x1 <= x0): they must go nowhere.
      items.push_back({o, x0, x0 + int(rng() % 80) - 5, y0, y0 + int(rng() % 80) - 5, 1});
    }
    std::vector<Rect> tiles = makeTiles(frame, tw, th);
    auto lists = objectsPerTile(items, frame, tw, th);
    ASSERT_EQ(lists.size(), tiles.size());
    for (size_t t = 0; t < tiles.size(); ++t) {
      Ids want;
      const Rect& r = tiles[t];
      for (const Footprint& f : items)
        if (f.x0 < f.x1 && f.y0 < f.y1 && f.x0 < r.x1() && f.x1 > r.x && f.y0 < r.y1() &&
            f.y1 > r.y)
          want.push_back(f.object);
      EXPECT_EQ(lists[t], want) << "trial " << trial << " tile " << t;
    }
  }
}

TEST(ObjectsPerTile, AFootprintOnATileCornerGoesToTheFourTilesAroundIt) {
  // Footprint pixels [63, 65) x [63, 65) touch the tiles at (0,0) (1,0) (0,1) (1,1).
  auto lists = objectsPerTile({{7, 63, 65, 63, 65, 1}}, {0, 0, 256, 256}, 64, 64);
  ASSERT_EQ(lists.size(), 16u);
  for (size_t t : {0u, 1u, 4u, 5u}) EXPECT_EQ(lists[t], Ids{7}) << t;
  size_t total = 0;
  for (const auto& l : lists) total += l.size();
  EXPECT_EQ(total, 4u);
}

TEST(TilePool, AddedTilesAreHandedOutAfterTheEarlierOnes) {
  TilePool p(2, 2, 2);
  EXPECT_EQ(p.refill(0), (Ids{0, 1}));
  EXPECT_EQ(p.refill(1), Ids{});
  p.add(3);  // the next frame's tiles
  EXPECT_EQ(p.size(), 5u);
  EXPECT_FALSE(p.finished());
  EXPECT_EQ(p.refill(1), (Ids{2, 3}));
  EXPECT_EQ(p.refill(0), Ids{});  // its window is full
  p.done(0, 1);
  EXPECT_EQ(p.refill(0), Ids{4});
  for (auto [k, t] : {std::pair{0, 0u}, {1, 2u}, {1, 3u}, {0, 4u}}) p.done(k, t);
  EXPECT_TRUE(p.finished());
}

TEST(ParseTileSize, AcceptsWxHAndRejectsTheRest) {
  int w = 0, h = 0;
  EXPECT_TRUE(parseTileSize("128x64", &w, &h));
  EXPECT_EQ(w, 128);
  EXPECT_EQ(h, 64);
  EXPECT_TRUE(parseTileSize("1x16384", &w, &h));
  for (const char* bad : {"", "x", "128", "128x", "x64", "0x64", "64x0", "16385x1", "-1x4", "12 x4",
                          "4x4x4", "axb", "99999999999x1"})
    EXPECT_FALSE(parseTileSize(bad, &w, &h)) << bad;
}

TEST(ParseBalance, NamesRoundTrip) {
  for (Balance b : {Balance::Frustum, Balance::TilesStatic, Balance::TilesDynamic, Balance::Auto}) {
    Balance got = Balance::Auto;
    EXPECT_TRUE(parseBalance(balanceName(b), &got)) << balanceName(b);
    EXPECT_EQ(got, b);
  }
  Balance got;
  EXPECT_FALSE(parseBalance("tiles", &got));
  EXPECT_FALSE(parseBalance("Frustum", &got));
}

TEST(BalanceTrial, TimesEachCandidateOnItsBlockThenKeepsTheFastest) {
  const std::vector<Balance> c = {Balance::Frustum, Balance::TilesStatic, Balance::TilesDynamic};
  BalanceTrial t(c, /*warmup=*/1, /*block=*/3);
  // Frame 0 warms up with the first candidate; frames 1-3, 4-6, 7-9 are the blocks.
  EXPECT_EQ(t.strategy(0), Balance::Frustum);
  EXPECT_FALSE(t.boundary(0));
  std::vector<Balance> seen;
  double now = 1000;
  const double per_frame[] = {50, 20, 35};  // static is the fastest here
  for (uint32_t i = 1; i <= 9; ++i) {
    if (t.boundary(i)) t.blockBoundary(i, now);
    seen.push_back(t.strategy(i));
    now += per_frame[(i - 1) / 3];
  }
  EXPECT_EQ(seen, (std::vector<Balance>{Balance::Frustum, Balance::Frustum, Balance::Frustum,
                                        Balance::TilesStatic, Balance::TilesStatic,
                                        Balance::TilesStatic, Balance::TilesDynamic,
                                        Balance::TilesDynamic, Balance::TilesDynamic}));
  EXPECT_FALSE(t.decided());
  ASSERT_TRUE(t.boundary(10));
  t.blockBoundary(10, now);
  ASSERT_TRUE(t.decided());
  EXPECT_EQ(t.winner(), Balance::TilesStatic);
  EXPECT_EQ(t.blockMs(), (std::vector<double>{50, 20, 35}));
  for (uint32_t i = 10; i < 40; ++i) {
    EXPECT_FALSE(t.boundary(i));
    EXPECT_EQ(t.strategy(i), Balance::TilesStatic);
  }
}

TEST(BalanceTrial, AWalkthroughShorterThanTheTrialStaysOnTheCandidatesInTurn) {
  BalanceTrial t({Balance::Frustum, Balance::TilesDynamic}, 1, 2);
  EXPECT_EQ(t.strategy(0), Balance::Frustum);
  t.blockBoundary(1, 0);
  EXPECT_EQ(t.strategy(2), Balance::Frustum);
  t.blockBoundary(3, 10);
  EXPECT_EQ(t.strategy(3), Balance::TilesDynamic);
  EXPECT_FALSE(t.decided());
  EXPECT_EQ(t.blockMs()[0], 5);
  EXPECT_LT(t.blockMs()[1], 0) << "not timed yet";
}
