#include "reference.h"

#include "run_settings.h"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "atomic_file.h"
#include "draw.h"
#include "error.h"
#include "gpu_cache.h"
#include "host_cache.h"
#include "image.h"
#include "memory_policy.h"
#include "scene.h"
#include "stats_csv.h"
#include "walkthrough.h"

namespace dmmr {

namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

Image toImage(int w, int h, const std::vector<uint8_t>& bottomUp) {
  Image img;
  img.width = w;
  img.height = h;
  img.rgba.resize(bottomUp.size());
  size_t row = size_t(w) * 4;
  for (int y = 0; y < h; ++y)
    std::copy_n(bottomUp.data() + size_t(h - 1 - y) * row, row, img.rgba.data() + size_t(y) * row);
  return img;
}

struct ExactVisible {
  uint64_t objects = 0, triangles = 0;
  std::vector<uint32_t> list;  // ascending
};

// Objects owning at least one pixel of the frame, from an object-id render.
ExactVisible exactVisible(const Scene& scene, GpuCache& meshes, Renderer& r, const Camera& cam,
                          const Rect& full) {
  r.beginIdFrame(cam, full);
  for (uint32_t i = 0; i < scene.objects.size(); ++i)
    if (const GpuMesh* mesh = meshes.acquire(scene.objects[i].geometry))
      r.drawId(*mesh, scene.objects[i].transform, scene.objects[i].box, i);
  std::vector<uint8_t> px;
  r.readPixels(full, &px);
  std::vector<uint8_t> seen(scene.objects.size(), 0);
  ExactVisible ev;
  for (size_t p = 0; p < px.size(); p += 4) {
    uint32_t v = px[p] | (uint32_t(px[p + 1]) << 8) | (uint32_t(px[p + 2]) << 16);
    if (v == 0 || v > scene.objects.size() || seen[v - 1]) continue;
    seen[v - 1] = 1;
    ++ev.objects;
    ev.triangles += scene.objects[v - 1].weight;
  }
  for (uint32_t i = 0; i < scene.objects.size(); ++i)
    if (seen[i]) ev.list.push_back(i);
  return ev;
}

}  // namespace

void runReference(const ReferenceOptions& opts) {
  Scene scene = loadScene(opts.scene);
  Walkthrough path = readWalkthrough(opts.walkthrough);
  if (opts.from_frame >= path.points.size())
    throw Error("--from-frame " + std::to_string(opts.from_frame) + " is not a frame of " +
                opts.walkthrough + " (" + std::to_string(path.points.size()) + " frames)");
  std::string header = "frame,frame_ms,draw_ms,objects,triangles";
  header += opts.exact_visible ? ",exact_visible_objects,exact_visible_triangles,floor_ms\n" : "\n";
  std::string csv = resumeStatsCsv(opts.stats, header, opts.from_frame);
  std::filesystem::create_directories(opts.out);
  RunSettings settings = baseRunSettings(opts.scene, opts.walkthrough, opts.view);
  settings.add("renderer", "reference");
  if (opts.from_frame > 0) checkResume(opts.out, settings, uint32_t(opts.from_frame));
  writeRunSettings(opts.out, settings);
  // The input checked, before the caches start to grow (memory_policy.h).
  preTouchHeap(preTouchBytes(opts.pre_touch_mib, scene.manifest.geometry_bytes));

  auto ctx = createContext(opts.context);
  Renderer renderer(ctx->gl(), opts.view.width, opts.view.height);
  const uint64_t flush_default = defaultFlushTriangles(ctx->gl()),
                 flush = flushTrianglesFor(ctx->gl(), opts.flush_triangles);
  renderer.setFlushEvery(flush);

  // With unlimited budgets every geometry is uploaded once, on first use;
  // instances share it.
  HostCache host(scene,
                 HostCacheOptions{opts.cache.ram_budget, opts.cache.ram_dir, opts.cache.eviction});
  RendererBackend backend(renderer);
  GpuCache meshes(scene, host, backend, opts.cache.gpu_budget, opts.cache.eviction);

  double near = opts.view.near > 0 ? opts.view.near : defaultNear(scene);
  Rect full{0, 0, opts.view.width, opts.view.height};
  std::vector<uint8_t> pixels;
  for (size_t f = opts.from_frame; f < path.points.size(); ++f) {
    auto t0 = Clock::now();
    Camera cam =
        cameraAt(path.points[f], opts.view.width, opts.view.height, opts.view.fovy_deg, near);
    renderer.beginFrame(cam, full);
    meshes.nextFrame();
    host.nextFrame();
    uint64_t tris = 0;
    for (const ObjectBounds& o : scene.objects) {  // ascending object index
      const GpuMesh* mesh = meshes.acquire(o.geometry);
      if (!mesh) continue;  // unreadable geometry: warned about, skipped
      renderer.draw(*mesh, o.transform, o.box, meshes.textures());
      tris += mesh->triangles;
    }
    renderer.readPixels(full, &pixels);
    double draw_ms = msSince(t0);
    writePng(opts.out + "/" + frameFileName(f), toImage(opts.view.width, opts.view.height, pixels));
    double frame_ms = msSince(t0);
    char line[160];
    std::snprintf(line, sizeof line, "%zu,%.3f,%.3f,%zu,%llu", f, frame_ms, draw_ms,
                  scene.objects.size(), static_cast<unsigned long long>(tris));
    csv += line;
    if (opts.exact_visible) {
      ExactVisible ev = exactVisible(scene, meshes, renderer, cam, full);
      // The fill-rate floor: the same frame drawn from the exactly visible
      // set alone (what a perfect culler would leave), read back; the
      // pixels equal the frame's. Geometry is resident by now.
      auto tf = Clock::now();
      renderer.setFlushEvery(flush_default);
      renderer.beginFrame(cam, full);
      for (uint32_t i : ev.list)
        if (const GpuMesh* mesh = meshes.acquire(scene.objects[i].geometry))
          renderer.draw(*mesh, scene.objects[i].transform, scene.objects[i].box, meshes.textures());
      std::vector<uint8_t> floor;
      renderer.readPixels(full, &floor);
      double floor_ms = msSince(tf);
      renderer.setFlushEvery(flush);
      DMMR_CHECK(floor == pixels);
      std::snprintf(line, sizeof line, ",%llu,%llu,%.3f",
                    static_cast<unsigned long long>(ev.objects),
                    static_cast<unsigned long long>(ev.triangles), floor_ms);
      csv += line;
    }
    csv += "\n";
    if (!opts.stats.empty()) writeFileAtomic(opts.stats, csv);  // flushed as frames finish
    if (opts.progress)
      std::fprintf(stderr, "\rdmmr-reference: frame %zu/%zu (%.0f ms)", f + 1, path.points.size(),
                   frame_ms);
  }
  if (opts.progress) std::fprintf(stderr, "\n");
}

}  // namespace dmmr
