// Tile-based distribution (Sensors 2022 mobile ray-tracing paper, section 4):
// the frame as a pool of fixed-size tiles, dealt to the clients up front
// (static) or handed out on demand (dynamic); and the link model that the
// network benchmark falls back to where real shaping is impossible. Plain
// data, no MPI or GL: the building blocks of --balance tiles-static and
// tiles-dynamic.
#pragma once

#include <cstdint>
#include <deque>
#include <string>
#include <vector>

#include "divide.h"
#include "math.h"

namespace dmmr {

// Tiles of tile_w x tile_h pixels covering `frame` in row order (GL order:
// the bottom row of tiles first, each left to right); the last column and
// row are cut to fit. tile_w, tile_h >= 1; an empty frame has no tiles.
std::vector<Rect> makeTiles(const Rect& frame, int tile_w, int tile_h);

// Per tile of makeTiles(frame, tile_w, tile_h), the objects whose footprint
// overlaps it (the per-tile cull: a tile's client draws only these). Lists
// are ascending when `items` is ascending by object; a footprint with no
// pixels goes nowhere.
std::vector<std::vector<uint32_t>> objectsPerTile(const std::vector<Footprint>& items,
                                                  const Rect& frame, int tile_w, int tile_h);

enum class TileOrder : uint8_t {
  Rows,         // the paper's round-robin: tile i to client i mod n
  Interleaved,  // tile (row r, column c) to client (r + c) mod n: diagonals,
                // so a heavy area spanning a few rows and columns is split
                // among clients even when the column count is a multiple of n
};

// Static dealing: for each client, the indices (into makeTiles' list) of its
// tiles, ascending. Every tile goes to exactly one client; counts differ by
// at most one for Rows. `columns` is the tile grid's width (>= 1).
std::vector<std::vector<uint32_t>> dealTiles(size_t tiles, int columns, int clients,
                                             TileOrder order);

// Dynamic dealing: a pool handed out on demand, with at most `window` tiles
// in flight per client (more hides the link's latency; 1 is the paper's
// request-per-tile). Tiles are numbered on over the whole run; the pool
// keeps only those from the oldest not yet returned on, so its memory is
// bounded by what is queued and in flight, not by the run's length.
class TilePool {
 public:
  TilePool(size_t tiles, int clients, int window);
  // Appends `tiles` more to the pool (the next frame's, say), numbered on.
  void add(size_t tiles);
  // Tiles ever added: the number the next added tile gets.
  size_t size() const { return base_ + owner_.size(); }
  // Tiles to send `client` now: enough to fill its window from the pool,
  // lowest index first. Empty when the pool is dry or the window is full.
  std::vector<uint32_t> refill(int client);
  // `client` returned `tile` (which it must have been given and not yet
  // returned).
  void done(int client, uint32_t tile);
  bool finished() const { return returned_ == size(); }
  int inFlight(int client) const { return in_flight_[size_t(client)]; }
  // Which client was given `tile` (-1: not yet handed out); `tile` must not
  // be forgotten yet (>= forgotten()).
  int owner(uint32_t tile) const;
  // Tiles below this number were all returned, and are forgotten.
  size_t forgotten() const { return base_; }
  // Tiles whose bookkeeping is held: size() - forgotten().
  size_t held() const { return owner_.size(); }

 private:
  // Tiles base_, base_ + 1, ...: the client given each (-1: none yet), and
  // whether it came back.
  std::deque<int> owner_;
  std::deque<uint8_t> back_;
  std::vector<int> in_flight_;
  int window_;
  size_t base_ = 0, next_ = 0, returned_ = 0;  // next_: the next tile to hand out
};

// The tile size that cuts a width x height frame (each >= 1) into about
// `tiles` (>= 1) tiles, as near square as a grid of columns x rows with
// columns / rows near width / height allows: columns = round(sqrt(tiles *
// width / height)) within 1 and min(width, tiles), rows = ceil(tiles /
// columns) within 1 and height, and the tile size is the frame's side over
// each, rounded up. So the tile size follows the frame's size and the
// client count (--tiles-per-client) where a fixed --tile would give a
// 1024x1024 frame four times the tiles of a 512x512 one.
void gridTileSize(int width, int height, int tiles, int* tile_w, int* tile_h);

// Parses "WxH" (W, H in 1..16384); false when malformed.
bool parseTileSize(const std::string& text, int* w, int* h);

// How the server distributes a frame among the clients.
enum class Balance : uint8_t {
  Frustum,       // DMMR's load-balanced frustum division: one region per client
  TilesStatic,   // tiles dealt up front (TileOrder); each client returns its batch
  TilesDynamic,  // tiles on demand, `window` in flight per client, returned one by one
  Auto,          // BalanceTrial: each timed on a few frames, then the fastest
};
const char* balanceName(Balance b);
// Parses frustum | tiles-static | tiles-dynamic | auto; false when unknown.
bool parseBalance(const std::string& text, Balance* out);

// --balance auto: lets the frame times on the link at hand decide. After
// `warmup` frames (the first loads geometry) each candidate renders `block`
// frames in turn, the pipeline drained before each block so that a block's
// time is its own; then the candidate with the least time per frame renders
// the rest. Plain bookkeeping: the server times the blocks.
class BalanceTrial {
 public:
  BalanceTrial(std::vector<Balance> candidates, uint32_t warmup, uint32_t block);
  // The strategy for the run's frame `i` (0: the first frame rendered).
  Balance strategy(uint32_t i) const;
  // True when frame `i` starts a timed block (or ends the last one): the
  // server waits for every earlier frame first, then calls blockBoundary.
  bool boundary(uint32_t i) const;
  // At a boundary: the time now, in ms on any steady clock.
  void blockBoundary(uint32_t i, double now_ms);
  bool decided() const { return decided_; }
  Balance winner() const { return winner_; }
  // Per candidate: ms per frame of its block (negative: not timed yet).
  const std::vector<double>& blockMs() const { return block_ms_; }
  const std::vector<Balance>& candidates() const { return candidates_; }

 private:
  std::vector<Balance> candidates_;
  uint32_t warmup_, block_;
  std::vector<double> block_ms_;
  double started_ms_ = 0;
  bool decided_ = false;
  Balance winner_;
};

// A network link as a model: latency, bandwidth and jitter.
struct LinkModel {
  double latency_s = 0;     // one way
  double bits_per_s = 1e9;  // usable bandwidth
  double jitter_s = 0;      // extra delay, uniform in [0, jitter_s]
};

// Seconds for a message of `bytes` on `link`: latency + size / bandwidth +
// jitter * u, with u in [0, 1) drawn by the caller (so runs are repeatable).
double linkSeconds(uint64_t bytes, const LinkModel& link, double u);

}  // namespace dmmr
