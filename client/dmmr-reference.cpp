// dmmr-reference --scene DIR --walkthrough PATH --out DIR: ground-truth frames.
#include <CLI/CLI.hpp>
#include <cstdio>

#include "cli_options.h"
#include "error.h"
#include "memory_policy.h"
#include "reference.h"

int main(int argc, char** argv) {
  dmmr::ReferenceOptions o;
  std::string backend = "osmesa";
  CLI::App app{"dmmr-reference: render a walkthrough brute force (no culling), the ground truth"};
  dmmr::RunPaths paths;
  dmmr::addRunOptions(app, paths, o.view);
  app.add_option("--backend", backend, "osmesa or egl")->check(CLI::IsMember({"osmesa", "egl"}));
  app.add_option("--egl-device", o.context.egl_device, "EGL device index (-1: surfaceless)");
  app.add_flag("!--no-progress", o.progress, "do not print progress");
  app.add_option("--from-frame", o.from_frame,
                 "resume an interrupted run: render from this frame on (earlier frames and "
                 "their stats rows are kept)");
  dmmr::addFlushOption(app, &o.flush_triangles);
  dmmr::addCacheOptions(app, o.cache);
  bool keepMemory = true, hugePages = true;
  dmmr::addMemoryOptions(app, &keepMemory, &hugePages, &o.pre_touch_mib);
  dmmr::addConfigOption(app);
  app.add_flag("--exact-visible", o.exact_visible,
               "add the exactly visible objects and triangles (object-id render) to --stats");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return dmmr::exitParse(app, e);
  }
  dmmr::applyMemoryPolicy(keepMemory, hugePages, o.pre_touch_mib != 0, argv);
  try {
    o.scene = paths.scene;
    o.walkthrough = paths.walkthrough;
    o.out = paths.out;
    o.stats = paths.stats;
    o.context.backend = dmmr::parseBackend(backend);
    dmmr::runReference(o);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "dmmr-reference: %s\n", e.what());
    return 1;
  }
  return 0;
}
