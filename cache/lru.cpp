#include "lru.h"

#include "error.h"

namespace dmmr {

bool LruBudget::touch(uint32_t key) {
  auto it = entries_.find(key);
  if (it == entries_.end()) return false;
  order_.splice(order_.end(), order_, it->second.pos);
  return true;
}

void LruBudget::insert(uint32_t key, uint64_t bytes, std::vector<uint32_t>* evicted) {
  DMMR_CHECK(admits(bytes) && !contains(key));
  while (budget_ - used_ < bytes) {
    uint32_t victim = order_.front();
    erase(victim);
    evicted->push_back(victim);
  }
  order_.push_back(key);
  entries_[key] = {std::prev(order_.end()), bytes};
  used_ += bytes;
}

bool LruBudget::insertIfFree(uint32_t key, uint64_t bytes) {
  DMMR_CHECK(!contains(key));
  if (budget_ - used_ < bytes) return false;
  order_.push_back(key);
  entries_[key] = {std::prev(order_.end()), bytes};
  used_ += bytes;
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
