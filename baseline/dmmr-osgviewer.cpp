// dmmr-osgviewer --model FILE --walkthrough PATH --out DIR: the baseline,
// OpenSceneGraph's own single-node path on the original model.
#include <CLI/CLI.hpp>
#include <cstdio>

#include "cli_options.h"
#include "error.h"
#include "osg_baseline.h"

int main(int argc, char** argv) {
  dmmr::OsgViewerOptions o;
  CLI::App app{
      "dmmr-osgviewer: render a walkthrough of the original model with osgViewer (and "
      "osg::OcclusionQueryNode), headless through OSMesa: the benchmarks' OSG baseline"};
  app.add_option("--model", o.model, "model file osgDB reads (e.g. the scene generator's .osgb)")
      ->required();
  app.add_option("--walkthrough", o.walkthrough, "AnimationPath file")->required();
  app.add_option("--out", o.out, "output directory for frame_NNNNNN.png")->required();
  app.add_option("--stats", o.stats, "per-frame statistics CSV");
  app.add_option("--width", o.view.width, "image width")->check(CLI::Range(1, 16384));
  app.add_option("--height", o.view.height, "image height")->check(CLI::Range(1, 16384));
  app.add_option("--fovy", o.view.fovy_deg, "vertical field of view, degrees")
      ->check(dmmr::finiteRange(1.0, 179.0));
  app.add_option("--near", o.view.near,
                 "nearest near plane (default: model diagonal * 1e-5, as dmmr; OSG computes "
                 "near and far from what it draws and never goes closer than this)")
      ->check(CLI::PositiveNumber);
  dmmr::addSwitchOption(app, "--occlusion", &o.occlusion,
                        "insert osg::OcclusionQueryNode above groups");
  app.add_option("--min-vertices", o.queries.min_vertices,
                 "a group gets a query node when its subgraph has more vertices than this")
      ->capture_default_str();
  app.add_option("--visibility-threshold", o.queries.visibility_threshold,
                 "samples a query must pass, more than this (OSG's default 500; 0 is exact)")
      ->capture_default_str();
  app.add_option("--query-frame-count", o.queries.query_frame_count,
                 "frames between queries of a node (OSG's default 5; 1 is every frame)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_flag("!--no-progress", o.progress, "do not print progress");
  dmmr::addConfigOption(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return dmmr::exitParse(app, e);
  }
  try {
    dmmr::runOsgViewer(o);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "dmmr-osgviewer: %s\n", e.what());
    return 1;
  }
  return 0;
}
