// Benchmark (not a test): how fast a scene's geometry files decode, from
// bytes in memory to GeometryData (container checksum included), whatever
// their encoding.
//
//   codec_bench SCENE_DIR [RUNS]     default RUNS: 7
//
// Prints one line: encoding, geometry files, unique vertices, unique
// triangles, geometry file bytes, the median seconds of RUNS passes over all
// files, and triangles/s.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "atomic_file.h"
#include "error.h"
#include "formats.h"
#include "scene.h"

using namespace dmmr;

int main(int argc, char** argv) {
  if (argc < 2 || argc > 3) {
    std::fprintf(stderr, "usage: codec_bench SCENE_DIR [RUNS]\n");
    return 2;
  }
  int runs = argc == 3 ? std::atoi(argv[2]) : 7;
  try {
    Scene s = loadScene(argv[1], false);
    std::vector<std::vector<uint8_t>> files;
    std::vector<std::string> names;
    uint64_t bytes = 0, triangles = 0, vertices = 0;
    for (uint32_t g = 0; g < s.manifest.geometries; ++g) {
      names.push_back(s.dir + "/" + geometryFileName(g));
      files.push_back(readFileBytes(names.back()));
      bytes += files.back().size();
    }
    std::vector<double> seconds;
    for (int run = 0; run < std::max(1, runs); ++run) {
      uint64_t t = 0, v = 0;
      auto t0 = std::chrono::steady_clock::now();
      for (size_t i = 0; i < files.size(); ++i) {
        GeometryData g = decodeGeometry(files[i], names[i]);
        t += g.triangleCount();
        v += g.vertexCount();
      }
      seconds.push_back(
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
      triangles = t;
      vertices = v;
    }
    std::sort(seconds.begin(), seconds.end());
    double median = seconds[seconds.size() / 2];
    std::printf("%s %zu %llu %llu %llu %.6f %.0f\n", encodingName(s.manifest.encoding),
                files.size(), (unsigned long long)vertices, (unsigned long long)triangles,
                (unsigned long long)bytes, median, median > 0 ? double(triangles) / median : 0.0);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "codec_bench: %s\n", e.what());
    return 1;
  }
  return 0;
}
