// The cache's LRU policy on its own, and byte-size parsing: plain data.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "budget.h"
#include "lru.h"
#include "test_support.h"

using namespace dmmr;
using Keys = std::vector<uint32_t>;

TEST(LruBudget, EvictsLeastRecentlyUsedFirst) {
  LruBudget lru(100, Eviction::Lru);
  Keys evicted;
  lru.insert(1, 40, &evicted);
  lru.insert(2, 40, &evicted);
  EXPECT_TRUE(lru.touch(1));  // 2 is now the least recently used
  lru.insert(3, 40, &evicted);
  EXPECT_EQ(evicted, Keys{2});
  EXPECT_EQ(lru.order(), (Keys{1, 3}));
  EXPECT_EQ(lru.used(), 80u);
}

TEST(LruBudget, EvictsAsManyAsItTakes) {
  LruBudget lru(100, Eviction::Lru);
  Keys evicted;
  for (uint32_t k = 0; k < 5; ++k) lru.insert(k, 20, &evicted);
  EXPECT_TRUE(evicted.empty());
  lru.insert(9, 70, &evicted);
  EXPECT_EQ(evicted, (Keys{0, 1, 2, 3}));
  EXPECT_EQ(lru.order(), (Keys{4, 9}));
  EXPECT_EQ(lru.used(), 90u);
}

TEST(LruBudget, TouchOfAnAbsentKeyChangesNothing) {
  LruBudget lru(10, Eviction::Lru);
  Keys evicted;
  lru.insert(1, 5, &evicted);
  EXPECT_FALSE(lru.touch(2));
  EXPECT_EQ(lru.order(), Keys{1});
}

TEST(LruBudget, AdmitsNothingLargerThanTheBudget) {
  LruBudget lru(64);
  EXPECT_TRUE(lru.admits(64));
  EXPECT_FALSE(lru.admits(65));
  EXPECT_FALSE(LruBudget(0).admits(1));
  EXPECT_TRUE(LruBudget(0).admits(0));
  EXPECT_TRUE(LruBudget().admits(uint64_t(1) << 62));
}

TEST(LruBudget, InsertIfFreeNeverEvicts) {
  LruBudget lru(100, Eviction::Lru);
  Keys evicted;
  lru.insert(1, 60, &evicted);
  EXPECT_FALSE(lru.insertIfFree(2, 41));
  EXPECT_EQ(lru.order(), Keys{1});
  EXPECT_TRUE(lru.insertIfFree(2, 40));
  EXPECT_EQ(lru.used(), 100u);
}

TEST(LruBudget, EraseReturnsTheBytesFreed) {
  LruBudget lru(100, Eviction::Lru);
  Keys evicted;
  lru.insert(7, 33, &evicted);
  EXPECT_EQ(lru.erase(7), 33u);
  EXPECT_EQ(lru.erase(7), 0u);
  EXPECT_EQ(lru.used(), 0u);
  EXPECT_EQ(lru.size(), 0u);
}

TEST(LruBudget, FrameLruEvictsTheFramesNewestWhenTheFrameOverflows) {
  LruBudget lru(30, Eviction::FrameLru);
  Keys evicted;
  lru.insert(1, 10, &evicted);
  lru.nextFrame();
  lru.insert(2, 10, &evicted);
  lru.insert(3, 10, &evicted);
  lru.insert(4, 10, &evicted);  // 1 is from an earlier frame: plain LRU
  EXPECT_EQ(evicted, Keys{1});
  lru.insert(5, 10, &evicted);  // all from this frame: the newest goes
  EXPECT_EQ(evicted, (Keys{1, 4}));
  EXPECT_EQ(lru.order(), (Keys{2, 3, 5}));
}

// A walkthrough that draws the same 10 entries in the same order every
// frame through room for 6: LRU misses every time, FrameLru keeps 5 of them.
TEST(LruBudget, FrameLruKeepsPartOfAWorkingSetLargerThanTheBudget) {
  for (Eviction e : {Eviction::Lru, Eviction::FrameLru}) {
    LruBudget lru(60, e);
    int hits = 0;
    for (int frame = 0; frame < 10; ++frame) {
      lru.nextFrame();
      for (uint32_t k = 0; k < 10; ++k) {
        Keys evicted;
        if (lru.touch(k))
          hits += frame > 0;
        else
          lru.insert(k, 10, &evicted);
      }
    }
    EXPECT_EQ(hits, e == Eviction::Lru ? 0 : 9 * 5) << int(e);
  }
}

// Fixed-seed random operations against a plain model (a vector in use
// order, with the frame of each use): same evictions, same contents, and
// never above the budget, for both policies.
TEST(LruBudget, MatchesAPlainModelUnderRandomOperations) {
  std::mt19937 rng(20261122);
  for (Eviction policy : {Eviction::Lru, Eviction::FrameLru})
    for (uint64_t budget : {0u, 1u, 50u, 200u, 1000u}) {
      LruBudget lru(budget, policy);
      struct E {
        uint32_t key;
        uint64_t bytes, frame;
      };
      std::vector<E> model;  // least recently used first
      uint64_t frame = 0;
      std::vector<uint64_t> size(40);
      for (auto& s : size) s = rng() % 120;
      for (int step = 0; step < 5000; ++step) {
        if (rng() % 50 == 0) {
          lru.nextFrame();
          ++frame;
        }
        uint32_t key = rng() % 40;
        auto it = std::find_if(model.begin(), model.end(), [&](auto& e) { return e.key == key; });
        int op = int(rng() % 3);
        if (op == 0 && it != model.end()) {  // a hit
          E e = *it;
          e.frame = frame;
          model.erase(it);
          model.push_back(e);
          ASSERT_TRUE(lru.touch(key));
        } else if (op == 1 && it == model.end() && lru.admits(size[key])) {  // a miss
          Keys evicted, expected;
          uint64_t used = 0;
          for (auto& e : model) used += e.bytes;
          while (budget - used < size[key]) {
            auto victim = policy == Eviction::FrameLru && model.front().frame == frame
                              ? model.end() - 1
                              : model.begin();
            expected.push_back(victim->key);
            used -= victim->bytes;
            model.erase(victim);
          }
          model.push_back({key, size[key], frame});
          lru.insert(key, size[key], &evicted);
          ASSERT_EQ(evicted, expected);
        } else if (op == 2) {
          uint64_t want = it == model.end() ? 0 : it->bytes;
          if (it != model.end()) model.erase(it);
          ASSERT_EQ(lru.erase(key), want);
        }
        Keys order;
        uint64_t used = 0;
        for (auto& e : model) {
          order.push_back(e.key);
          used += e.bytes;
        }
        ASSERT_EQ(lru.order(), order);
        ASSERT_EQ(lru.used(), used);
        ASSERT_LE(lru.used(), budget);
      }
    }
}

TEST(ByteSize, ParsesCountsAndBinaryUnits) {
  EXPECT_EQ(parseByteSize("0"), 0u);
  EXPECT_EQ(parseByteSize("512"), 512u);
  EXPECT_EQ(parseByteSize("512B"), 512u);
  EXPECT_EQ(parseByteSize("4K"), 4096u);
  EXPECT_EQ(parseByteSize("4kb"), 4096u);
  EXPECT_EQ(parseByteSize("3M"), 3u << 20);
  EXPECT_EQ(parseByteSize("3MiB"), 3u << 20);
  EXPECT_EQ(parseByteSize("2G"), uint64_t(2) << 30);
  EXPECT_EQ(parseByteSize("1T"), uint64_t(1) << 40);
  EXPECT_EQ(parseByteSize("unlimited"), LruBudget::kUnlimited);
}

TEST(ByteSize, RejectsWhatIsNotASize) {
  EXPECT_NE(test::errorOf([] { parseByteSize(""); }).find("does not start with a number"),
            std::string::npos);
  EXPECT_NE(test::errorOf([] { parseByteSize("M"); }).find("does not start with a number"),
            std::string::npos);
  EXPECT_NE(test::errorOf([] { parseByteSize("-1"); }).find("does not start with a number"),
            std::string::npos);
  EXPECT_NE(test::errorOf([] { parseByteSize("12X"); }).find("unknown unit"), std::string::npos);
  EXPECT_NE(test::errorOf([] { parseByteSize("1.5G"); }).find("unknown unit"), std::string::npos);
  EXPECT_NE(test::errorOf([] { parseByteSize("99999999999999999999"); }).find("too large"),
            std::string::npos);
  EXPECT_NE(test::errorOf([] { parseByteSize("20000000T"); }).find("too large"), std::string::npos);
}

TEST(ByteSize, FormatsForPeople) {
  EXPECT_EQ(formatByteSize(LruBudget::kUnlimited), "unlimited");
  EXPECT_EQ(formatByteSize(1000), "1000 B");
  EXPECT_EQ(formatByteSize(3u << 20), "3.0 MiB");
}
