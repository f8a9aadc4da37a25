// The interactive mode's policy on plain data: latest pose wins, viewers take
// turns, one frame in flight per viewer with newer frames replacing held
// ones, and the still frame once a viewer stops moving.
#include <gtest/gtest.h>

#include <random>

#include "viewer_schedule.h"

using namespace dmmr;

namespace {

Pose pose(uint32_t seq) {
  Pose p;
  p.seq = seq;
  p.position = {double(seq), 0, 0};
  return p;
}

}  // namespace

TEST(ViewerSchedule, RendersOnlyTheLatestPoseAndDropsStaleOnes) {
  ViewerSchedule s(1, 250);
  s.add(1);
  EXPECT_TRUE(s.pose(1, pose(1), 0));
  EXPECT_TRUE(s.pose(1, pose(2), 1));
  EXPECT_TRUE(s.pose(1, pose(5), 2));
  EXPECT_FALSE(s.pose(1, pose(4), 3)) << "older than the latest: stale";
  EXPECT_FALSE(s.pose(1, pose(5), 3)) << "same seq: stale";
  auto pick = s.next();
  ASSERT_TRUE(pick);
  EXPECT_EQ(pick->pose.seq, 5u);
  EXPECT_FALSE(s.next()) << "nothing newer to render";
  EXPECT_FALSE(s.pose(9, pose(1), 0)) << "unknown viewer";
}

TEST(ViewerSchedule, AViewerHasAtMostMaxRenderingFramesInThePipeline) {
  ViewerSchedule s(2, 250);
  s.add(1);
  s.pose(1, pose(1), 0);
  ASSERT_TRUE(s.next());
  s.pose(1, pose(2), 1);
  ASSERT_TRUE(s.next());
  s.pose(1, pose(3), 2);
  EXPECT_FALSE(s.next()) << "two rendering already";
  s.rendered(1, 0, 1);
  auto pick = s.next();
  ASSERT_TRUE(pick);
  EXPECT_EQ(pick->pose.seq, 3u);
}

TEST(ViewerSchedule, ViewersTakeTurns) {
  ViewerSchedule s(1, 250);
  for (uint64_t v : {10, 20, 30}) s.add(v);
  std::vector<uint64_t> order;
  uint32_t frame = 0;
  for (uint32_t round = 1; round <= 4; ++round) {
    for (uint64_t v : {10, 20, 30}) s.pose(v, pose(round), round);
    for (int i = 0; i < 3; ++i) {
      auto pick = s.next();
      ASSERT_TRUE(pick);
      order.push_back(pick->viewer);
      s.rendered(pick->viewer, frame++, pick->pose.seq);
      s.acked(pick->viewer, frame - 1);
    }
  }
  for (size_t i = 3; i < order.size(); ++i) EXPECT_NE(order[i], order[i - 1]) << i;
  for (uint64_t v : {10, 20, 30}) EXPECT_EQ(std::count(order.begin(), order.end(), v), 4);
}

TEST(ViewerSchedule, AFastViewerDoesNotStarveASlowOne) {
  // Viewer 1 sends a pose before every pick; viewer 2 sends one pose. Viewer
  // 2's pose is rendered within one turn of viewer 1's.
  ViewerSchedule s(1, 250);
  s.add(1);
  s.add(2);
  s.pose(1, pose(1), 0);
  auto first = s.next();
  ASSERT_TRUE(first);
  EXPECT_EQ(first->viewer, 1u);
  s.rendered(1, 0, 1);
  s.pose(2, pose(1), 1);
  s.pose(1, pose(2), 1);
  auto second = s.next();
  ASSERT_TRUE(second);
  EXPECT_EQ(second->viewer, 2u);
}

TEST(ViewerSchedule, OneFrameInFlightANewerOneReplacesTheHeldOne) {
  ViewerSchedule s(1, 250);
  s.add(1);
  uint32_t frame = 0;
  auto render = [&](uint32_t seq) {
    s.pose(1, pose(seq), seq);
    auto pick = s.next();
    EXPECT_TRUE(pick);
    return s.rendered(1, frame++, seq);
  };
  EXPECT_EQ(render(1), ViewerSchedule::Delivery::Send);
  EXPECT_EQ(s.inFlight(1), 0u);
  EXPECT_EQ(render(2), ViewerSchedule::Delivery::Hold);
  EXPECT_EQ(render(3), ViewerSchedule::Delivery::Hold);
  EXPECT_EQ(s.held(1), 2u) << "frame 2 (pose 3) replaced frame 1 (pose 2)";
  EXPECT_FALSE(s.acked(1, 7)) << "an ack of a frame not in flight changes nothing";
  EXPECT_EQ(s.inFlight(1), 0u);
  EXPECT_EQ(s.acked(1, 0), 2u) << "the held frame goes next";
  EXPECT_EQ(s.inFlight(1), 2u);
  EXPECT_FALSE(s.held(1));
  EXPECT_FALSE(s.acked(1, 2)) << "nothing held";
  EXPECT_FALSE(s.inFlight(1));
}

TEST(ViewerSchedule, StillFrameIsDueOnceAfterTheViewerStops) {
  ViewerSchedule s(1, 250);
  s.add(1);
  s.pose(1, pose(1), 1000);
  s.next();
  EXPECT_TRUE(s.dueStills(2000).empty()) << "still rendering";
  s.rendered(1, 0, 1);
  EXPECT_TRUE(s.dueStills(2000).empty()) << "its frame is in flight";
  s.acked(1, 0);
  EXPECT_TRUE(s.dueStills(1100).empty()) << "moved 100 ms ago";
  auto due = s.dueStills(1300);
  ASSERT_EQ(due.size(), 1u);
  EXPECT_EQ(due[0], (ViewerSchedule::Still{1, 0}));
  EXPECT_EQ(s.inFlight(1), 0u) << "the still is in flight until acked";
  s.acked(1, 0);
  EXPECT_TRUE(s.dueStills(5000).empty()) << "once per pose";
  // A newer pose not yet rendered: no still for the old one.
  s.pose(1, pose(2), 6000);
  EXPECT_TRUE(s.dueStills(7000).empty());
  s.next();
  s.rendered(1, 1, 2);
  s.acked(1, 1);
  due = s.dueStills(7000);
  ASSERT_EQ(due.size(), 1u);
  EXPECT_EQ(due[0].frame, 1u);
}

TEST(ViewerSchedule, FramesOfAViewerThatLeftAreGone) {
  ViewerSchedule s(1, 250);
  s.add(1);
  s.add(2);
  s.pose(1, pose(1), 0);
  s.next();
  s.remove(1);
  EXPECT_EQ(s.rendered(1, 0, 1), ViewerSchedule::Delivery::Gone);
  EXPECT_FALSE(s.next());
  EXPECT_EQ(s.size(), 1u);
}

TEST(ViewerSchedule, RandomisedInvariantsHold) {
  // Fixed seed: random poses, picks, completions and acks for 4 viewers.
  // Invariants: never more than max_rendering per viewer rendering, a picked
  // pose is always that viewer's latest, seqs picked per viewer increase.
  std::mt19937 rng(17);
  const int kMax = 2;
  ViewerSchedule s(kMax, 50);
  std::map<uint64_t, uint32_t> seq, last_picked;
  std::map<uint64_t, std::vector<std::pair<uint32_t, uint32_t>>> rendering;  // frame, seq
  uint32_t frame = 0;
  double now = 0;
  for (uint64_t v = 1; v <= 4; ++v) s.add(v);
  for (int step = 0; step < 20000; ++step) {
    now += 1;
    uint64_t v = 1 + rng() % 4;
    switch (rng() % 4) {
      case 0:
        s.pose(v, pose(++seq[v]), now);
        break;
      case 1:
        if (auto pick = s.next()) {
          EXPECT_EQ(pick->pose.seq, seq[pick->viewer]);
          EXPECT_GT(pick->pose.seq, last_picked[pick->viewer]);
          last_picked[pick->viewer] = pick->pose.seq;
          rendering[pick->viewer].push_back({frame++, pick->pose.seq});
          EXPECT_LE(int(rendering[pick->viewer].size()), kMax);
        }
        break;
      case 2:
        if (!rendering[v].empty()) {
          auto [f, q] = rendering[v].front();
          rendering[v].erase(rendering[v].begin());
          s.rendered(v, f, q);
        }
        break;
      case 3:
        if (auto f = s.inFlight(v)) s.acked(v, *f);
        for (const auto& still : s.dueStills(now)) EXPECT_EQ(s.inFlight(still.viewer), still.frame);
        break;
    }
  }
}
