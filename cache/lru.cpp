#include "lru.h"

#include "error.h"

namespace dmmr {

void LruBudget::link(uint32_t key) {
  Entry& e = entries_[key];
  e.prev = last_;
  e.next = kNone;
  (last_ == kNone ? first_ : entries_[last_].next) = key;
  last_ = key;
}

void LruBudget::unlink(uint32_t key) {
  Entry& e = entries_[key];
  (e.prev == kNone ? first_ : entries_[e.prev].next) = e.next;
  (e.next == kNone ? last_ : entries_[e.next].prev) = e.prev;
}

bool LruBudget::touch(uint32_t key) {
  if (!contains(key)) return false;
  if (key != last_) {
    unlink(key);
    link(key);
  }
  entries_[key].frame = frame_;
  return true;
}

void LruBudget::add(uint32_t key, uint64_t bytes) {
  DMMR_CHECK(key != kNone);
  if (key >= entries_.size()) entries_.resize(size_t(key) + 1);
  Entry& e = entries_[key];
  e.held = true;
  e.bytes = bytes;
  e.frame = frame_;
  link(key);
  used_ += bytes;
  ++size_;
}

uint32_t LruBudget::victim() const {
  if (eviction_ == Eviction::FrameLru && entries_[first_].frame == frame_) return last_;
  return first_;
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
  if (!contains(key)) return 0;
  Entry& e = entries_[key];
  unlink(key);
  e.held = false;
  used_ -= e.bytes;
  --size_;
  return e.bytes;
}

std::vector<uint32_t> LruBudget::order() const {
  std::vector<uint32_t> keys;
  keys.reserve(size_);
  for (uint32_t k = first_; k != kNone; k = entries_[k].next) keys.push_back(k);
  return keys;
}

}  // namespace dmmr
