// The cost model of fitted division weights (server/cost_model.h): the fit
// recovers known coefficients from noisy samples (fixed seeds), never goes
// negative, refuses degenerate data, and finds a slow client's speed.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <iostream>
#include <vector>

#include "cost_model.h"
#include "server_test_util.h"

namespace dmmr {
namespace {

using test::Rng;

const CostModel kTruth{0.02, 0.0005, 0.003, 0.00001, 0.000004, 0.0002, true};

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
      s.fill = rng.integer(0, 3000000);   // overdraw: up to 4 layers of the largest region
      s.raster = rng.integer(0, 100000);  // at most one triangle a footprint pixel
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
  EXPECT_NEAR(m.per_raster, kTruth.per_raster, 1e-12);
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
  for (double v :
       {m.per_drawn, m.per_triangle, m.per_tested, m.per_pixel, m.per_fill, m.per_raster})
    EXPECT_GE(v, 0) << m;
}

// 24 samples of two clients taking turns, sample i made by `make(i, client)`.
std::vector<CostSample> twoClients(const std::function<CostSample(int, int)>& make) {
  std::vector<CostSample> s;
  for (int i = 0; i < 24; ++i) {
    s.push_back(make(i, i % 2));
    s.back().client = i % 2;
  }
  return s;
}

TEST(CostModel, FillIsToldApartFromThePixelsOfTheRegion) {
  // Two regions of equal area, one empty and one under a few large objects:
  // the time follows the fill, not the area.
  CostModel m = fitCostModel(twoClients([](int i, int client) {
    CostSample c{.drawn = 5, .triangles = 300, .tested = 200};
    c.pixels = 200000 + 1000 * (i % 5);
    c.fill = client == 0 ? 0 : 400000 + 20000 * (i % 7);
    c.ms = 1 + 0.000005 * c.pixels + 0.00002 * c.fill;
    return c;
  }));
  ASSERT_TRUE(m.fitted);
  EXPECT_NEAR(m.per_fill, 0.00002, 0.000002) << m;
  EXPECT_LT(m.per_pixel, 0.00001) << m;
}

TEST(CostModel, RasterIsToldApartFromTheTriangles) {
  // Two regions drawing as many triangles, one of near objects (every
  // triangle set up) and one of far ones (the triangle cull keeps about one a
  // pixel): the time follows the rasterised triangles.
  CostModel m = fitCostModel(twoClients([](int i, int client) {
    CostSample c{.drawn = 40,
                 .triangles = 400000.0 + 10000 * (i % 5),
                 .tested = 200,
                 .pixels = 100000,
                 .fill = 150000.0 + 5000 * (i % 3)};
    c.raster = client == 0 ? c.triangles : 30000 + 2000 * (i % 7);
    c.ms = 2 + 0.00003 * c.triangles + 0.0002 * c.raster;
    return c;
  }));
  ASSERT_TRUE(m.fitted);
  EXPECT_NEAR(m.per_raster, 0.0002, 0.00002) << m;
  EXPECT_NEAR(m.per_triangle, 0.00003, 0.00001) << m;
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

TEST(ClientDebt, ProjectedDebtTakesOffWhatTheFramesInFlightPay) {
  auto near = [](const std::vector<double>& a, const std::vector<double>& b) {
    if (a.size() != b.size()) return false;
    for (size_t i = 0; i < a.size(); ++i)
      if (std::abs(a[i] - b[i]) > 1e-12) return false;
    return true;
  };
  // 10 ms a frame: a factor of 0.8 takes 2 ms off, 1.2 adds 2.
  EXPECT_TRUE(near(projectedDebt({4, 0, -4}, {{0.8, 1, 1.2}}, 10), {2, 0, -2}));
  EXPECT_TRUE(near(projectedDebt({4, 0, -4}, {{0.8, 1, 1.2}, {0.9, 1, 1.1}}, 10), {1, 0, -1}));
  // Nothing in flight, no mean time: the debt as measured.
  EXPECT_EQ(projectedDebt({4, -4}, {}, 10), (std::vector<double>{4, -4}));
  EXPECT_EQ(projectedDebt({4, -4}, {{0.5, 2}}, 0), (std::vector<double>{4, -4}));
  // A factor missing (fewer clients then) or not finite counts as 1.
  EXPECT_TRUE(near(projectedDebt({4, 0, -4}, {{0.8}, {std::nan(""), 1, 1.2}}, 10), {2, 0, -2}));
}

// The closed loop catching up runs in, on plain data: clients whose time is
// their share times a lasting bias and a noise that drifts from frame to
// frame (fixed seeds), each frame's times known to the planner only
// `in_flight` frames after it was planned, as in the pipeline. Planning on
// the measured debt alone pays every debt again in each frame planned before
// the first payment shows, so the clients take turns at being the slowest;
// planning on the projected debt evens single frames better than not
// catching up at all, and the clients' means as well as the measured debt
// does.
struct LoopResult {
  double frame_max_over_mean = 0;  // median over frames
  double means_max_over_mean = 0;  // the busiest client's mean over the mean
};
enum class CatchUp { Off, Measured, Projected };
LoopResult catchUpLoop(CatchUp mode, uint64_t seed, int clients = 4, int frames = 400,
                       int in_flight = 3) {
  Rng rng(seed);
  std::vector<double> bias(size_t(clients), 0.0), drift(size_t(clients), 0.0);
  for (double& b : bias) b = rng.real(-0.25, 0.25);
  std::vector<double> debt(size_t(clients), 0.0), sums(size_t(clients), 0.0), ratios;
  double frame_ms = 0;
  std::vector<std::vector<CostSample>> measured;  // frame f's times, reported at f + in_flight
  std::vector<std::vector<double>> factors;       // the catching-up factors each frame used
  for (int f = 0; f < frames; ++f) {
    if (f >= in_flight) updateClientDebt(measured[size_t(f - in_flight)], &debt, &frame_ms);
    std::vector<double> fac(size_t(clients), 1.0);
    if (mode == CatchUp::Measured) fac = clientDebtFactors(debt, frame_ms, clients);
    if (mode == CatchUp::Projected) {
      std::vector<std::vector<double>> planned;
      for (int g = std::max(0, f - in_flight + 1); g < f; ++g)
        planned.push_back(factors[size_t(g)]);
      fac = clientDebtFactors(projectedDebt(debt, planned, frame_ms), frame_ms, clients);
    }
    factors.push_back(fac);
    double total = 0;
    for (double x : fac) total += x;
    std::vector<CostSample> frame;
    double mean = 0, max = 0;
    for (int k = 0; k < clients; ++k) {
      double& d = drift[size_t(k)];
      d = 0.7 * d + rng.real(-0.25, 0.25);
      CostSample s;
      s.client = k;
      s.ms = 10.0 * clients * fac[size_t(k)] / total * (1 + bias[size_t(k)] + d);
      frame.push_back(s);
      mean += s.ms / clients;
      max = std::max(max, s.ms);
      if (f >= 50) sums[size_t(k)] += s.ms;
    }
    measured.push_back(frame);
    if (f >= 50) ratios.push_back(max / mean);
  }
  std::sort(ratios.begin(), ratios.end());
  LoopResult r;
  r.frame_max_over_mean = ratios[ratios.size() / 2];
  double mean = 0, max = 0;
  for (double s : sums) mean += s / clients, max = std::max(max, s);
  r.means_max_over_mean = max / mean;
  return r;
}

TEST(ClientDebt, PlanningOnTheProjectedDebtEvensFramesAndMeans) {
  double frame[3] = {0, 0, 0}, means[3] = {0, 0, 0};
  const int seeds = 20;
  for (uint64_t seed = 1; seed <= seeds; ++seed) {
    int i = 0;
    for (CatchUp mode : {CatchUp::Off, CatchUp::Measured, CatchUp::Projected}) {
      LoopResult r = catchUpLoop(mode, seed);
      frame[i] += r.frame_max_over_mean / seeds;
      means[i] += r.means_max_over_mean / seeds;
      ++i;
    }
  }
  std::cout << "per-frame max/mean off " << frame[0] << ", measured " << frame[1] << ", projected "
            << frame[2] << "; the means' max/mean " << means[0] << ", " << means[1] << ", "
            << means[2] << "\n";
  EXPECT_GT(frame[1], frame[0]) << "catching up on the measured debt rings";
  EXPECT_LT(frame[2], frame[0]) << "the projected debt evens single frames";
  EXPECT_LT(means[1], means[0]);
  EXPECT_LT(means[2], means[0]);
  EXPECT_LT(means[2] - 1, 0.5 * (means[0] - 1)) << "and most of the means' imbalance";
}

}  // namespace
}  // namespace dmmr
