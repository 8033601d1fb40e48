#pragma once
// A small open-addressing hash map from 63-bit integer keys (packed voxel / cell coordinates)
// to values: linear probing in one flat array of key-value slots (a lookup usually reads one
// cache line), several times faster than std::unordered_map for the millions of lookups a
// frame integration or a neighbour search makes. No erase.
#include <cstdint>
#include <utility>
#include <vector>

namespace fruit_shape_completion {

template <typename Value>
class FlatHashMap {
 public:
  static constexpr std::uint64_t kEmpty = ~0ull;  // never a packed key (those use 63 bits)

  explicit FlatHashMap(std::size_t expected = 16) { rehash(capacityFor(expected)); }

  std::size_t size() const { return size_; }

  Value* find(std::uint64_t key) {
    for (std::size_t i = slot(key);; i = (i + 1) & mask_) {
      if (slots_[i].key == key) return &slots_[i].value;
      if (slots_[i].key == kEmpty) return nullptr;
    }
  }
  const Value* find(std::uint64_t key) const { return const_cast<FlatHashMap*>(this)->find(key); }

  // Fetches the slot of `key` into the cache ahead of a find or insert (which must not grow
  // the map in between, or the slot moves: reserve with the constructor).
  void prefetch(std::uint64_t key) const { __builtin_prefetch(&slots_[slot(key)]); }

  // The value for `key`, default-constructed if new; second is true if it was inserted.
  std::pair<Value*, bool> insert(std::uint64_t key) {
    if (2 * (size_ + 1) > slots_.size()) rehash(slots_.size() * 2);
    for (std::size_t i = slot(key);; i = (i + 1) & mask_) {
      if (slots_[i].key == key) return {&slots_[i].value, false};
      if (slots_[i].key == kEmpty) {
        slots_[i].key = key;
        slots_[i].value = Value();
        ++size_;
        return {&slots_[i].value, true};
      }
    }
  }

  template <typename Fn>  // fn(key, value&)
  void forEach(Fn&& fn) {
    for (auto& s : slots_)
      if (s.key != kEmpty) fn(s.key, s.value);
  }

  void clear() { rehash(16); }

  // Empties the map for about `expected` keys, keeping the slot array when it is the right
  // size (refilling it is much cheaper than fresh memory).
  void reset(std::size_t expected) {
    const std::size_t capacity = capacityFor(expected);
    if (slots_.size() != capacity) {
      std::vector<Slot>(capacity).swap(slots_);
      mask_ = capacity - 1;
    } else {
      for (auto& s : slots_) s.key = kEmpty;
    }
    size_ = 0;
  }

 private:
  struct Slot {
    std::uint64_t key = kEmpty;
    Value value{};
  };
  static std::size_t capacityFor(std::size_t n) {
    std::size_t c = 16;
    while (c < 2 * n) c *= 2;
    return c;
  }
  std::size_t slot(std::uint64_t key) const {
    key ^= key >> 29;
    key *= 0xbf58476d1ce4e5b9ull;
    key ^= key >> 32;
    return static_cast<std::size_t>(key) & mask_;
  }
  void rehash(std::size_t capacity) {
    std::vector<Slot> old(capacity);
    old.swap(slots_);
    mask_ = capacity - 1;
    size_ = 0;
    for (auto& s : old)
      if (s.key != kEmpty) *insert(s.key).first = std::move(s.value);
  }

  std::vector<Slot> slots_;
  std::size_t mask_ = 0;
  std::size_t size_ = 0;
};

}  // namespace fruit_shape_completion
