// dmmr-netem-probe: what an MPI link between rank 0 and rank 1 measures.
//
//   mpirun -np 2 dmmr-netem-probe [--pings P] [--bytes B] [--reps R]
//
// Latency: P ping-pongs of 1 byte (after 20 warm-up ones, which also open the
// TCP connections); prints the round trip's min, median, mean and max.
// Throughput: R times, rank 0 sends one message of B bytes (default 8 MiB) to
// rank 1, which answers with 1 byte; the transfer time is from the send to
// the answer, less one median one-way latency for the answer. Prints each and
// the median, as key=value lines (docs/netem.md). Other ranks only wait.
#include <mpi.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <numeric>
#include <string>
#include <vector>

namespace {

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

}  // namespace

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  int rank = 0, size = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  long pings = 50, bytes = 8L << 20, reps = 3;
  for (int i = 1; i + 1 < argc; i += 2) {
    std::string a = argv[i];
    long v = std::strtol(argv[i + 1], nullptr, 10);
    if (a == "--pings") {
      pings = v;
    } else if (a == "--bytes") {
      bytes = v;
    } else if (a == "--reps") {
      reps = v;
    } else {
      if (rank == 0) std::fprintf(stderr, "dmmr-netem-probe: unknown option %s\n", argv[i]);
      MPI_Abort(MPI_COMM_WORLD, 2);
    }
  }
  if (size < 2 || pings < 1 || bytes < 1 || reps < 1) {
    if (rank == 0) std::fprintf(stderr, "dmmr-netem-probe: needs 2 ranks, positive counts\n");
    MPI_Abort(MPI_COMM_WORLD, 2);
  }

  char name[MPI_MAX_PROCESSOR_NAME] = {};
  int len = 0;
  MPI_Get_processor_name(name, &len);
  std::vector<char> names(size_t(size) * MPI_MAX_PROCESSOR_NAME);
  MPI_Gather(name, MPI_MAX_PROCESSOR_NAME, MPI_CHAR, names.data(), MPI_MAX_PROCESSOR_NAME, MPI_CHAR,
             0, MPI_COMM_WORLD);

  if (rank <= 1) {
    const int peer = 1 - rank;
    char b = 0;
    std::vector<double> rtt;
    for (long i = 0; i < 20 + pings; ++i) {
      double t = MPI_Wtime();
      if (rank == 0) {
        MPI_Send(&b, 1, MPI_CHAR, peer, 0, MPI_COMM_WORLD);
        MPI_Recv(&b, 1, MPI_CHAR, peer, 0, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        if (i >= 20) rtt.push_back(MPI_Wtime() - t);
      } else {
        MPI_Recv(&b, 1, MPI_CHAR, peer, 0, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        MPI_Send(&b, 1, MPI_CHAR, peer, 0, MPI_COMM_WORLD);
      }
    }
    std::vector<char> data(size_t(bytes), 'x');
    std::vector<double> transfer;
    const double oneWay = rank == 0 ? median(rtt) / 2 : 0;
    for (long r = 0; r < reps; ++r) {
      if (rank == 0) {
        double t = MPI_Wtime();
        MPI_Send(data.data(), int(bytes), MPI_CHAR, peer, 1, MPI_COMM_WORLD);
        MPI_Recv(&b, 1, MPI_CHAR, peer, 1, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        transfer.push_back(MPI_Wtime() - t - oneWay);
      } else {
        MPI_Recv(data.data(), int(bytes), MPI_CHAR, peer, 1, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        MPI_Send(&b, 1, MPI_CHAR, peer, 1, MPI_COMM_WORLD);
      }
    }
    if (rank == 0) {
      for (int r = 0; r < size; ++r)
        std::printf("rank%d=%s\n", r, &names[size_t(r) * MPI_MAX_PROCESSOR_NAME]);
      std::sort(rtt.begin(), rtt.end());
      double mean = std::accumulate(rtt.begin(), rtt.end(), 0.0) / double(rtt.size());
      std::printf(
          "pings=%ld\nrtt_ms_min=%.3f\nrtt_ms_median=%.3f\nrtt_ms_mean=%.3f\nrtt_ms_max=%.3f\n",
          pings, rtt.front() * 1e3, median(rtt) * 1e3, mean * 1e3, rtt.back() * 1e3);
      std::printf("one_way_ms=%.3f\nbytes=%ld\n", oneWay * 1e3, bytes);
      for (long r = 0; r < reps; ++r) std::printf("transfer_s_%ld=%.4f\n", r, transfer[size_t(r)]);
      double t = median(transfer);
      std::printf("transfer_s=%.4f\nthroughput_mbit=%.2f\n", t, double(bytes) * 8 / t / 1e6);
      std::fflush(stdout);
    }
  }
  MPI_Barrier(MPI_COMM_WORLD);
  MPI_Finalize();
  return 0;
}
