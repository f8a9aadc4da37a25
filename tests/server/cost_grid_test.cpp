// Tests for the division's screen-space cost correction (server/cost_grid.h):
// the update's direction, normalisation and clamps, the footprint factor
// against a per-pixel brute force, and the closed loop with divideFrame,
// where measured client time balances although the weights misjudge it.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <vector>

#include "cost_grid.h"
#include "divide.h"
#include "server_test_util.h"

namespace dmmr {
namespace {

using test::Rng;

double geometricMean(const CostGrid& g) {
  double s = 0;
  for (double f : g.factor) s += std::log(f);
  return std::exp(s / double(g.factor.size()));
}

// Feedback from a frame planned with the grid as it is now.
void correct(CostGrid* g, Rect frame, const std::vector<RegionCost>& regions,
             const CostGridGain& gain = {}) {
  CostGrid now = *g;
  correctCostGrid(g, now, frame, regions, gain);
}

TEST(CostGrid, UniformIsOnes) {
  CostGrid g = CostGrid::uniform(3, 2);
  EXPECT_EQ(g, (CostGrid{3, 2, {1, 1, 1, 1, 1, 1}}));
}

TEST(CostGrid, BalancedFramesLeaveItUniform) {
  // Measured time in proportion to the plan: nothing to correct.
  CostGrid g = CostGrid::uniform(8, 8);
  Rect frame{0, 0, 256, 256};
  for (int i = 0; i < 5; ++i)
    correct(&g, frame, {{{0, 0, 100, 256}, 300, 30}, {{100, 0, 156, 256}, 100, 10}});
  for (double f : g.factor) EXPECT_NEAR(f, 1.0, 1e-12);
}

TEST(CostGrid, ARegionThatCostMoreThanPlannedWeighsMore) {
  CostGrid g = CostGrid::uniform(4, 1);
  Rect frame{0, 0, 400, 10};
  // Left half planned 50%, measured 75%.
  correct(&g, frame, {{{0, 0, 200, 10}, 50, 75}, {{200, 0, 200, 10}, 50, 25}});
  EXPECT_GT(g.factor[0], 1.0) << g;
  EXPECT_EQ(g.factor[0], g.factor[1]);
  EXPECT_LT(g.factor[2], 1.0) << g;
  EXPECT_EQ(g.factor[2], g.factor[3]);
  EXPECT_NEAR(geometricMean(g), 1.0, 1e-12);
  // With gain 1 the ratio between the halves is the measured ratio of
  // ratios: (0.75 / 0.5) / (0.25 / 0.5) = 3, less the smoothing of 1/(2n).
  CostGrid h = CostGrid::uniform(4, 1);
  correct(&h, frame, {{{0, 0, 200, 10}, 50, 75}, {{200, 0, 200, 10}, 50, 25}}, {1.0, 0.0, 4, 64});
  EXPECT_NEAR(h.factor[0] / h.factor[3], (75 + 12.5) / (25 + 12.5), 1e-9) << h;
}

TEST(CostGrid, LateFeedbackIsMeasuredAgainstTheGridItWasPlannedWith) {
  // The grid already doubled the left half's weight while the frame was in
  // flight; the frame, planned with the uniform grid, says the left half
  // costs 2x its plan. With gain 1 the grid lands on that frame's target
  // (left 2x right at most), not on 2 x 2.
  Rect frame{0, 0, 400, 10};
  CostGrid planned = CostGrid::uniform(2, 1), g = planned;
  g.factor = {std::sqrt(2.0), 1 / std::sqrt(2.0)};
  std::vector<RegionCost> r = {{{0, 0, 200, 10}, 50, 200.0 / 3},
                               {{200, 0, 200, 10}, 50, 100.0 / 3}};
  correctCostGrid(&g, planned, frame, r, {1.0, 0.0, 4, 64});
  double target = (200.0 / 3 + 100.0 / 8) / (100.0 / 3 + 100.0 / 8);  // with the smoothing
  EXPECT_NEAR(g.factor[0] / g.factor[1], target, 1e-9) << g;
  // Half the way there in log space with gain 0.5.
  g.factor = {std::sqrt(2.0), 1 / std::sqrt(2.0)};
  correctCostGrid(&g, planned, frame, r, {0.5, 0.0, 4, 64});
  EXPECT_NEAR(g.factor[0] / g.factor[1], std::sqrt(2.0 * target), 1e-9) << g;
}

TEST(CostGrid, ACellUnderTwoRegionsTakesTheirAreaWeightedLogRatio) {
  CostGrid g = CostGrid::uniform(2, 1);
  Rect frame{0, 0, 200, 1};
  // Region A is cell 0 and a quarter of cell 1; B the rest of cell 1.
  std::vector<RegionCost> r = {{{0, 0, 125, 1}, 1, 4}, {{125, 0, 75, 1}, 1, 1}};
  CostGridGain gain{1.0, 0.0, 100, 1000};
  correct(&g, frame, r, gain);
  double em = 5.0 / 2 / 4, ep = 2.0 / 2 / 4;  // smoothing
  double la = std::log(((4 + em) / (5 + 2 * em)) / ((1 + ep) / (2 + 2 * ep)));
  double lb = std::log(((1 + em) / (5 + 2 * em)) / ((1 + ep) / (2 + 2 * ep)));
  double l0 = la, l1 = 0.25 * la + 0.75 * lb, mean = (l0 + l1) / 2;
  EXPECT_NEAR(g.factor[0], std::exp(l0 - mean), 1e-12);
  EXPECT_NEAR(g.factor[1], std::exp(l1 - mean), 1e-12);
}

TEST(CostGrid, StepsAndFactorsAreClamped) {
  CostGrid g = CostGrid::uniform(2, 1);
  Rect frame{0, 0, 2, 1};
  CostGridGain gain{1.0, 0.0, 2, 3};
  // Planned nothing on the left, measured everything there: a huge ratio,
  // one step of at most 2x.
  correct(&g, frame, {{{0, 0, 1, 1}, 0, 100}, {{1, 0, 1, 1}, 100, 0}}, gain);
  EXPECT_NEAR(g.factor[0] / g.factor[1], 4.0, 1e-9) << g;  // +log 2 and -log 2
  for (int i = 0; i < 20; ++i)
    correct(&g, frame, {{{0, 0, 1, 1}, 0, 100}, {{1, 0, 1, 1}, 100, 0}}, gain);
  EXPECT_LE(g.factor[0], 3.0 + 1e-9) << g;
  EXPECT_GE(g.factor[1], 1 / 3.0 - 1e-9) << g;
}

TEST(CostGrid, ForgettingDrawsStaleCellsBackToOne) {
  CostGrid g = CostGrid::uniform(2, 1);
  Rect frame{0, 0, 100, 1};
  correct(&g, frame, {{{0, 0, 50, 1}, 1, 3}, {{50, 0, 50, 1}, 1, 1}});
  double before = g.factor[0];
  ASSERT_GT(before, 1.2);
  // Frames from a single region say nothing; only forgetting acts then, and
  // a single region is no feedback at all.
  correct(&g, frame, {{{0, 0, 100, 1}, 1, 3}});
  EXPECT_EQ(g.factor[0], before);
  // Balanced frames: the factors decay toward 1 at the forget rate.
  for (int i = 0; i < 200; ++i) correct(&g, frame, {{{0, 0, 50, 1}, 1, 1}, {{50, 0, 50, 1}, 1, 1}});
  EXPECT_NEAR(g.factor[0], 1.0, 0.01) << g;
}

TEST(CostGrid, NothingMeasuredOrPlannedChangesNothing) {
  CostGrid g = CostGrid::uniform(3, 3);
  g.factor[4] = 2;
  CostGrid before = g;
  Rect frame{0, 0, 30, 30};
  correct(&g, frame, {{{0, 0, 15, 30}, 0, 0}, {{15, 0, 15, 30}, 0, 0}});
  EXPECT_EQ(g, before);
  correct(&g, frame, {{{0, 0, 15, 30}, 5, 0}, {{15, 0, 15, 30}, 5, 0}});
  EXPECT_EQ(g, before);
  correct(&g, frame, {});
  EXPECT_EQ(g, before);
}

// Per-pixel brute force: the mean over the clipped rectangle's pixels of the
// factor of the cell each pixel lies in.
double bruteFactor(const CostGrid& g, Rect frame, int x0, int x1, int y0, int y1) {
  double sum = 0, n = 0;
  for (int y = std::max(y0, frame.y); y < std::min(y1, frame.y1()); ++y)
    for (int x = std::max(x0, frame.x); x < std::min(x1, frame.x1()); ++x) {
      int i = 0, j = 0;
      while (frame.x + int64_t(frame.w) * (i + 1) / g.columns <= x) ++i;
      while (frame.y + int64_t(frame.h) * (j + 1) / g.rows <= y) ++j;
      sum += g.factor[size_t(j) * size_t(g.columns) + size_t(i)];
      n += 1;
    }
  return n > 0 ? sum / n : 1.0;
}

TEST(CostGrid, FootprintFactorIsThePixelMeanOfItsCells) {
  Rng rng(7);
  for (int trial = 0; trial < 300; ++trial) {
    // Frames smaller than the grid too (cells of no pixel).
    Rect frame{rng.integer(-20, 20), rng.integer(-20, 20), rng.integer(1, 90), rng.integer(1, 90)};
    CostGrid g = CostGrid::uniform(rng.integer(1, 40), rng.integer(1, 40));
    for (double& f : g.factor) f = rng.real(0.1, 5);
    int x0 = rng.integer(frame.x - 10, frame.x1() + 5), y0 = rng.integer(frame.y - 10, frame.y1());
    int x1 = x0 + rng.integer(0, 60), y1 = y0 + rng.integer(0, 60);
    EXPECT_NEAR(costGridFactor(g, frame, x0, x1, y0, y1), bruteFactor(g, frame, x0, x1, y0, y1),
                1e-9)
        << frame << " " << g << " x " << x0 << ".." << x1 << " y " << y0 << ".." << y1;
  }
}

// ---- closed loop with the division ------------------------------------------

// A scene whose weights misjudge its cost: objects on the left cost 4x their
// weight, and every object costs a fixed part the weights leave out.
// With `exact`, cost is the weight itself.
struct Scene {
  std::vector<Footprint> items;
  bool exact = false;
  double costOf(const Footprint& f) const {
    if (exact) return double(f.weight);
    double cx = 0.5 * (f.x0 + f.x1);
    return double(f.weight) * (cx < 300 ? 4.0 : 1.0) + 150;
  }
};

Scene randomScene(Rng& rng, Rect frame, int n) {
  Scene s;
  for (int i = 0; i < n; ++i) {
    Footprint f;
    f.object = uint32_t(i);
    int w = rng.integer(2, 40), h = rng.integer(2, 40);
    f.x0 = rng.integer(frame.x, frame.x1() - w);
    f.y0 = rng.integer(frame.y, frame.y1() - h);
    f.x1 = f.x0 + w;
    f.y1 = f.y0 + h;
    f.weight = uint64_t(rng.integer(10, 1000));
    s.items.push_back(f);
  }
  return s;
}

// Each region's cost: every object overlapping it, counted whole.
std::vector<double> measure(const Scene& s, const std::vector<Region>& regions) {
  std::vector<double> out;
  for (const Region& r : regions) {
    double c = 0;
    for (uint32_t o : r.objects) c += s.costOf(s.items[o]);
    out.push_back(c);
  }
  return out;
}

double maxOverMean(const std::vector<double>& v) {
  double m = 0, sum = 0;
  for (double x : v) {
    m = std::max(m, x);
    sum += x;
  }
  return m / (sum / double(v.size()));
}

// Runs `frames` frames, feedback arriving `lag` frames late as in the
// pipeline; returns the median max/mean of the last 10 frames.
double closedLoop(const Scene& base, Rect frame, int clients, int frames, int lag, bool correct) {
  CostGrid grid = CostGrid::uniform(32, 24);
  std::deque<std::pair<CostGrid, std::vector<RegionCost>>> inFlight;
  std::vector<double> tail;
  Scene s = base;
  for (int f = 0; f < frames; ++f) {
    // The camera pans: everything drifts a pixel right each frame.
    std::vector<Footprint> items = s.items;
    for (Footprint& it : items) {
      if (correct) {
        double k = costGridFactor(grid, frame, it.x0, it.x1, it.y0, it.y1);
        it.weight = uint64_t(std::llround(double(it.weight) * k));
      }
    }
    std::vector<Region> regions = divideFrame(items, frame, clients);
    std::vector<double> ms = measure(s, regions);
    std::vector<RegionCost> fb;
    for (size_t k = 0; k < regions.size(); ++k)
      fb.push_back({regions[k].rect, double(regions[k].weight), ms[k]});
    inFlight.push_back({grid, fb});
    if (int(inFlight.size()) > lag) {
      correctCostGrid(&grid, inFlight.front().first, frame, inFlight.front().second);
      inFlight.pop_front();
    }
    if (f >= frames - 10) tail.push_back(maxOverMean(ms));
    for (Footprint& it : s.items) {
      ++it.x0;
      ++it.x1;
    }
  }
  std::sort(tail.begin(), tail.end());
  return tail[tail.size() / 2];
}

TEST(CostGridLoop, MeasuredTimeBalancesWhereTheWeightsMisjudgeIt) {
  Rect frame{0, 0, 1024, 768};
  for (uint64_t seed = 1; seed <= 3; ++seed) {
    Rng rng(seed);
    Scene s = randomScene(rng, Rect{-40, 0, 1024, 768}, 3000);
    for (int clients : {2, 4, 8}) {
      double without = closedLoop(s, frame, clients, 40, 3, false);
      double with = closedLoop(s, frame, clients, 40, 3, true);
      EXPECT_GT(without, 1.3) << "seed " << seed << " clients " << clients;
      EXPECT_LT(with, 1.1) << "seed " << seed << " clients " << clients << " without " << without;
    }
  }
}

TEST(CostGridLoop, WeightsThatAreRightStayBalanced) {
  // Cost exactly the weight, feedback at once: the correction must not make
  // things worse.
  Rect frame{0, 0, 1024, 768};
  Rng rng(11);
  Scene s = randomScene(rng, frame, 3000);
  s.exact = true;
  for (int clients : {2, 4})
    EXPECT_LT(closedLoop(s, frame, clients, 30, 0, true), 1.05) << clients << " clients";
}

}  // namespace
}  // namespace dmmr
