// The CPUs a rank may use, and the warning when a client has too few for its
// GL stages (mpirun's default binding of one core per rank).
#include <gtest/gtest.h>

#include <pthread.h>
#include <sched.h>

#include <string>
#include <thread>

#include "affinity.h"

using namespace dmmr;

namespace {
bool contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}
}  // namespace

TEST(PlacementWarning, EmptyWhenTheClientHasEnoughCpus) {
  EXPECT_EQ(placementWarning(1, 2, 2), "");
  EXPECT_EQ(placementWarning(3, 16, 2), "");
}

TEST(PlacementWarning, NamesTheRankAndBothCountsWhenTooFew) {
  std::string w = placementWarning(1, 1, 2);
  EXPECT_TRUE(contains(w, "client rank 1 ")) << w;
  EXPECT_TRUE(contains(w, "may use 1 CPU ")) << w;
  EXPECT_TRUE(contains(w, "want 2;")) << w;
  EXPECT_TRUE(contains(w, "--bind-to none")) << w;
  EXPECT_EQ(w.find('\n'), std::string::npos) << w;

  w = placementWarning(7, 3, 4);
  EXPECT_TRUE(contains(w, "client rank 7 ")) << w;
  EXPECT_TRUE(contains(w, "may use 3 CPUs ")) << w;
  EXPECT_TRUE(contains(w, "want 4;")) << w;
}

TEST(AllowedCpuCount, CountsTheAffinityMask) {
  cpu_set_t set;
  CPU_ZERO(&set);
  ASSERT_EQ(::sched_getaffinity(0, sizeof set, &set), 0);
  int before = allowedCpuCount();
  EXPECT_GE(before, 1);
  EXPECT_EQ(before, CPU_COUNT(&set));

  // A thread's own mask narrowed to one, then (where there are) two of the
  // allowed CPUs: the count follows; the main thread's is unchanged.
  int first = -1, second = -1;
  for (int cpu = 0; cpu < CPU_SETSIZE && second < 0; ++cpu) {
    if (!CPU_ISSET(cpu, &set)) continue;
    if (first < 0)
      first = cpu;
    else
      second = cpu;
  }
  ASSERT_GE(first, 0);
  int one = 0, two = 0, rcOne = -1, rcTwo = -1;
  std::thread t([&] {
    cpu_set_t narrow;
    CPU_ZERO(&narrow);
    CPU_SET(first, &narrow);
    rcOne = ::sched_setaffinity(0, sizeof narrow, &narrow);
    one = allowedCpuCount();
    if (second >= 0) {
      CPU_SET(second, &narrow);
      rcTwo = ::sched_setaffinity(0, sizeof narrow, &narrow);
      two = allowedCpuCount();
    }
  });
  t.join();
  ASSERT_EQ(rcOne, 0);
  EXPECT_EQ(one, 1);
  if (second >= 0) {
    ASSERT_EQ(rcTwo, 0);
    EXPECT_EQ(two, 2);
  }
  EXPECT_EQ(allowedCpuCount(), before);
}

// What a thread reads back as its own name (pthread_getname_np).
static std::string ownName() {
  char buf[64] = {};
  pthread_getname_np(pthread_self(), buf, sizeof buf);
  return buf;
}

TEST(NameThisThread, NamesOnlyTheCallingThread) {
  std::string before = ownName(), inside;
  std::thread([&] {
    dmmr::nameThisThread("dmmr-draw");
    inside = ownName();
  }).join();
  EXPECT_EQ(inside, "dmmr-draw");
  EXPECT_EQ(ownName(), before);
}

TEST(NameThisThread, KeepsTheFirstFifteenCharactersOfALongName) {
  std::string inside;
  std::thread([&] {
    dmmr::nameThisThread("dmmr-visibility-stage");  // 21 characters: Linux keeps 15
    inside = ownName();
  }).join();
  EXPECT_EQ(inside, "dmmr-visibility");
}
