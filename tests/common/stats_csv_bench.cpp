// Not a test: the cost of the stats CSV over a run, per frame, as the server
// wrote it before issue 14 (the whole file rewritten atomically every frame)
// and as it does now (StatsCsvAppender, one append per frame).
//   stats_csv_bench FRAMES ROW_BYTES DIR
// Prints the CPU (user+sys) and wall seconds of each, for the same rows.
#include <sys/resource.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "atomic_file.h"
#include "stats_csv.h"

namespace {

double cpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  auto s = [](timeval t) { return double(t.tv_sec) + double(t.tv_usec) * 1e-6; };
  return s(u.ru_utime) + s(u.ru_stime);
}

template <typename F>
void timed(const char* name, F f) {
  double c0 = cpuSeconds();
  auto w0 = std::chrono::steady_clock::now();
  f();
  double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - w0).count();
  std::printf("%-8s cpu %.3f s  wall %.3f s\n", name, cpuSeconds() - c0, wall);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 4) {
    std::fprintf(stderr, "usage: %s FRAMES ROW_BYTES DIR\n", argv[0]);
    return 2;
  }
  int frames = std::atoi(argv[1]);
  size_t row_bytes = size_t(std::atol(argv[2]));
  std::string dir = argv[3], header = "frame,frame_ms\n";
  std::string row(row_bytes - 1, '7');
  row += '\n';
  timed("rewrite", [&] {
    std::string csv = header;
    for (int f = 0; f < frames; ++f) {
      csv += row;
      dmmr::writeFileAtomic(dir + "/rewrite.csv", csv);
    }
  });
  timed("append", [&] {
    dmmr::StatsCsvAppender csv(dir + "/append.csv", header);
    for (int f = 0; f < frames; ++f) csv.append(row);
  });
  return 0;
}
