#include "cut/fragments.h"

#include <algorithm>
#include <unordered_set>

namespace incise::cut_detail {

std::vector<Fragment> find_fragments(const TetMesh& mesh, std::span<const TetId> starts, std::size_t limit) {
  if (limit == 0) return {};
  std::vector<Fragment> closed;
  bool open_part = false;
  std::unordered_set<std::uint32_t> seen;
  std::size_t work = 0;
  for (TetId s : starts) {
    // Breadth first, so a fill covers the starts near it; total work stays O(limit).
    if (work > 2 * limit) break;
    if (!mesh.is_alive(s) || seen.count(s.idx())) continue;
    Fragment part;
    std::vector<TetId> queue{s};
    seen.insert(s.idx());
    bool open = false;
    for (std::size_t i = 0; i < queue.size(); ++i) {
      const TetId t = queue[i];
      ++work;
      part.tets.push_back(t);
      part.volume += mesh.volume(t);
      if (part.tets.size() > limit) {
        open = true;
        break;
      }
      for (int f = 0; f < 4; ++f) {
        const TetId n = mesh.neighbor(t, f);
        if (n.is_valid() && seen.insert(n.idx()).second) queue.push_back(n);
      }
    }
    if (open) {
      open_part = true;
      continue;
    }
    closed.push_back(std::move(part));
  }
  if (!open_part && !closed.empty()) {
    auto big = std::max_element(closed.begin(), closed.end(),
                                [](const Fragment& a, const Fragment& b) { return a.tets.size() < b.tets.size(); });
    closed.erase(big);
  }
  return closed;
}

}  // namespace incise::cut_detail
