#include "cut/fragments.h"

#include <algorithm>

namespace incise::cut_detail {

namespace {

// One flood fill per start, grown in turns. Fills that meet merge (union-find); a fill that
// runs out of tets without meeting another has found a whole connected part. The search ends
// as soon as one fill is left (every start is connected: nothing detached), so a partial cut
// costs about the walk around its front and a through-cut about twice the smaller side.
struct Fill {
  std::vector<TetId> tets;  // visited, in order; tets[head..] are still to expand
  std::size_t head = 0;
  int parent = -1;          // merged into this fill (-1: a root)
  bool closed = false, open = false;
  double volume = 0;
};

int root(std::vector<Fill>& fills, int i) {
  while (fills[i].parent >= 0) i = fills[i].parent;
  return i;
}

}  // namespace

std::vector<Fragment> find_fragments(const TetMesh& mesh, std::span<const TetId> starts, std::size_t limit,
                                     FragmentScratch& scratch, Fragment* body) {
  if (body) *body = Fragment{};
  if (limit == 0) return {};
  std::vector<Fill> fills;
  // owner of tet i: scratch.owner[i] when scratch.stamp[i] is this call's stamp.
  if (scratch.stamp.size() < mesh.tet_capacity()) {
    scratch.stamp.resize(mesh.tet_capacity(), 0);
    scratch.owner.resize(mesh.tet_capacity(), -1);
  }
  if (++scratch.now == 0) {  // the stamp wrapped: every entry is old
    std::fill(scratch.stamp.begin(), scratch.stamp.end(), 0);
    scratch.now = 1;
  }
  const std::uint32_t now = scratch.now;
  std::uint32_t* const stamp = scratch.stamp.data();
  int* const owner = scratch.owner.data();
  for (TetId s : starts) {
    if (!mesh.is_alive(s) || stamp[s.idx()] == now) continue;
    stamp[s.idx()] = now;
    owner[s.idx()] = int(fills.size());
    fills.emplace_back();
    fills.back().tets.push_back(s);
    fills.back().volume = mesh.volume(s);
  }
  std::size_t active = fills.size();  // roots neither closed nor open
  std::size_t roots = fills.size();
  constexpr std::size_t kTurn = 32;   // tets a fill expands per turn
  while (roots > 1 && active > 0) {
    for (std::size_t i = 0; i < fills.size() && roots > 1; ++i) {
      if (fills[i].parent >= 0 || fills[i].closed || fills[i].open) continue;
      for (std::size_t k = 0; k < kTurn && fills[i].parent < 0; ++k) {
        Fill& f = fills[i];
        if (f.head == f.tets.size()) {
          f.closed = true;
          --active;
          break;
        }
        if (f.tets.size() > limit) {
          f.open = true;
          --active;
          break;
        }
        const TetId t = f.tets[f.head++];
        for (int j = 0; j < 4; ++j) {
          const TetId n = mesh.neighbor(t, j);
          if (!n.is_valid()) continue;
          if (stamp[n.idx()] != now) {
            stamp[n.idx()] = now;
            owner[n.idx()] = int(i);
            fills[i].tets.push_back(n);
            fills[i].volume += mesh.volume(n);
            continue;
          }
          const int other = root(fills, owner[n.idx()]);
          if (other == int(i)) continue;
          // Two fills met: the smaller joins the larger's queue (its unexpanded tets too).
          int keep = int(i), gone = other;
          if (fills[gone].tets.size() > fills[keep].tets.size()) std::swap(keep, gone);
          // If this fill is the one that goes, t has neighbours left to look at: expand it again.
          if (gone == int(i)) --fills[i].head;
          Fill& a = fills[keep];
          Fill& b = fills[gone];
          const bool b_active = !b.closed && !b.open;
          const bool a_active = !a.closed && !a.open;
          a.tets.insert(a.tets.end(), b.tets.begin() + std::ptrdiff_t(b.head), b.tets.end());
          a.tets.insert(a.tets.begin() + std::ptrdiff_t(a.head), b.tets.begin(), b.tets.begin() + std::ptrdiff_t(b.head));
          a.head += b.head;
          a.volume += b.volume;
          a.open = a.open || b.open;
          if (a.open && a_active) --active;
          if (b_active) --active;
          b.parent = keep;
          b.tets.clear();
          b.tets.shrink_to_fit();
          --roots;
          if (keep != int(i)) break;  // this fill is gone; its turn ends
        }
      }
    }
  }
  if (roots <= 1) return {};  // every start is connected to every other: nothing detached
  std::vector<Fragment> closed;
  bool open_part = false;
  for (Fill& f : fills) {
    if (f.parent >= 0) continue;
    if (!f.closed) {
      open_part = true;
      continue;
    }
    closed.push_back({std::move(f.tets), f.volume});
  }
  // Every part closed (a small body cut through): the largest is the body, by volume, which
  // the improvement keeps (by tet count, a part that insertion refined more could pass it).
  if (!open_part && !closed.empty()) {
    auto big = std::max_element(closed.begin(), closed.end(),
                                [](const Fragment& a, const Fragment& b) { return a.volume < b.volume; });
    if (body) *body = std::move(*big);
    closed.erase(big);
  }
  return closed;
}

}  // namespace incise::cut_detail
