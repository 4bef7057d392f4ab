#pragma once
// Per mesh edge, the tets around it, for the edge-smoothed model (sim/fem/fem_model_edges.cpp),
// whose product sweeps every edge's list each time. Up to kInline tets of an edge sit with
// their count in one fixed-size record, the records in edge id order, so that the sweep
// streams through them; a list per edge on the heap had scattered them (each grows as the
// mesh's tets register, and moves when it does), a cache miss an edge on large meshes
// (docs/solver.md#edge-smoothed-product). An edge with more tets keeps them all in a list of
// its own, named by the record. Removal swaps the last tet into the removed one's place, so an
// edge's order is the order its tets came and went in.
#include <array>
#include <cstdint>
#include <span>
#include <vector>

namespace incise {

class EdgeTetLists {
public:
  static constexpr std::uint32_t kInline = 7;  // with the count, 32 bytes a record

  std::size_t size() const { return rec_.size(); }
  void add_edge() { rec_.push_back({}); }
  bool empty(std::size_t e) const { return rec_[e][0] == 0; }
  std::span<const std::uint32_t> operator[](std::size_t e) const {
    const Record& r = rec_[e];
    if (r[0] <= kInline) return {r.data() + 1, r[0]};
    return long_[r[1]];
  }

  void push(std::size_t e, std::uint32_t t) {
    Record& r = rec_[e];
    if (r[0] < kInline) {
      r[1 + r[0]++] = t;
      return;
    }
    if (r[0] == kInline) {  // spills: the record now names its list
      std::uint32_t at;
      if (free_long_.empty()) {
        at = std::uint32_t(long_.size());
        long_.emplace_back();
      } else {
        at = free_long_.back();
        free_long_.pop_back();
      }
      long_[at].assign(r.begin() + 1, r.end());
      r[1] = at;
    }
    long_[r[1]].push_back(t);
    ++r[0];
  }

  // Removes t from e's tets (nothing if it is not there).
  void remove(std::size_t e, std::uint32_t t) {
    Record& r = rec_[e];
    if (r[0] <= kInline) {
      for (std::uint32_t i = 1; i <= r[0]; ++i)
        if (r[i] == t) {
          r[i] = r[r[0]];
          --r[0];
          return;
        }
      return;
    }
    std::vector<std::uint32_t>& l = long_[r[1]];
    for (std::size_t i = 0; i < l.size(); ++i)
      if (l[i] == t) {
        l[i] = l.back();
        l.pop_back();
        --r[0];
        break;
      }
    if (r[0] == kInline) {  // back into the record
      const std::uint32_t at = r[1];
      for (std::uint32_t i = 0; i < kInline; ++i) r[1 + i] = long_[at][i];
      long_[at].clear();
      free_long_.push_back(at);
    }
  }

private:
  using Record = std::array<std::uint32_t, kInline + 1>;  // count, then the tets (or the list's index)
  std::vector<Record> rec_;
  std::vector<std::vector<std::uint32_t>> long_;
  std::vector<std::uint32_t> free_long_;
};

}  // namespace incise
