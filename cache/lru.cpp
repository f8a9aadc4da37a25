#include "lru.h"

#include "error.h"

namespace dmmr {

bool LruBudget::touch(uint32_t key) {
  auto it = entries_.find(key);
  if (it == entries_.end()) return false;
  order_.splice(order_.end(), order_, it->second.pos);
  it->second.frame = frame_;
  return true;
}

void LruBudget::add(uint32_t key, uint64_t bytes) {
  order_.push_back(key);
  entries_[key] = {std::prev(order_.end()), bytes, frame_};
  used_ += bytes;
}

uint32_t LruBudget::victim() const {
  uint32_t lru = order_.front();
  if (eviction_ == Eviction::FrameLru && entries_.at(lru).frame == frame_) return order_.back();
  return lru;
}

void LruBudget::insert(uint32_t key, uint64_t bytes, std::vector<uint32_t>* evicted) {
  DMMR_CHECK(admits(bytes) && !contains(key));
  while (budget_ - used_ < bytes) {
    uint32_t v = victim();
    erase(v);
    evicted->push_back(v);
  }
  add(key, bytes);
}

bool LruBudget::insertIfFree(uint32_t key, uint64_t bytes) {
  DMMR_CHECK(!contains(key));
  if (budget_ - used_ < bytes) return false;
  add(key, bytes);
  return true;
}

uint64_t LruBudget::erase(uint32_t key) {
  auto it = entries_.find(key);
  if (it == entries_.end()) return 0;
  uint64_t bytes = it->second.bytes;
  order_.erase(it->second.pos);
  entries_.erase(it);
  used_ -= bytes;
  return bytes;
}

}  // namespace dmmr
