// SendBatch (common/mpi_comm.h) across processes: send_batch_probe under
// mpirun, its receivers holding off for 300 ms.
#include <gtest/gtest.h>

#include <cstdio>
#include <string>

#include "test_support.h"

namespace {

// The value after "key=" in the probe's line ("" when missing).
std::string field(const std::string& line, const std::string& key) {
  size_t at = line.find(key + "=");
  if (at == std::string::npos) return "";
  at += key.size() + 1;
  return line.substr(at, line.find_first_of(" \n", at) - at);
}

TEST(SendBatch, DeliversEveryMessageInOrderAndSleepsWhileReceiversAreLate) {
  int status = -1;
  std::string out = dmmr::test::runCapture(
      "timeout 120 " + dmmr::test::mpirun(3) + " " + dmmr::test::tool("send_batch_probe"), &status);
  ASSERT_EQ(status, 0) << out;
  // Both receivers got every message, in the order posted, byte for byte.
  EXPECT_EQ(field(out, "replies"), "ok;ok") << out;
  // The rendezvous-sized messages (three of six) were still in flight after
  // posting: the receivers had not polled yet.
  EXPECT_GE(std::stoi(field(out, "in_flight")), 3) << out;
  // wait() returned only once the late receivers took their messages...
  const double waited = std::stod(field(out, "waited_ms"));
  EXPECT_GE(waited, 150) << out;
  // ...and slept meanwhile: Open MPI's blocking send spins a core instead.
  EXPECT_LT(std::stod(field(out, "wait_cpu_ms")), 0.5 * waited) << out;
  // It named the oldest send in flight: rank 1's, then rank 2's.
  std::string told = field(out, "told");
  EXPECT_TRUE(told == "1,2" || told == "1" || told == "2") << out;
}

}  // namespace
