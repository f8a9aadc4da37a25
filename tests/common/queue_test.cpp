// BoundedQueue: FIFO order, blocking when full or empty, close() waking both
// sides, and a two-thread transfer. Blocking calls run on std::async threads
// waited on with timeouts, so a broken queue fails the test instead of
// hanging it (a hung thread is then left detached; the process still ends).
#include <gtest/gtest.h>

#include <chrono>
#include <future>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <type_traits>
#include <vector>

#include "queue.h"

using namespace dmmr;
using namespace std::chrono_literals;

namespace {

// Long enough that a correct queue never misses it on a loaded machine.
constexpr auto kTimeout = 10s;
// How long a call must stay blocked to count as blocking.
constexpr auto kBlocked = 100ms;

// Runs `f` on its own thread. If the test gives up on it, the thread is
// detached (with the state it uses kept alive by shared_ptr) rather than
// joined, so that the test cannot hang.
template <typename F>
std::future<std::invoke_result_t<F>> startAsync(F f) {
  using R = std::invoke_result_t<F>;
  auto task = std::make_shared<std::packaged_task<R()>>(std::move(f));
  std::future<R> fut = task->get_future();
  std::thread([task] { (*task)(); }).detach();
  return fut;
}

// Runs `body` on its own thread and fails the test when it does not finish in
// time (a single-threaded sequence blocks forever if the queue miscounts).
// Every test body runs this way, so a broken queue can fail a test but never
// hang it.
template <typename F>
void runBounded(F body, std::chrono::seconds limit = 3 * kTimeout) {
  std::future<bool> done = startAsync([body] {
    body();
    return true;
  });
  ASSERT_EQ(done.wait_for(limit), std::future_status::ready) << "blocked: the queue hangs";
}

}  // namespace

TEST(BoundedQueue, FifoOrder) {
  runBounded([] {
    BoundedQueue<int> q(4);
    for (int i = 0; i < 4; ++i) EXPECT_TRUE(q.push(i));
    for (int i = 0; i < 4; ++i) EXPECT_EQ(q.pop(), i);
    // Interleaved, the ring wrapping around several times, never above capacity
    // (one item stays queued between rounds).
    int next_in = 0, next_out = 0;
    EXPECT_TRUE(q.push(next_in++));
    for (int round = 0; round < 20; ++round) {
      for (int k = 0; k < 3; ++k) EXPECT_TRUE(q.push(next_in++));
      for (int k = 0; k < 3; ++k) EXPECT_EQ(q.pop(), next_out++);
    }
    while (next_out < next_in) EXPECT_EQ(q.pop(), next_out++);
  });
}

TEST(BoundedQueue, MoveOnlyItems) {
  runBounded([] {
    BoundedQueue<std::unique_ptr<std::string>> q(2);
    EXPECT_TRUE(q.push(std::make_unique<std::string>("a")));
    EXPECT_TRUE(q.push(std::make_unique<std::string>("b")));
    auto a = q.pop();
    ASSERT_TRUE(a && *a);
    EXPECT_EQ(**a, "a");
    EXPECT_EQ(**q.pop(), "b");
  });
}

TEST(BoundedQueue, PushBlocksWhenFullUntilAPop) {
  runBounded([] {
    auto q = std::make_shared<BoundedQueue<int>>(2);
    ASSERT_TRUE(q->push(1));
    ASSERT_TRUE(q->push(2));
    std::future<bool> pushed = startAsync([q] { return q->push(3); });
    EXPECT_EQ(pushed.wait_for(kBlocked), std::future_status::timeout) << "push did not block";
    EXPECT_EQ(q->pop(), 1);
    ASSERT_EQ(pushed.wait_for(kTimeout), std::future_status::ready) << "pop did not wake push";
    EXPECT_TRUE(pushed.get());
    EXPECT_EQ(q->pop(), 2);
    EXPECT_EQ(q->pop(), 3);
  });
}

TEST(BoundedQueue, PopBlocksWhenEmptyUntilAPush) {
  runBounded([] {
    auto q = std::make_shared<BoundedQueue<int>>(1);
    std::future<std::optional<int>> popped = startAsync([q] { return q->pop(); });
    EXPECT_EQ(popped.wait_for(kBlocked), std::future_status::timeout) << "pop did not block";
    EXPECT_TRUE(q->push(42));
    ASSERT_EQ(popped.wait_for(kTimeout), std::future_status::ready) << "push did not wake pop";
    EXPECT_EQ(popped.get(), 42);
  });
}

TEST(BoundedQueue, CloseWakesABlockedPop) {
  runBounded([] {
    auto q = std::make_shared<BoundedQueue<int>>(3);
    std::future<std::optional<int>> popped = startAsync([q] { return q->pop(); });
    EXPECT_EQ(popped.wait_for(kBlocked), std::future_status::timeout) << "pop did not block";
    q->close();
    ASSERT_EQ(popped.wait_for(kTimeout), std::future_status::ready) << "close did not wake pop";
    EXPECT_EQ(popped.get(), std::nullopt);
    EXPECT_FALSE(q->push(1)) << "push after close";
    EXPECT_EQ(q->pop(), std::nullopt);
  });
}

TEST(BoundedQueue, CloseLetsConsumersDrainFirst) {
  runBounded([] {
    BoundedQueue<int> q(3);
    ASSERT_TRUE(q.push(1));
    ASSERT_TRUE(q.push(2));
    q.close();
    EXPECT_FALSE(q.push(3));
    EXPECT_EQ(q.pop(), 1);
    EXPECT_EQ(q.pop(), 2);
    EXPECT_EQ(q.pop(), std::nullopt);
    EXPECT_EQ(q.pop(), std::nullopt);
  });
}

TEST(BoundedQueue, CloseWakesABlockedPush) {
  runBounded([] {
    auto q = std::make_shared<BoundedQueue<int>>(1);
    ASSERT_TRUE(q->push(1));
    std::future<bool> pushed = startAsync([q] { return q->push(2); });
    EXPECT_EQ(pushed.wait_for(kBlocked), std::future_status::timeout) << "push did not block";
    q->close();
    ASSERT_EQ(pushed.wait_for(kTimeout), std::future_status::ready) << "close did not wake push";
    EXPECT_FALSE(pushed.get());
    EXPECT_EQ(q->pop(), 1);  // what was queued before close still drains
    EXPECT_EQ(q->pop(), std::nullopt);
  });
}

TEST(BoundedQueue, CloseWakesEveryBlockedThread) {
  runBounded([] {
    // Several pops blocked on an empty queue: notify_all must reach them all.
    auto q = std::make_shared<BoundedQueue<int>>(2);
    std::vector<std::future<std::optional<int>>> pops;
    for (int i = 0; i < 4; ++i) pops.push_back(startAsync([q] { return q->pop(); }));
    EXPECT_EQ(pops[0].wait_for(kBlocked), std::future_status::timeout);
    q->close();
    for (auto& p : pops) {
      ASSERT_EQ(p.wait_for(kTimeout), std::future_status::ready);
      EXPECT_EQ(p.get(), std::nullopt);
    }
  });
}

TEST(BoundedQueue, ProducerConsumerTransfersInOrder) {
  runBounded(
      [] {
        constexpr int kItems = 100000;
        auto q = std::make_shared<BoundedQueue<int>>(2);  // small: both sides block often
        std::future<bool> producer = startAsync([q] {
          for (int i = 0; i < kItems; ++i)
            if (!q->push(i)) return false;
          q->close();
          return true;
        });
        std::future<int> consumer = startAsync([q] {
          int expected = 0;
          while (auto v = q->pop()) {
            if (*v != expected) return -1 - expected;  // out of order
            ++expected;
          }
          return expected;
        });
        ASSERT_EQ(producer.wait_for(60s), std::future_status::ready) << "producer hung";
        ASSERT_EQ(consumer.wait_for(kTimeout), std::future_status::ready) << "consumer hung";
        EXPECT_TRUE(producer.get());
        EXPECT_EQ(consumer.get(), kItems);
      },
      5 * kTimeout);
}
