// Not a test by itself: send_batch_test runs it with `mpirun -np 3`.
// Rank 0 posts, in one SendBatch, messages of eager and rendezvous sizes to
// ranks 1 and 2, which take them only after sleeping kHoldMs; it then waits
// for the batch and prints what it saw. Ranks 1 and 2 check every message's
// order, tag, size and bytes and answer "ok" or what was wrong.
// Rank 0 prints one line:
//   "in_flight=<after posting> waited_ms=<wall> wait_cpu_ms=<thread CPU>
//    told=<the destinations wait() named, distinct, in order> replies=<ok|...>"
#include <chrono>
#include <cstdio>
#include <string>
#include <thread>
#include <vector>

#include "cpu_time.h"
#include "mpi_comm.h"

namespace {

constexpr int kHoldMs = 300;
// Per destination: the sizes posted, in order (eager ones, a few KiB and up
// go by rendezvous on Open MPI's shared memory).
const std::vector<std::vector<size_t>> kSizes = {{16, size_t(1) << 20, 8, 300 << 10},
                                                 {size_t(2) << 20, 0}};

std::vector<uint8_t> pattern(int dest, size_t index, size_t size) {
  std::vector<uint8_t> b(size);
  for (size_t i = 0; i < size; ++i) b[i] = uint8_t(dest * 31 + index * 7 + i * 13);
  return b;
}

}  // namespace

int main(int argc, char** argv) {
  dmmr::Comm comm(&argc, &argv);
  if (comm.size() != 3) {
    std::fprintf(stderr, "send_batch_probe: run with 3 ranks\n");
    return 2;
  }
  if (comm.rank() != 0) {
    std::this_thread::sleep_for(std::chrono::milliseconds(kHoldMs));
    const auto& sizes = kSizes[size_t(comm.rank() - 1)];
    std::string verdict = "ok";
    for (size_t i = 0; i < sizes.size(); ++i) {
      dmmr::Message m = comm.recv(0);
      if (m.tag != dmmr::Tag::Job || m.bytes != pattern(comm.rank(), i, sizes[i]))
        verdict =
            "rank " + std::to_string(comm.rank()) + " message " + std::to_string(i) + " differs";
    }
    comm.send(0, dmmr::Tag::Bye, std::vector<uint8_t>(verdict.begin(), verdict.end()));
    return 0;
  }
  dmmr::SendBatch batch(comm);
  for (int dest = 1; dest <= 2; ++dest)
    for (size_t i = 0; i < kSizes[size_t(dest - 1)].size(); ++i)
      batch.post(dest, dmmr::Tag::Job, pattern(dest, i, kSizes[size_t(dest - 1)][i]));
  const size_t in_flight = batch.inFlight();
  std::string told;
  int last = 0;
  auto t0 = std::chrono::steady_clock::now();
  const double c0 = dmmr::threadCpuMs();
  batch.wait([&](int dest) {
    if (dest != last) told += (told.empty() ? "" : ",") + std::to_string(last = dest);
  });
  const double cpu = dmmr::threadCpuMs() - c0;
  const double wall =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  std::string replies;
  for (int k = 0; k < 2; ++k) {
    dmmr::Message m = comm.recv(dmmr::kAnySource);
    replies += (replies.empty() ? "" : ";") + std::string(m.bytes.begin(), m.bytes.end());
  }
  std::printf("in_flight=%zu waited_ms=%.0f wait_cpu_ms=%.1f told=%s replies=%s\n", in_flight, wall,
              cpu, told.c_str(), replies.c_str());
  return 0;
}
