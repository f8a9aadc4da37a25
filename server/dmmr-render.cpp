// mpirun -np N+1 dmmr-render --scene DIR --walkthrough PATH --out DIR
// Rank 0 is the server; ranks 1..N are clients.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "affinity.h"
#include "cli_options.h"
#include "client.h"
#include "error.h"
#include "memory_policy.h"
#include "protocol.h"
#include "run_settings.h"
#include "server.h"

int main(int argc, char** argv) {
  dmmr::ServerOptions s;
  dmmr::ClientOptions c;
  std::string backend = "osmesa", codec = "lz4";
  CLI::App app{"dmmr-render: distributed rendering of a walkthrough (rank 0 server, 1..N clients)"};
  dmmr::RunPaths paths;
  dmmr::addRunOptions(app, paths, s.view, /*path_optional=*/true);
  std::string serve;
  app.add_option("--serve", serve,
                 "interactive mode: serve the viewer page and a WebSocket on [ADDR:]PORT "
                 "(ADDR 127.0.0.1 unless given; port 0: any free one) and render the poses "
                 "viewers send; --walkthrough then gives the home pose, --out is optional "
                 "(docs/interactive.md)");
  app.add_option("--still-ms", s.serve_opts.still_ms,
                 "interactive: after this long without a new pose the exact frame follows as PNG")
      ->check(CLI::Range(0.0, 60000.0));
  app.add_option("--serve-max-rate", s.serve_opts.max_rate,
                 "interactive: messages a second a viewer may send before it is cut off")
      ->check(CLI::Range(1, 100000));
  app.add_option("--serve-max-viewers", s.serve_opts.max_viewers,
                 "interactive: viewers at once; more are refused")
      ->check(CLI::Range(1, 1024));
  app.add_option("--in-flight", s.in_flight, "frames sent ahead of the last assembled")
      ->check(CLI::Range(1, 16));
  app.add_option("--backend", backend, "client GL backend: osmesa or egl")
      ->check(CLI::IsMember({"osmesa", "egl"}));
  int visDevice = -1, renderDevice = -1;
  std::string visibility = "on";
  app.add_option("--vis-egl-device", visDevice,
                 "EGL device of the visibility context (-1: surfaceless)");
  app.add_option("--render-egl-device", renderDevice,
                 "EGL device of the render context (-1: surfaceless)");
  app.add_option("--visibility", visibility,
                 "occlusion culling on the clients: pyramid (depth read back, boxes tested on "
                 "the CPU; on is the same), queries (hardware occlusion queries) or off")
      ->check(CLI::IsMember({"on", "pyramid", "queries", "off"}));
  std::string stages = "fused";
  app.add_option("--stages", stages,
                 "fused (the default: one context draws last frame's visible set in colour and "
                 "tests the rest against its depth; needs --visibility pyramid), split (the "
                 "visibility and render stages on two contexts and threads; the default with "
                 "--visibility queries) or auto (both timed on the first frames, the faster kept)")
      ->check(CLI::IsMember({"split", "fused", "auto"}));
  dmmr::addSwitchOption(app, "--cost-model", &c.visibility.governor,
                        "on: a client stops culling for a while when its measurements say "
                        "culling does not pay (never changes a pixel); off: always cull");
  app.add_option("--query-threshold", c.visibility.query_threshold,
                 "samples a query must pass (0: any; above 0 approximates)");
  app.add_option("--keep-frames", c.visibility.keep_frames,
                 "frames an object stays visible after passing a query");
  app.add_option("--second-pass-min", c.visibility.second_pass_min,
                 "objects newly passing that trigger a second depth-and-query pass "
                 "(large: never)");
  dmmr::addSwitchOption(app, "--predict", &c.visibility.predict,
                        "fused stages: on (last frame's visible objects that its depth, moved "
                        "to the new camera, all but hides are not drawn first but tested) or "
                        "off; never changes a pixel");
  dmmr::addSwitchOption(app, "--part-boxes", &c.visibility.part_boxes,
                        "depth-pyramid tests: on (an object whose box passes is tested again "
                        "by the preprocessor's part boxes) or off (its box alone); never "
                        "changes a pixel");
  dmmr::addSwitchOption(app, "--part-draws", &c.visibility.part_draws,
                        "on (an object is drawn part by part: parts outside the client's region, "
                        "and with --part-boxes parts the depth-pyramid tests found hidden, are "
                        "left out; needs a scene preprocessed with part order, parts.bin "
                        "version 2) or off (objects drawn whole); never changes a pixel");
  std::string weights = "fitted";
  app.add_option("--weights", weights,
                 "division weights: fitted (a cost model of objects drawn and tested, "
                 "triangles, pixels and fill, and each client's speed, fitted to the clients' "
                 "measured times; the default), visible (triangles drawn lately) or frustum "
                 "(all triangles)")
      ->check(CLI::IsMember({"visible", "fitted", "frustum"}));
  app.add_option("--division-log", s.division_log,
                 "frustum division: a CSV with one row per client and frame, the server's "
                 "forecast for the region and the weight it balanced beside what the client "
                 "reported (docs/benchmarks.md, issue 16)");
  dmmr::addSwitchOption(app, "--catch-up", &s.catch_up,
                        "frustum division with fitted weights: on (a client whose measured time "
                        "ran above the clients' mean gets smaller shares of the next frames until "
                        "it has caught up, as frames in flight let it) or off; never changes a "
                        "pixel");
  std::string unseen = "hidden";
  app.add_option("--unseen", unseen,
                 "frustum division: how an object weighs that came into view in frames no "
                 "client has reported on yet: hidden (as if culled lately; the default), "
                 "drawn (as if drawn lately) or learnt (as drawn, times the fraction of such "
                 "objects that were drawn lately); never changes a pixel")
      ->check(CLI::IsMember({"drawn", "hidden", "learnt"}));
  dmmr::addSwitchOption(app, "--cost-grid", &s.cost_grid,
                        "frustum division: on (the weights are corrected, cell by cell of the "
                        "screen, by where the clients' measured time went in past frames; with "
                        "visible or fitted weights) or off; never changes a pixel");
  app.add_option("--regions-per-client", s.regions_per_client,
                 "frustum division into this many regions per client, each client's spread "
                 "over the frame so that a stale forecast's error is shared; never changes a "
                 "pixel (default 1)")
      ->check(CLI::Range(1, 16));
  app.add_option("--pool-share", s.pool_share,
                 "frustum division: leave this share of each frame's planned weight out of "
                 "the clients' regions, in parts handed out on demand to whichever client is "
                 "free first, so that what the forecast got wrong is shared out within the "
                 "frame (0: off, the default); never changes a pixel")
      ->check(CLI::Range(0.0, 0.9));
  app.add_option("--pool-parts", s.pool_parts,
                 "frustum division with --pool-share: the pool's parts (0, the default: twice "
                 "the clients), dealt --tiles-in-flight at a time a client (1 unless given)")
      ->check(CLI::Range(0, 4096));
  app.add_option("--query-runs", c.visibility.run_sizes,
                 "hierarchical query rounds: run sizes, decreasing, ending at 1")
      ->delimiter(',')
      ->check(CLI::PositiveNumber);
  app.add_flag("--occluder-lod", c.visibility.occluder_lod,
               "draw occluders with their level of detail (faster, approximate)");
  app.add_flag("--potential-occluders-every-frame", c.visibility.potential_every_frame,
               "draw the preprocessor's occluders every frame, not only without a previous list");
  dmmr::addFlushOption(app, &c.flush_triangles);
  dmmr::addTriangleCullOption(app, &c.triangle_cull);
  app.add_option("--compress", codec, "sub-frame compression: lz4, zlib or none")
      ->check(CLI::IsMember({"lz4", "zlib", "none"}));
  app.add_flag("!--no-progress", s.progress, "do not print progress");
  app.add_option("--from-frame", s.from_frame,
                 "resume an interrupted run: render from this frame on (earlier frames and "
                 "their stats rows are kept)");
  dmmr::addCacheOptions(app, c.cache);
  app.add_option("--client-timeout", s.client_timeout_s,
                 "seconds a client may stay silent while it owes a sub-frame before the run "
                 "is aborted naming it")
      ->check(CLI::PositiveNumber);
  std::string balance = "frustum", tile = "128x128", tileOrder = "rows";
  app.add_option("--balance", balance,
                 "frame distribution: frustum (load-balanced division), tiles-static, "
                 "tiles-dynamic or auto (chosen from the measured link)")
      ->check(CLI::IsMember({"frustum", "tiles-static", "tiles-dynamic", "auto"}));
  app.add_option("--tile", tile, "tile size WxH for the tile strategies (e.g. 128x128)");
  app.add_option("--tiles-per-client", s.tiles_per_client,
                 "tile strategies: size the tiles to cut each frame into about N tiles a "
                 "client, whatever its size (0, or --tile given: --tile's size)")
      ->check(CLI::Range(0, 4096));
  app.add_option("--tile-order", tileOrder,
                 "tiles-static dealing: rows (round-robin) or interleaved (diagonals)")
      ->check(CLI::IsMember({"rows", "interleaved"}));
  app.add_option("--tiles-in-flight", s.tile_window,
                 "tiles-dynamic: tiles given to a client before it returns one")
      ->check(CLI::Range(1, 4));
  app.add_option("--stage-turns", c.stage_turns,
                 "benchmark mode, one machine: the GL stages of every client take turns, "
                 "holding a lock on this file while they work on a job, so that each stage's "
                 "time is its own (docs/benchmarks.md, per-client cost)");
  std::string renderer = "raster", bvhQuality = "medium";
  app.add_option("--renderer", renderer,
                 "raster (GL, the default) or raytrace (Embree on the CPU: no GL context, no "
                 "occlusion culling; docs/raytrace.md)")
      ->check(CLI::IsMember({"raster", "raytrace"}));
  app.add_flag("--shadows", c.ray.shadows,
               "raytrace: hard shadows from a directional light (--light)");
  app.add_flag("--reflections", c.ray.reflections,
               "raytrace: mirror reflection and refraction on objects marked so");
  app.add_option("--ray-stride", s.ray_stride,
                 "raytrace: one primary ray per NxN pixels, the rest interpolated bilinearly "
                 "(1: every pixel, exact; with --serve, moving frames only; the error is in "
                 "docs/benchmarks.md)")
      ->check(CLI::Range(1, int(dmmr::kMaxJobRayStride)));
  app.add_option("--ray-depth", c.ray.max_depth, "raytrace: bounces at most")
      ->check(CLI::Range(0, 16));
  std::vector<double> light;
  app.add_option("--light", light, "raytrace: direction towards the light, X,Y,Z (world)")
      ->delimiter(',')
      ->expected(3);
  app.add_option("--bvh-quality", bvhQuality, "raytrace: Embree build quality")
      ->check(CLI::IsMember({"low", "medium", "high"}));
  std::string bvhLayout = "compact";
  app.add_option("--bvh-layout", bvhLayout,
                 "raytrace: Embree's BVH layout: compact (the default: 40% less memory, same "
                 "speed here) or default (Embree's own)")
      ->check(CLI::IsMember({"compact", "default"}));
  app.add_option("--ray-threads", c.ray_threads,
                 "raytrace: threads per client, its render stage's included (0: every CPU it "
                 "may use; 1: the stage thread alone, whose CPU time is then the whole cost)")
      ->check(CLI::Range(0, 1024));
  app.add_option("--mirror", c.mirror,
                 "raytrace --reflections: objects that mirror, by node name (glob; an object "
                 "matches when its node or any node above it does)");
  app.add_option("--glass", c.glass, "raytrace --reflections: objects that refract, by node name");
  bool keepMemory = true, hugePages = true;
  dmmr::addMemoryOptions(app, &keepMemory, &hugePages, &c.pre_touch_mib);
  dmmr::addConfigOption(app);
  // Only rank 0 prints usage errors (the rank is known before MPI starts).
  const char* rankEnv = std::getenv("OMPI_COMM_WORLD_RANK");
  bool quiet = rankEnv && std::atoi(rankEnv) != 0;
  // A usage error fails the job through rank 0, which prints it; the other
  // ranks exit 0, since one exiting non-zero first makes mpirun kill the job,
  // rank 0 included, before it has printed anything.
  const int usage_failure = quiet ? 0 : 1;
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (quiet) return 0;
    return dmmr::exitParse(app, e);
  }
  if (!serve.empty()) {
    s.serve = true;
    s.progress = false;
    if (!dmmr::parseServeAddress(serve, &s.serve_opts.address, &s.serve_opts.port)) {
      if (!quiet)
        std::fprintf(stderr,
                     "dmmr-render: --serve %s: expected [ADDR:]PORT, e.g. 8080 or "
                     "0.0.0.0:8080\n",
                     serve.c_str());
      return usage_failure;
    }
    // One frame at a time per viewer unless told: the latency a person
    // feels is the pipeline's depth times the frame time.
    if (app.count("--in-flight") == 0) s.in_flight = 1;
    s.serve_opts.max_rendering = s.in_flight;
  } else if (paths.walkthrough.empty() || paths.out.empty()) {
    if (!quiet)
      std::fprintf(stderr, "dmmr-render: --walkthrough and --out are required (or --serve)\n");
    return usage_failure;
  }
  c.ray.compact = bvhLayout == "compact";
  c.ray.quality = bvhQuality == "low"    ? dmmr::BvhQuality::Low
                  : bvhQuality == "high" ? dmmr::BvhQuality::High
                                         : dmmr::BvhQuality::Medium;
  if (!light.empty()) {
    double n = std::sqrt(light[0] * light[0] + light[1] * light[1] + light[2] * light[2]);
    if (!(n > 0) || !std::isfinite(n)) {
      if (!quiet) std::fprintf(stderr, "dmmr-render: --light must be a non-zero direction\n");
      return usage_failure;
    }
    c.ray.light = {light[0] / n, light[1] / n, light[2] / n};
  }
  s.scene = c.scene = paths.scene;
  s.walkthrough = paths.walkthrough;
  s.out = paths.out;
  s.stats = paths.stats;
  c.view = s.view;
  c.visibility_context = {dmmr::parseBackend(backend), visDevice};
  c.render_context = {dmmr::parseBackend(backend), renderDevice};
  c.visibility.method = visibility == "off"       ? dmmr::VisibilityMethod::Off
                        : visibility == "queries" ? dmmr::VisibilityMethod::Queries
                                                  : dmmr::VisibilityMethod::Pyramid;
  // Queries need the visibility stage's own context: split stages unless
  // told otherwise.
  if (visibility == "queries" && app.count("--stages") == 0) stages = "split";
  c.visibility.stages = stages == "fused"  ? dmmr::StageMode::Fused
                        : stages == "auto" ? dmmr::StageMode::Auto
                                           : dmmr::StageMode::Split;
  if (c.visibility.stages != dmmr::StageMode::Split &&
      c.visibility.method == dmmr::VisibilityMethod::Queries) {
    if (!quiet)
      std::fprintf(stderr, "dmmr-render: --stages %s needs --visibility pyramid\n", stages.c_str());
    return usage_failure;
  }
  if (s.ray_stride > 1 && renderer != "raytrace") {
    if (!quiet) std::fprintf(stderr, "dmmr-render: --ray-stride needs --renderer raytrace\n");
    return usage_failure;
  }
  // With --serve the stride is for moving frames; a still is rendered again
  // with every ray.
  s.serve_opts.render_stills = s.ray_stride > 1;
  if (renderer == "raytrace") {
    c.raytrace = true;
    // A ray finds the nearest surface itself: nothing to cull, no GL.
    c.visibility.method = dmmr::VisibilityMethod::Off;
    if (app.count("--visibility") && visibility != "off" && !quiet)
      std::fprintf(stderr,
                   "dmmr-render: --renderer raytrace does no occlusion culling; --visibility is "
                   "ignored\n");
  }
  s.visible_weights = weights == "visible" || weights == "fitted";
  s.fitted_weights = weights == "fitted";
  s.unseen = unseen == "drawn"    ? dmmr::FramePlanner::Unseen::Drawn
             : unseen == "learnt" ? dmmr::FramePlanner::Unseen::Learnt
                                  : dmmr::FramePlanner::Unseen::Hidden;
  if (c.visibility.run_sizes.empty() || c.visibility.run_sizes.back() != 1 ||
      !std::is_sorted(c.visibility.run_sizes.rbegin(), c.visibility.run_sizes.rend())) {
    if (!quiet) std::fprintf(stderr, "dmmr-render: --query-runs must decrease and end at 1\n");
    return usage_failure;
  }
  // A pool's parts are twice the clients by default: with two in flight a
  // client, every part would be handed out at once, none on demand.
  if (s.pool_share > 0 && app.count("--tiles-in-flight") == 0) s.tile_window = 1;
  if (s.pool_share > 0 && s.regions_per_client > 1) {
    if (!quiet)
      std::fprintf(stderr, "dmmr-render: --pool-share cannot be used with --regions-per-client\n");
    return usage_failure;
  }
  if (s.regions_per_client > 1 && s.cost_grid) {
    if (!quiet)
      std::fprintf(stderr,
                   "dmmr-render: --cost-grid needs one region a client; it cannot be used with "
                   "--regions-per-client %d\n",
                   s.regions_per_client);
    return usage_failure;
  }
  c.codec = dmmr::parseCodec(codec);
  dmmr::parseBalance(balance, &s.balance);  // checked by CLI11 above
  s.tile_order = tileOrder == "rows" ? dmmr::TileOrder::Rows : dmmr::TileOrder::Interleaved;
  // A tile size given wins, so that `--config configs/big-meshes.toml
  // --tile 32x32` means 32x32 tiles.
  if (app.count("--tile") > 0) s.tiles_per_client = 0;
  if (!dmmr::parseTileSize(tile, &s.tile_w, &s.tile_h)) {
    if (!quiet)
      std::fprintf(stderr, "dmmr-render: --tile %s: expected WxH with W, H from 1 to 16384\n",
                   tile.c_str());
    return usage_failure;
  }

  // What makes the frames what they are, for --from-frame's check.
  s.settings = dmmr::baseRunSettings(s.scene, s.walkthrough, s.view);
  s.settings.add("renderer", renderer);
  if (c.raytrace) {
    s.settings.add("ray-stride", std::to_string(s.ray_stride));
    s.settings.add("shadows", c.ray.shadows ? "on" : "off");
    s.settings.add("light", std::to_string(c.ray.light.x) + "," + std::to_string(c.ray.light.y) +
                                "," + std::to_string(c.ray.light.z));
    s.settings.add("reflections", c.ray.reflections ? "on" : "off");
    s.settings.add("ray-depth", std::to_string(c.ray.max_depth));
    std::string marked;
    for (const auto& m : c.mirror) marked += "mirror:" + m + " ";
    for (const auto& g : c.glass) marked += "glass:" + g + " ";
    s.settings.add("effects", marked);
  } else {
    s.settings.add("query-threshold", std::to_string(c.visibility.query_threshold));
    s.settings.add("occluder-lod", c.visibility.occluder_lod ? "on" : "off");
  }

  // Before MPI and any thread: it may restart the program (huge pages).
  dmmr::applyMemoryPolicy(keepMemory, hugePages, c.pre_touch_mib != 0, argv);
  int status = 0;
  try {
    dmmr::Comm comm(&argc, &argv);
    if (comm.rank() != 0) {
      // The GL stages' threads: one with fused stages or without culling.
      const int wanted = c.visibility.stages == dmmr::StageMode::Fused ||
                                 c.visibility.method == dmmr::VisibilityMethod::Off
                             ? 1
                             : 2;
      std::string warning = dmmr::placementWarning(comm.rank(), dmmr::allowedCpuCount(), wanted);
      if (!warning.empty()) std::fprintf(stderr, "%s\n", warning.c_str());
    }
    try {
      status = comm.rank() == 0 ? dmmr::runServer(comm, s) : dmmr::runClient(comm, c);
    } catch (const std::exception& e) {
      // Past the handshake a lone failing rank cannot stop the others in
      // order: end the whole job rather than leave ranks waiting.
      std::fprintf(stderr, "dmmr-render: rank %d: %s\n", comm.rank(), e.what());
      comm.abort(1);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "dmmr-render: %s\n", e.what());
    return 1;
  }
  return status;
}
