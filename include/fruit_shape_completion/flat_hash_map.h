#pragma once
// A small open-addressing hash map from 63-bit integer keys (packed voxel / cell coordinates)
// to values: linear probing in one flat array, several times faster than std::unordered_map
// for the millions of lookups a frame integration or a neighbour search makes. No erase.
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
      if (keys_[i] == key) return &values_[i];
      if (keys_[i] == kEmpty) return nullptr;
    }
  }
  const Value* find(std::uint64_t key) const { return const_cast<FlatHashMap*>(this)->find(key); }

  // The value for `key`, default-constructed if new; second is true if it was inserted.
  std::pair<Value*, bool> insert(std::uint64_t key) {
    if (2 * (size_ + 1) > keys_.size()) rehash(keys_.size() * 2);
    for (std::size_t i = slot(key);; i = (i + 1) & mask_) {
      if (keys_[i] == key) return {&values_[i], false};
      if (keys_[i] == kEmpty) {
        keys_[i] = key;
        values_[i] = Value();
        ++size_;
        return {&values_[i], true};
      }
    }
  }

  template <typename Fn>  // fn(key, value&)
  void forEach(Fn&& fn) {
    for (std::size_t i = 0; i < keys_.size(); ++i)
      if (keys_[i] != kEmpty) fn(keys_[i], values_[i]);
  }

  void clear() { rehash(16); }

 private:
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
    std::vector<std::uint64_t> old_keys(capacity, kEmpty);
    std::vector<Value> old_values(capacity);
    old_keys.swap(keys_);
    old_values.swap(values_);
    mask_ = capacity - 1;
    size_ = 0;
    for (std::size_t i = 0; i < old_keys.size(); ++i)
      if (old_keys[i] != kEmpty) *insert(old_keys[i]).first = std::move(old_values[i]);
  }

  std::vector<std::uint64_t> keys_;
  std::vector<Value> values_;
  std::size_t mask_ = 0;
  std::size_t size_ = 0;
};

}  // namespace fruit_shape_completion
