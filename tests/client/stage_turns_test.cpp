// StageTurns (--stage-turns): holders of one lock file never overlap, within
// a process (each StageTurns is its own open file) as across processes; and
// threadCpuMs counts the calling thread alone.
#include <gtest/gtest.h>
#include <poll.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <memory>
#include <thread>

#include "cpu_time.h"
#include "error.h"
#include "stage_turns.h"

namespace dmmr {
namespace {

namespace fs = std::filesystem;

std::string lockPath(const char* name) {
  return (fs::temp_directory_path() /
          (std::string("dmmr-turns-") + name + "-" + std::to_string(::getpid())))
      .string();
}

TEST(StageTurns, TwoStagesInOneProcessNeverHoldTheTurnAtOnce) {
  std::string path = lockPath("threads");
  std::atomic<int> inside{0}, most{0};
  auto stage = [&] {
    StageTurns turns(path);
    for (int i = 0; i < 300; ++i) {
      StageTurns::Hold hold(&turns);
      int now = ++inside;
      for (int seen = most.load(); now > seen && !most.compare_exchange_weak(seen, now);) {
      }
      std::this_thread::yield();  // give the other stage a chance to overlap
      --inside;
    }
  };
  std::thread a(stage), b(stage);
  a.join();
  b.join();
  EXPECT_EQ(most.load(), 1);
  fs::remove(path);
}

TEST(StageTurns, AnotherProcessWaitsForTheTurn) {
  std::string path = lockPath("processes");
  StageTurns mine(path);
  mine.take();
  int ready[2], done[2];
  ASSERT_EQ(::pipe(ready), 0);
  ASSERT_EQ(::pipe(done), 0);
  pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    StageTurns theirs(path);
    char c = 'r';
    (void)!::write(ready[1], &c, 1);
    theirs.take();  // blocks until the parent gives the turn up
    c = 't';
    (void)!::write(done[1], &c, 1);
    ::_exit(0);
  }
  char c = 0;
  ASSERT_EQ(::read(ready[0], &c, 1), 1);
  // The child is at take(): while the turn is held it must not get it.
  pollfd early{done[0], POLLIN, 0};
  EXPECT_EQ(::poll(&early, 1, 200), 0) << "the other process took the turn while it was held";
  mine.give();
  ASSERT_EQ(::read(done[0], &c, 1), 1);
  EXPECT_EQ(c, 't');
  int status = 0;
  ::waitpid(child, &status, 0);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  fs::remove(path);
}

TEST(StageTurns, AnUnopenableLockFileIsAnErrorNamingIt) {
  try {
    StageTurns t("/nonexistent-dir-dmmr/turns.lock");
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent-dir-dmmr/turns.lock"), std::string::npos)
        << e.what();
  }
}

TEST(ThreadCpuTime, CountsTheCallingThreadOnlyNotTheProcess) {
  std::atomic<bool> stop{false};
  double spun = 0;
  std::thread spinner([&] {
    double t0 = threadCpuMs();
    volatile uint64_t x = 0;
    while (threadCpuMs() - t0 < 100) x = x + 1;  // 100 ms of this thread's CPU
    spun = threadCpuMs() - t0;
    stop = true;
  });
  double mine0 = threadCpuMs();
  auto wall0 = std::chrono::steady_clock::now();
  while (!stop) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  double mine = threadCpuMs() - mine0;
  double wall =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - wall0).count();
  spinner.join();
  EXPECT_GE(spun, 100);
  // The sleeping thread used little CPU while the other spun 100 ms (a
  // process-wide clock would show at least 100 ms here).
  EXPECT_LT(mine, 50) << "wall " << wall;
}

TEST(ThreadUsage, CountsTheCallingThreadsPageFaultsAndKernelTime) {
  // 64 MiB touched page by page on another thread: at least one fault per
  // 4 KiB page there (fewer with huge pages: then at least one per 2 MiB),
  // nearly none here, and the kernel time of zeroing them is within that
  // thread's CPU time.
  constexpr size_t kBytes = size_t(64) << 20;
  ThreadUsage theirs{};
  double their_cpu = 0;
  ThreadUsage mine0 = threadUsage();
  std::thread toucher([&] {
    ThreadUsage u0 = threadUsage();
    double c0 = threadCpuMs();
    std::unique_ptr<char[]> block(new char[kBytes]);
    volatile char* bytes = block.get();  // volatile: the stores are not elided
    for (size_t i = 0; i < kBytes; i += 4096) bytes[i] = char(i);
    ThreadUsage u1 = threadUsage();
    their_cpu = threadCpuMs() - c0;
    theirs = {u1.sys_ms - u0.sys_ms, u1.minor_faults - u0.minor_faults};
  });
  toucher.join();
  ThreadUsage mine1 = threadUsage();
  EXPECT_GE(theirs.minor_faults, kBytes / (2u << 20));
  EXPECT_LT(mine1.minor_faults - mine0.minor_faults, 64u);
  EXPECT_GE(theirs.sys_ms, 0);
  EXPECT_LE(theirs.sys_ms, their_cpu + 1.0);
}

}  // namespace
}  // namespace dmmr
