// dmmr-reference --scene DIR --walkthrough PATH --out DIR: ground-truth frames.
#include <CLI/CLI.hpp>
#include <cstdio>

#include "error.h"
#include "reference.h"

int main(int argc, char** argv) {
  dmmr::ReferenceOptions o;
  std::string backend = "osmesa";
  CLI::App app{"dmmr-reference: render a walkthrough brute force (no culling), the ground truth"};
  app.add_option("--scene", o.scene, "preprocessed scene directory")->required();
  app.add_option("--walkthrough", o.walkthrough, "AnimationPath file")->required();
  app.add_option("--out", o.out, "output directory for frame_NNNNNN.png")->required();
  app.add_option("--stats", o.stats, "per-frame CSV");
  app.add_option("--width", o.view.width, "image width")->check(CLI::Range(1, 16384));
  app.add_option("--height", o.view.height, "image height")->check(CLI::Range(1, 16384));
  app.add_option("--fovy", o.view.fovy_deg, "vertical field of view, degrees")
      ->check(CLI::Range(1.0, 179.0));
  app.add_option("--near", o.view.near, "near plane distance (default: scene diagonal * 1e-5)")
      ->check(CLI::PositiveNumber);
  app.add_option("--backend", backend, "osmesa or egl")->check(CLI::IsMember({"osmesa", "egl"}));
  app.add_option("--egl-device", o.context.egl_device, "EGL device index (-1: surfaceless)");
  app.add_flag("!--no-progress", o.progress, "do not print progress");
  app.add_flag("--exact-visible", o.exact_visible,
               "add the exactly visible objects and triangles (object-id render) to --stats");
  CLI11_PARSE(app, argc, argv);
  try {
    o.context.backend = dmmr::parseBackend(backend);
    dmmr::runReference(o);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "dmmr-reference: %s\n", e.what());
    return 1;
  }
  return 0;
}
