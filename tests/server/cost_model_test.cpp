// The cost model of fitted division weights (server/cost_model.h): the fit
// recovers known coefficients from noisy samples (fixed seeds), never goes
// negative, refuses degenerate data, and finds a slow client's speed.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "cost_model.h"
#include "server_test_util.h"

namespace dmmr {
namespace {

using test::Rng;

const CostModel kTruth{0.02, 0.0005, 0.003, 0.00001, 0.000004, true};

// `frames` x `clients` samples of random work, timed by kTruth at each
// client's speed, with +-`noise` relative error.
std::vector<CostSample> samples(Rng& rng, int frames, int clients, double noise,
                                const std::vector<double>& speeds = {}) {
  std::vector<CostSample> out;
  for (int f = 0; f < frames; ++f)
    for (int k = 0; k < clients; ++k) {
      CostSample s;
      s.client = k;
      s.drawn = rng.integer(10, 400);
      s.triangles = rng.integer(1000, 60000);
      s.tested = rng.integer(50, 3000);
      s.pixels = rng.integer(10000, 800000);
      s.fill = rng.integer(0, 3000000);  // overdraw: up to 4 layers of the largest region
      double speed = speeds.empty() ? 1.0 : speeds[size_t(k)];
      s.ms = predictMs(kTruth, s) / speed * (1 + noise * (rng.integer(-1000, 1000) / 1000.0));
      out.push_back(s);
    }
  return out;
}

TEST(CostModel, RecoversTheCoefficientsOfNoiselessSamples) {
  Rng rng(1);
  CostModel m = fitCostModel(samples(rng, 10, 4, 0));
  ASSERT_TRUE(m.fitted);
  EXPECT_NEAR(m.per_drawn, kTruth.per_drawn, 1e-9);
  EXPECT_NEAR(m.per_triangle, kTruth.per_triangle, 1e-12);
  EXPECT_NEAR(m.per_tested, kTruth.per_tested, 1e-10);
  EXPECT_NEAR(m.per_pixel, kTruth.per_pixel, 1e-13);
  EXPECT_NEAR(m.per_fill, kTruth.per_fill, 1e-13);
}

TEST(CostModel, PredictsNoisySamplesWithinTheirNoise) {
  for (uint64_t seed = 1; seed <= 20; ++seed) {
    Rng rng(seed);
    CostModel m = fitCostModel(samples(rng, 24, 4, 0.1));
    ASSERT_TRUE(m.fitted) << seed;
    for (const CostSample& s : samples(rng, 5, 4, 0)) {
      double truth = predictMs(kTruth, s);
      EXPECT_NEAR(predictMs(m, s), truth, 0.1 * truth) << seed << " " << m;
    }
  }
}

TEST(CostModel, CoefficientsAreNeverNegative) {
  // Times that fall with the triangle count: an unconstrained fit would
  // give triangles a negative cost.
  std::vector<CostSample> s;
  for (int i = 0; i < 20; ++i) {
    CostSample c;
    c.client = i % 2;
    c.drawn = 10 + i;
    c.triangles = 1000 * (20 - i);
    c.tested = 5 + (i * 7) % 11;
    c.pixels = 1000 + 37 * i;
    c.ms = 1 + 0.1 * i;
    s.push_back(c);
  }
  CostModel m = fitCostModel(s);
  ASSERT_TRUE(m.fitted);
  for (double v : {m.per_drawn, m.per_triangle, m.per_tested, m.per_pixel, m.per_fill})
    EXPECT_GE(v, 0) << m;
}

TEST(CostModel, FillIsToldApartFromThePixelsOfTheRegion) {
  // Two regions of equal area, one empty and one under a few large objects:
  // the time follows the fill, not the area.
  std::vector<CostSample> s;
  for (int i = 0; i < 24; ++i) {
    CostSample c;
    c.client = i % 2;
    c.drawn = 5;
    c.triangles = 300;
    c.tested = 200;
    c.pixels = 200000 + 1000 * (i % 5);
    c.fill = c.client == 0 ? 0 : 400000 + 20000 * (i % 7);
    c.ms = 1 + 0.000005 * c.pixels + 0.00002 * c.fill;
    s.push_back(c);
  }
  CostModel m = fitCostModel(s);
  ASSERT_TRUE(m.fitted);
  EXPECT_NEAR(m.per_fill, 0.00002, 0.000002) << m;
  EXPECT_LT(m.per_pixel, 0.00001) << m;
}

TEST(CostModel, TooFewOrDegenerateSamplesAreUnfitted) {
  Rng rng(3);
  std::vector<CostSample> three = samples(rng, 1, 3, 0);
  EXPECT_FALSE(fitCostModel(three).fitted);
  std::vector<CostSample> zero(8);  // no work at all
  for (CostSample& s : zero) s.ms = 1;
  EXPECT_FALSE(fitCostModel(zero).fitted);
  std::vector<CostSample> bad = samples(rng, 2, 2, 0);
  for (CostSample& s : bad) s.ms = NAN;  // left out: nothing remains
  EXPECT_FALSE(fitCostModel(bad).fitted);
}

TEST(CostModel, FindsASlowClientAndLeavesEqualOnesAtOne) {
  for (uint64_t seed = 1; seed <= 10; ++seed) {
    Rng rng(seed);
    std::vector<double> speeds;
    fitCostsAndSpeeds(samples(rng, 24, 4, 0.1, {1, 0.5, 1, 1}), 4, &speeds);
    ASSERT_EQ(speeds.size(), 4u);
    // Normalised to a mean of 1: 1.14 for the three, 0.57 for the slow one.
    EXPECT_NEAR(speeds[1] / speeds[0], 0.5, 0.08) << seed;
    EXPECT_NEAR(speeds[2], speeds[0], 0.15) << seed;
    fitCostsAndSpeeds(samples(rng, 24, 4, 0.1), 4, &speeds);
    for (double s : speeds) EXPECT_EQ(s, 1.0) << seed;  // within the deadband
  }
}

// Debt feedback: a client slower than the mean on a frame runs into debt,
// which fades by kDebtMemory a frame and lowers its next shares.
TEST(ClientDebt, GrowsWithTimeAboveTheMeanAndFades) {
  std::vector<double> debt;
  double frame_ms = 0;
  std::vector<CostSample> frame(3);
  for (int k = 0; k < 3; ++k) frame[size_t(k)].client = k;
  frame[0].ms = 14, frame[1].ms = 10, frame[2].ms = 6;  // mean 10
  updateClientDebt(frame, &debt, &frame_ms);
  EXPECT_EQ(debt, (std::vector<double>{4, 0, -4}));
  EXPECT_EQ(frame_ms, 10);
  updateClientDebt(frame, &debt, &frame_ms);
  EXPECT_DOUBLE_EQ(debt[0], 4 * kDebtMemory + 4);
  EXPECT_DOUBLE_EQ(debt[2], -(4 * kDebtMemory + 4));
  // Equal times from now on: the debt fades geometrically, the order stays.
  for (CostSample& c : frame) c.ms = 20;
  double before = debt[0];
  updateClientDebt(frame, &debt, &frame_ms);
  EXPECT_DOUBLE_EQ(debt[0], before * kDebtMemory);
  EXPECT_DOUBLE_EQ(frame_ms, kDebtMemory * 10 + (1 - kDebtMemory) * 20);
  // A client without a finite time keeps its debt; the mean is of the others.
  frame[1].ms = std::nan("");
  frame[0].ms = 30, frame[2].ms = 10;
  std::vector<double> kept = debt;
  updateClientDebt(frame, &debt, &frame_ms);
  EXPECT_EQ(debt[1], kept[1]);
  EXPECT_DOUBLE_EQ(debt[0], kept[0] * kDebtMemory + 10);
}

TEST(ClientDebt, FactorsPayTheDebtBackWithinBounds) {
  // 10 ms a frame: a debt of 4 ms is paid back over kDebtFrames frames.
  std::vector<double> f = clientDebtFactors({4, 0, -4}, 10, 3);
  ASSERT_EQ(f.size(), 3u);
  EXPECT_DOUBLE_EQ(f[0], 1 - 4 / (kDebtFrames * 10));
  EXPECT_EQ(f[1], 1);
  EXPECT_DOUBLE_EQ(f[2], 1 + 4 / (kDebtFrames * 10));
  // Clamped to [1/2, 2]; no mean time, or a non-finite debt: 1.
  EXPECT_EQ(clientDebtFactors({1000, -1000}, 10, 2), (std::vector<double>{0.5, 2}));
  EXPECT_EQ(clientDebtFactors({4, -4}, 0, 2), (std::vector<double>{1, 1}));
  EXPECT_EQ(clientDebtFactors({std::nan(""), 4}, 10, 3),
            (std::vector<double>{1, 1 - 4 / (kDebtFrames * 10), 1}));
}

}  // namespace
}  // namespace dmmr
