// The dmmr server (rank 0): holds the scene without geometry, plans each
// frame (culling, division), sends the jobs, and assembles the sub-frames on
// a separate thread into PNG frames and a statistics CSV.
#pragma once

#include <string>

#include "camera.h"
#include "mpi_comm.h"
#include "plan.h"
#include "run_settings.h"
#include "serve.h"
#include "tiles.h"

namespace dmmr {

struct ServerOptions {
  std::string scene;
  std::string walkthrough;
  // Written beside the frames; a run with from_frame > 0 checks them against
  // the earlier frames' (run_settings.h).
  RunSettings settings;
  std::string out;    // frames: frame_NNNNNN.png
  std::string stats;  // optional per-frame CSV
  // Optional CSV, one row per client and frame (frustum division): what the
  // server forecast for the region at plan time (FramePlanner::forecast) and
  // the weight it balanced, beside the work and time the client reported.
  // For studying the division's weights; costs a second projection of each
  // region's lately drawn objects.
  std::string division_log;
  ViewOptions view;
  // Frames sent ahead of the last one assembled: 3 keeps the server, the
  // visibility and the render stage busy on frames i, i-1, i-2; 1 serialises.
  int in_flight = 3;
  bool progress = true;
  // Weigh objects for the division by what the clients drew lately (see
  // FramePlanner::reportDrawn), rather than by all triangles in the frustum.
  bool visible_weights = true;
  // Fit a cost model and each client's speed to what the clients report, and
  // divide by fitted time (FramePlanner::reportCosts); needs visible_weights.
  // The default: with the fill term it balanced better than visible weights
  // alone on every measured scene (docs/benchmarks.md).
  bool fitted_weights = true;
  // Correct the division's weights by where the clients' measured time went
  // (FramePlanner::enableCostGrid, cost_grid.h); frustum division only.
  // Moves split lines only: never changes a pixel.
  bool cost_grid = false;
  // Frustum division into this many regions per client, dealt so that each
  // client's regions are spread over the frame (FramePlanner::plan). Moves
  // split lines only: never changes a pixel. Not with cost_grid.
  int regions_per_client = 1;
  // Frustum division with a pool (FramePlanner::plan): this share of each
  // frame's weight is left out of the clients' regions and split into
  // pool_parts parts (0: twice the clients), dealt on demand like
  // tiles-dynamic, tile_window in flight per client (dmmr-render makes that 1
  // for a pool unless told otherwise). 0: no pool. Moves split
  // lines only: never changes a pixel. Not with regions_per_client > 1.
  double pool_share = 0;
  int pool_parts = 0;
  // With fitted weights and more than one frame in flight: a client whose
  // time ran above the clients' mean gets smaller shares until it has caught
  // up (FramePlanner::setCatchUp).
  bool catch_up = true;
  // How objects weigh that came into view in frames no client has reported
  // on yet (FramePlanner::setUnseen).
  FramePlanner::Unseen unseen = FramePlanner::Unseen::Hidden;
  // A client that sends nothing for this long while it owes a sub-frame has
  // died or hangs: the server names it and aborts the job (frames already
  // assembled stay on disk). Generous by default: a first frame that loads
  // a huge region's geometry from disk can take minutes.
  double client_timeout_s = 600;
  // Resume an interrupted run: render frames from this one on; the stats
  // CSV keeps the rows of the frames before it.
  uint32_t from_frame = 0;
  // How frames are distributed (tiles.h): frustum division, or tile_w x
  // tile_h tiles dealt statically in tile_order, or on demand with
  // tile_window tiles in flight per client; auto measures the link at start.
  Balance balance = Balance::Frustum;
  int tile_w = 128, tile_h = 128;
  // Above 0: the tiles' size instead cuts each frame into about this many
  // tiles a client (gridTileSize).
  int tiles_per_client = 0;
  TileOrder tile_order = TileOrder::Rows;
  int tile_window = 2;
  // Interactive mode (serve.h): poses from viewers instead of the
  // walkthrough, which then only gives the home pose (optional); frames go
  // to the viewers, and to `out` only when it is set.
  // Ray-tracing clients trace one ray per ray_stride x ray_stride pixels
  // (FrameJob::ray_stride; 1: every pixel, exact).
  int ray_stride = 1;
  bool serve = false;
  ServeOptions serve_opts;
};

// Returns the process exit status; every message it prints names the rank
// that found the problem.
int runServer(Comm& comm, const ServerOptions& opts);

}  // namespace dmmr
