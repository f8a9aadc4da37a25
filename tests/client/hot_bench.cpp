// Benchmark (not a test): the client's hot paths of issue 14, each timed over
// many iterations, medians printed.
//
//   hot_bench merge              mergeSorted against sort + unique of the
//                                concatenation (the code it replaced), side by side
//   hot_bench readback [W H]     one sub-frame's readback to RGB: fresh buffers
//                                and a byte loop (the old code), kept buffers
//                                and a 4-to-3 loop or rgbaToRgb,
//                                glReadPixels(GL_RGB)
//   hot_bench depth [N]          a depth pass of N small occluders
//                                (Renderer::drawDepth), llvmpipe (OSMesa)
//   hot_bench shade [N [HALF]]   a shading pass of N objects (quads of half
//                                size HALF, default 0.02, at 5-15 m), each its
//                                own colour (Renderer::draw), llvmpipe
//   hot_bench frame [W H]        a client's fixed steps a frame (clear,
//                                readbacks) for a region of 1/16 of W x H
//
// Times are CPU seconds of the process (llvmpipe's threads included) unless
// the column says wall; run it on an otherwise quiet machine, or compare
// only numbers taken side by side.
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "draw.h"
#include "gl_context.h"
#include "image.h"
#include "visibility.h"

using namespace dmmr;

namespace {

double cpuMs() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return double(t.tv_sec) * 1e3 + double(t.tv_nsec) * 1e-6;
}
double wallMs() {
  return std::chrono::duration<double, std::milli>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

struct Timing {
  double cpu_ms, wall_ms;
};

// Medians over `reps` runs of `iters` calls of `f`, per call.
Timing time(int reps, int iters, const std::function<void()>& f) {
  std::vector<double> cpu, wall;
  for (int r = 0; r < reps; ++r) {
    double c0 = cpuMs(), w0 = wallMs();
    for (int i = 0; i < iters; ++i) f();
    cpu.push_back((cpuMs() - c0) / iters);
    wall.push_back((wallMs() - w0) / iters);
  }
  std::sort(cpu.begin(), cpu.end());
  std::sort(wall.begin(), wall.end());
  return {cpu[cpu.size() / 2], wall[wall.size() / 2]};
}

std::vector<uint32_t> randomSubset(std::mt19937& rng, uint32_t n, double p) {
  std::bernoulli_distribution keep(p);
  std::vector<uint32_t> out;
  for (uint32_t i = 0; i < n; ++i)
    if (keep(rng)) out.push_back(i);
  return out;
}

std::vector<uint32_t> sortUnique(const std::vector<std::vector<uint32_t>>& lists) {
  std::vector<uint32_t> out;
  for (const auto& l : lists) out.insert(out.end(), l.begin(), l.end());
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

int merge() {
  std::printf("%8s %8s %8s %14s %14s %8s\n", "objects", "lists", "total", "sort_us", "merge_us",
              "ratio");
  std::mt19937 rng(14);
  for (uint32_t n : {1000u, 10000u, 100000u})
    for (int k : {2, 3}) {
      // The client's shapes: a visible set (a tenth of the region) with the
      // few that passed or were marked.
      std::vector<std::vector<uint32_t>> lists = {randomSubset(rng, n, 0.1)};
      for (int i = 1; i < k; ++i) lists.push_back(randomSubset(rng, n, 0.02));
      size_t total = 0;
      for (const auto& l : lists) total += l.size();
      if (sortUnique(lists) != mergeSorted(lists)) return std::fprintf(stderr, "mismatch\n"), 1;
      int iters = int(2'000'000 / total) + 1;
      size_t sink = 0;
      Timing a = time(15, iters, [&] { sink += sortUnique(lists).size(); });
      Timing b = time(15, iters, [&] { sink += mergeSorted(lists).size(); });
      std::printf("%8u %8d %8zu %14.2f %14.2f %7.2fx%s\n", n, k, total, a.cpu_ms * 1e3,
                  b.cpu_ms * 1e3, a.cpu_ms / b.cpu_ms, sink == 0 ? " " : "");
    }
  return 0;
}

int readback(int w, int h) {
  auto ctx = createContext({Backend::OSMesa, -1});
  const GlApi& gl = ctx->gl();
  Renderer r(gl, w, h);
  Camera cam;
  Rect region{0, 0, w, h};
  r.beginFrame(cam, region);
  r.finish();
  size_t n = size_t(region.area());
  std::vector<uint8_t> keep_rgba, keep_rgb;
  size_t sink = 0;
  // The old code: fresh buffers each frame, a byte loop over the channels.
  Timing a = time(15, 20, [&] {
    std::vector<uint8_t> rgba, rgb;
    r.readPixels(region, &rgba);
    rgb.resize(n * 3);
    for (size_t i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c) rgb[i * 3 + c] = rgba[i * 4 + c];
    sink += rgb[n];
  });
  // Buffers kept across frames, 4-to-3 pointer loop.
  Timing b = time(15, 20, [&] {
    r.readPixels(region, &keep_rgba);
    keep_rgb.resize(n * 3);
    const uint8_t* s = keep_rgba.data();
    uint8_t* d = keep_rgb.data();
    for (size_t i = 0; i < n; ++i, s += 4, d += 3) {
      d[0] = s[0];
      d[1] = s[1];
      d[2] = s[2];
    }
    sink += keep_rgb[n];
  });
  // Kept buffers, rgbaToRgb (one 4-byte copy per pixel): the new code.
  Timing e = time(15, 20, [&] {
    r.readPixels(region, &keep_rgba);
    keep_rgb.resize(n * 3);
    rgbaToRgb(keep_rgba.data(), n, keep_rgb.data());
    sink += keep_rgb[n];
  });
  // GL converts: RGB rows, packed.
  Timing c = time(15, 20, [&] {
    keep_rgb.resize(n * 3);
    gl.PixelStorei(GL_PACK_ALIGNMENT, 1);
    gl.ReadPixels(0, 0, w, h, GL_RGB, GL_UNSIGNED_BYTE, keep_rgb.data());
    gl.PixelStorei(GL_PACK_ALIGNMENT, 4);
    sink += keep_rgb[n];
  });
  // RGBA alone (what any variant reads before converting).
  Timing d = time(15, 20, [&] {
    r.readPixels(region, &keep_rgba);
    sink += keep_rgba[n];
  });
  gl.check("readback bench");
  std::printf("%dx%d, ms per readback (CPU / wall):\n", w, h);
  std::printf("  old (fresh buffers, byte loop)   %7.3f / %7.3f\n", a.cpu_ms, a.wall_ms);
  std::printf("  kept buffers, 4-to-3 loop         %7.3f / %7.3f\n", b.cpu_ms, b.wall_ms);
  std::printf("  kept buffers, rgbaToRgb           %7.3f / %7.3f\n", e.cpu_ms, e.wall_ms);
  std::printf("  glReadPixels GL_RGB, alignment 1  %7.3f / %7.3f\n", c.cpu_ms, c.wall_ms);
  std::printf("  glReadPixels GL_RGBA alone        %7.3f / %7.3f%s\n", d.cpu_ms, d.wall_ms,
              sink == 1 ? " " : "");
  return 0;
}

// At the origin looking down -Z, 60 degrees vertically.
Camera benchCamera(double aspect = 1) {
  Camera cam;
  cam.eye = {0, 0, 0};
  cam.fovy_deg = 60;
  cam.aspect = aspect;
  cam.near = 0.1;
  return cam;
}

// N quads (two triangles; at the default half size of 2 cm, a few pixels
// each) spread over the view: small, the per-object cost, not the fill, is
// what a pass of them pays for.
struct Quads {
  std::vector<GpuMesh> meshes;
  std::vector<Box3d> boxes;
  std::vector<Mat4d> transforms;
};
Quads smallQuads(Renderer& r, int count, double s = 0.02) {
  Quads q;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int i = 0; i < count; ++i) {
    double z = -5 - 5 * (u(rng) + 1), x = u(rng) * 2, y = u(rng) * 2;
    GeometryData g;
    g.positions = {float(x - s), float(y - s), float(z), float(x + s), float(y - s), float(z),
                   float(x + s), float(y + s), float(z), float(x - s), float(y + s), float(z)};
    g.indices = {0, 1, 2, 0, 2, 3};
    SubMesh sm;
    sm.index_count = 6;
    float shade = float(i % 7) / 7.f;
    sm.diffuse[0] = shade;
    g.submeshes = {sm};
    q.meshes.push_back(r.upload(g));
    Box3d b;
    b.expand(Vec3d{x - s, y - s, z});
    b.expand(Vec3d{x + s, y + s, z});
    q.boxes.push_back(b);
    q.transforms.push_back(Mat4d::identity());
  }
  return q;
}

// A shading pass (Renderer::draw) of N quads of half size `half` (metres,
// at 5 to 15 m), each its own colour.
int shade(int count, double half) {
  const int size = 512;
  auto ctx = createContext({Backend::OSMesa, -1});
  Renderer r(ctx->gl(), size, size);
  Camera cam = benchCamera();
  Quads q = smallQuads(r, count, half);
  Rect region{0, 0, size, size};
  Timing t = time(15, 10, [&] {
    r.beginFrame(cam, region);
    for (int i = 0; i < count; ++i)
      r.draw(q.meshes[size_t(i)], q.transforms[size_t(i)], q.boxes[size_t(i)], {});
    r.finish();
  });
  ctx->gl().check("shade bench");
  std::printf(
      "shading pass of %d objects (half size %.3f m) at %dx%d: %.3f ms CPU, %.3f ms wall "
      "(%.2f us CPU each)\n",
      count, half, size, size, t.cpu_ms, t.wall_ms, t.cpu_ms * 1e3 / count);
  for (GpuMesh& m : q.meshes) r.release(m);
  return 0;
}

// One client's fixed cost a frame at W x H with a region of a sixteenth of
// the frame: clear, one draw, depth and colour readbacks, each step timed.
int frame(int w, int h) {
  auto ctx = createContext({Backend::OSMesa, -1});
  Renderer r(ctx->gl(), w, h);
  Camera cam = benchCamera(double(w) / h);
  Quads q = smallQuads(r, 1);
  Rect region{w / 4, h / 4, w / 4, h / 4};
  std::vector<uint8_t> rgba;
  std::vector<float> depth;
  auto step = [&](const char* what, const std::function<void()>& f) {
    Timing t = time(15, 20, f);
    std::printf("  %-44s %7.3f ms CPU %7.3f ms wall\n", what, t.cpu_ms, t.wall_ms);
  };
  std::printf("frame steps at %dx%d, region %dx%d:\n", w, h, region.w, region.h);
  step("beginFrame + finish", [&] {
    r.beginFrame(cam, region);
    r.finish();
  });
  step("beginFrame + one small draw + finish", [&] {
    r.beginFrame(cam, region);
    r.draw(q.meshes[0], q.transforms[0], q.boxes[0], {});
    r.finish();
  });
  step("beginFrame + readDepth(region)", [&] {
    r.beginFrame(cam, region);
    r.readDepth(region, &depth);
  });
  step("beginFrame + readPixels(region)", [&] {
    r.beginFrame(cam, region);
    r.readPixels(region, &rgba);
  });
  step("beginFrame + draw + readDepth + draw + readPixels", [&] {
    r.beginFrame(cam, region);
    r.draw(q.meshes[0], q.transforms[0], q.boxes[0], {});
    r.readDepth(region, &depth);
    r.draw(q.meshes[0], q.transforms[0], q.boxes[0], {});
    r.readPixels(region, &rgba);
  });
  r.release(q.meshes[0]);
  return 0;
}

int depth(int count) {
  const int size = 512;
  auto ctx = createContext({Backend::OSMesa, -1});
  Renderer r(ctx->gl(), size, size);
  Camera cam = benchCamera();
  Quads q = smallQuads(r, count);
  Rect region{0, 0, size, size};
  Timing t = time(15, 10, [&] {
    r.beginDepthFrame(cam, region);
    for (int i = 0; i < count; ++i)
      r.drawDepth(q.meshes[size_t(i)], q.transforms[size_t(i)], q.boxes[size_t(i)], false);
    r.finish();
  });
  ctx->gl().check("depth bench");
  std::printf("depth pass of %d occluders at %dx%d: %.3f ms CPU, %.3f ms wall (%.2f us CPU each)\n",
              count, size, size, t.cpu_ms, t.wall_ms, t.cpu_ms * 1e3 / count);
  for (GpuMesh& m : q.meshes) r.release(m);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  std::string what = argc > 1 ? argv[1] : "";
  if (what == "merge") return merge();
  if (what == "readback")
    return readback(argc > 3 ? std::atoi(argv[2]) : 512, argc > 3 ? std::atoi(argv[3]) : 512);
  if (what == "depth") return depth(argc > 2 ? std::atoi(argv[2]) : 2000);
  if (what == "shade")
    return shade(argc > 2 ? std::atoi(argv[2]) : 2000, argc > 3 ? std::atof(argv[3]) : 0.02);
  if (what == "frame")
    return frame(argc > 3 ? std::atoi(argv[2]) : 1024, argc > 3 ? std::atoi(argv[3]) : 768);
  std::fprintf(
      stderr,
      "usage: hot_bench merge | readback [W H] | depth [N] | shade [N [HALF]] | frame [W H]\n");
  return 2;
}
