#include "tiles.h"

#include <algorithm>

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

std::vector<uint32_t> TilePool::refill(int client) {
  DMMR_CHECK(client >= 0 && size_t(client) < in_flight_.size());
  std::vector<uint32_t> out;
  while (in_flight_[size_t(client)] < window_ && next_ < owner_.size()) {
    owner_[next_] = client;
    ++in_flight_[size_t(client)];
    out.push_back(uint32_t(next_++));
  }
  return out;
}

void TilePool::done(int client, uint32_t tile) {
  DMMR_CHECK(tile < owner_.size() && owner_[tile] == client && !back_[tile]);
  back_[tile] = 1;
  --in_flight_[size_t(client)];
  ++returned_;
}

double linkSeconds(uint64_t bytes, const LinkModel& link, double u) {
  return link.latency_s + double(bytes) * 8.0 / link.bits_per_s + link.jitter_s * u;
}

}  // namespace dmmr
