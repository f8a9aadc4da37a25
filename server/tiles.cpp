#include "tiles.h"

#include <algorithm>
#include <cmath>

#include "error.h"

namespace dmmr {

std::vector<Rect> makeTiles(const Rect& frame, int tile_w, int tile_h) {
  DMMR_CHECK(tile_w >= 1 && tile_h >= 1);
  std::vector<Rect> tiles;
  for (int y = frame.y; y < frame.y + frame.h; y += tile_h)
    for (int x = frame.x; x < frame.x + frame.w; x += tile_w)
      tiles.push_back(
          {x, y, std::min(tile_w, frame.x + frame.w - x), std::min(tile_h, frame.y + frame.h - y)});
  return tiles;
}

std::vector<std::vector<uint32_t>> objectsPerTile(const std::vector<Footprint>& items,
                                                  const Rect& frame, int tile_w, int tile_h) {
  DMMR_CHECK(tile_w >= 1 && tile_h >= 1);
  int columns = frame.w > 0 ? (frame.w + tile_w - 1) / tile_w : 0;
  int rows = frame.h > 0 ? (frame.h + tile_h - 1) / tile_h : 0;
  std::vector<std::vector<uint32_t>> out(size_t(columns) * size_t(rows));
  for (const Footprint& f : items) {
    // Footprint pixels [x0, x1) x [y0, y1), clipped to the frame.
    int x0 = std::max(f.x0, frame.x), x1 = std::min(f.x1, frame.x1());
    int y0 = std::max(f.y0, frame.y), y1 = std::min(f.y1, frame.y1());
    if (x0 >= x1 || y0 >= y1) continue;
    for (int r = (y0 - frame.y) / tile_h; r <= (y1 - 1 - frame.y) / tile_h; ++r)
      for (int c = (x0 - frame.x) / tile_w; c <= (x1 - 1 - frame.x) / tile_w; ++c)
        out[size_t(r) * size_t(columns) + size_t(c)].push_back(f.object);
  }
  return out;
}

std::vector<std::vector<uint32_t>> dealTiles(size_t tiles, int columns, int clients,
                                             TileOrder order) {
  DMMR_CHECK(columns >= 1 && clients >= 1);
  std::vector<std::vector<uint32_t>> out(static_cast<size_t>(clients));
  for (size_t i = 0; i < tiles; ++i) {
    size_t r = i / size_t(columns), c = i % size_t(columns);
    size_t k = order == TileOrder::Rows ? i : r + c;
    out[k % size_t(clients)].push_back(uint32_t(i));
  }
  return out;
}

TilePool::TilePool(size_t tiles, int clients, int window)
    : owner_(tiles, -1), back_(tiles, 0), in_flight_(size_t(clients), 0), window_(window) {
  DMMR_CHECK(clients >= 1 && window >= 1);
}

void TilePool::add(size_t tiles) {
  owner_.resize(owner_.size() + tiles, -1);
  back_.resize(back_.size() + tiles, 0);
}

std::vector<uint32_t> TilePool::refill(int client) {
  DMMR_CHECK(client >= 0 && size_t(client) < in_flight_.size());
  std::vector<uint32_t> out;
  while (in_flight_[size_t(client)] < window_ && next_ < size()) {
    owner_[next_ - base_] = client;
    ++in_flight_[size_t(client)];
    out.push_back(uint32_t(next_++));
  }
  return out;
}

void TilePool::done(int client, uint32_t tile) {
  DMMR_CHECK(tile >= base_ && tile < size() && owner_[tile - base_] == client &&
             !back_[tile - base_]);
  back_[tile - base_] = 1;
  --in_flight_[size_t(client)];
  ++returned_;
  // Forget the returned tiles at the front.
  while (!back_.empty() && back_.front()) {
    back_.pop_front();
    owner_.pop_front();
    ++base_;
  }
}

int TilePool::owner(uint32_t tile) const {
  DMMR_CHECK(tile >= base_ && tile < size());
  return owner_[tile - base_];
}

void gridTileSize(int width, int height, int tiles, int* tile_w, int* tile_h) {
  DMMR_CHECK(width >= 1 && height >= 1 && tiles >= 1);
  double columns = std::round(std::sqrt(double(tiles) * width / height));
  int cols = int(std::clamp(columns, 1.0, double(std::min(width, tiles))));
  int rows = std::clamp((tiles + cols - 1) / cols, 1, height);
  *tile_w = (width + cols - 1) / cols;
  *tile_h = (height + rows - 1) / rows;
}

bool parseTileSize(const std::string& text, int* w, int* h) {
  size_t x = text.find('x');
  if (x == std::string::npos || x == 0 || x + 1 >= text.size()) return false;
  auto number = [](const std::string& t, int* out) {
    if (t.size() > 5 || t.find_first_not_of("0123456789") != std::string::npos) return false;
    *out = std::stoi(t);
    return *out >= 1 && *out <= 16384;
  };
  return number(text.substr(0, x), w) && number(text.substr(x + 1), h);
}

const char* balanceName(Balance b) {
  switch (b) {
    case Balance::Frustum:
      return "frustum";
    case Balance::TilesStatic:
      return "tiles-static";
    case Balance::TilesDynamic:
      return "tiles-dynamic";
    case Balance::Auto:
      return "auto";
  }
  return "?";
}

bool parseBalance(const std::string& text, Balance* out) {
  for (Balance b : {Balance::Frustum, Balance::TilesStatic, Balance::TilesDynamic, Balance::Auto})
    if (text == balanceName(b)) {
      *out = b;
      return true;
    }
  return false;
}

BalanceTrial::BalanceTrial(std::vector<Balance> candidates, uint32_t warmup, uint32_t block)
    : candidates_(std::move(candidates)),
      warmup_(warmup),
      block_(block),
      block_ms_(candidates_.size(), -1.0) {
  DMMR_CHECK(!candidates_.empty() && block >= 1);
  winner_ = candidates_[0];
}

Balance BalanceTrial::strategy(uint32_t i) const {
  if (decided_) return winner_;
  if (i < warmup_) return candidates_[0];
  size_t c = (i - warmup_) / block_;
  return c < candidates_.size() ? candidates_[c] : winner_;
}

bool BalanceTrial::boundary(uint32_t i) const {
  return !decided_ && i >= warmup_ && (i - warmup_) % block_ == 0 &&
         (i - warmup_) / block_ <= candidates_.size();
}

void BalanceTrial::blockBoundary(uint32_t i, double now_ms) {
  DMMR_CHECK(boundary(i));
  size_t c = (i - warmup_) / block_;  // the block that starts here; c - 1 just ended
  if (c > 0) block_ms_[c - 1] = (now_ms - started_ms_) / block_;
  started_ms_ = now_ms;
  if (c == candidates_.size()) {
    size_t best = 0;
    for (size_t k = 1; k < block_ms_.size(); ++k)
      if (block_ms_[k] < block_ms_[best]) best = k;
    winner_ = candidates_[best];
    decided_ = true;
  }
}

double linkSeconds(uint64_t bytes, const LinkModel& link, double u) {
  return link.latency_s + double(bytes) * 8.0 / link.bits_per_s + link.jitter_s * u;
}

}  // namespace dmmr
