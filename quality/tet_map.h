#pragma once
// A map from tet id to V by open addressing (linear probing): inserts, finds and clearing only,
// never iterated, so it behaves exactly like an unordered_map keyed by id, without a node
// allocation per tet (an improvement pass queues every tet of its region once, ~1000 per cut
// step).
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace incise {

template <class V>
class TetMap {
public:
  V& operator[](std::uint32_t key) {
    if (2 * (size_ + 1) > slots_.size()) grow();
    Slot& s = probe(key);
    if (s.key != key) {
      s.key = key;
      s.value = V{};
      ++size_;
    }
    return s.value;
  }
  const V* find(std::uint32_t key) const {
    if (slots_.empty()) return nullptr;
    const Slot& s = const_cast<TetMap*>(this)->probe(key);
    return s.key == key ? &s.value : nullptr;
  }
  std::size_t size() const { return size_; }
  void clear() {
    slots_.clear();
    size_ = 0;
  }

private:
  static constexpr std::uint32_t kEmpty = 0xffffffffu;
  struct Slot {
    std::uint32_t key = kEmpty;
    V value{};
  };
  Slot& probe(std::uint32_t key) {
    const std::size_t mask = slots_.size() - 1;
    for (std::size_t i = (key * 0x9e3779b1u) & mask;; i = (i + 1) & mask)
      if (slots_[i].key == key || slots_[i].key == kEmpty) return slots_[i];
  }
  void grow() {
    std::vector<Slot> old = std::move(slots_);
    slots_.assign(std::max<std::size_t>(64, 2 * old.size()), Slot{});
    for (const Slot& s : old)
      if (s.key != kEmpty) probe(s.key) = s;
  }
  std::vector<Slot> slots_;
  std::size_t size_ = 0;
};

}  // namespace incise
