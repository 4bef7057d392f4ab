#include "sim/vertex_aggregation.h"

#include <algorithm>

namespace incise {

VertexAggregates aggregate_vertices(const TetMesh& mesh, const std::vector<std::uint8_t>& eligible, int ring) {
  const std::size_t nv = mesh.vertex_capacity();
  VertexAggregates out;
  out.of.assign(std::max(nv, eligible.size()), -1);
  auto ok = [&](std::size_t v) { return v < nv && v < eligible.size() && eligible[v] && mesh.is_alive(VertexId(std::uint32_t(v))); };
  // The neighbours of v (with repeats: one per shared tet, which phase 2 counts).
  std::vector<std::uint32_t> nb;
  auto neighbours = [&](std::uint32_t v) {
    nb.clear();
    for (TetId t : mesh.incident_tets(VertexId(v)))
      for (VertexId w : mesh.tet_vertices(t))
        if (w.idx() != v && ok(w.idx())) nb.push_back(w.idx());
  };
  // Phase 1: roots with an untouched star, grown `ring` rings over unaggregated vertices.
  std::vector<std::uint32_t> front, next;
  for (std::uint32_t v = 0; v < nv; ++v) {
    if (!ok(v) || out.of[v] >= 0) continue;
    neighbours(v);
    if (nb.empty() || std::any_of(nb.begin(), nb.end(), [&](std::uint32_t w) { return out.of[w] >= 0; })) continue;
    const std::int32_t id = std::int32_t(out.members.size());
    out.members.emplace_back();
    auto& m = out.members.back();
    out.of[v] = id;
    m.push_back(v);
    front.assign(1, v);
    for (int r = 0; r < ring && !front.empty(); ++r) {
      next.clear();
      for (std::uint32_t u : front) {
        neighbours(u);
        for (std::uint32_t w : nb)
          if (out.of[w] < 0) {
            out.of[w] = id;
            m.push_back(w);
            next.push_back(w);
          }
      }
      front.swap(next);
    }
  }
  const std::int32_t phase1 = std::int32_t(out.members.size());
  // Phase 2: join the phase-1 aggregate most connected to the vertex (decided on phase-1
  // membership only, so aggregates do not creep along chains).
  std::vector<std::int32_t> join(nv, -1);
  for (std::uint32_t v = 0; v < nv; ++v) {
    if (!ok(v) || out.of[v] >= 0) continue;
    neighbours(v);
    std::sort(nb.begin(), nb.end(), [&](std::uint32_t a, std::uint32_t b) { return out.of[a] < out.of[b]; });
    std::int32_t best = -1;
    std::size_t best_n = 0;
    for (std::size_t i = 0; i < nb.size();) {
      const std::int32_t a = out.of[nb[i]];
      std::size_t j = i;
      while (j < nb.size() && out.of[nb[j]] == a) ++j;
      if (a >= 0 && a < phase1 && j - i > best_n) best = a, best_n = j - i;
      i = j;
    }
    join[v] = best;
  }
  for (std::uint32_t v = 0; v < nv; ++v)
    if (join[v] >= 0) {
      out.of[v] = join[v];
      out.members[std::size_t(join[v])].push_back(v);
    }
  // Phase 3: leftovers (their neighbours are all leftovers or ineligible) group by star.
  for (std::uint32_t v = 0; v < nv; ++v) {
    if (!ok(v) || out.of[v] >= 0) continue;
    const std::int32_t id = std::int32_t(out.members.size());
    out.members.emplace_back(1, v);
    out.of[v] = id;
    neighbours(v);
    for (std::uint32_t w : nb)
      if (out.of[w] < 0) {
        out.of[w] = id;
        out.members.back().push_back(w);
      }
  }
  for (auto& m : out.members) std::sort(m.begin(), m.end());
  return out;
}

}  // namespace incise
