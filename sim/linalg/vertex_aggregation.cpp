#include "sim/linalg/vertex_aggregation.h"

#include <algorithm>

namespace incise {

void aggregate_more(const TetMesh& mesh, const std::vector<std::uint8_t>& eligible, int ring,
                    std::span<const std::uint32_t> pool, VertexAggregates& out) {
  const std::size_t nv = mesh.vertex_capacity();
  if (out.of.size() < std::max(nv, eligible.size())) out.of.resize(std::max(nv, eligible.size()), -1);
  auto ok = [&](std::size_t v) {
    return v < nv && v < eligible.size() && eligible[v] && mesh.is_alive(VertexId(std::uint32_t(v)));
  };
  // The neighbours of each pool vertex with repeats (one per shared tet, which phase 2
  // counts), gathered once: every phase reads them. Vertices outside the pool are read only
  // as neighbours (already aggregated, or not eligible).
  std::vector<std::uint32_t> start(pool.size() + 1, 0), adj;
  adj.reserve(pool.size() * 16);
  for (std::size_t k = 0; k < pool.size(); ++k) {
    const std::uint32_t v = pool[k];
    if (ok(v) && out.of[v] < 0)
      for (TetId t : mesh.incident_tets(VertexId(v)))
        for (VertexId w : mesh.tet_vertices(t))
          if (w.idx() != v && ok(w.idx())) adj.push_back(w.idx());
    start[k + 1] = std::uint32_t(adj.size());
  }
  // Pool index of a vertex, for the ring growth: a table by vertex id kept per thread, set at
  // the pool's vertices and reset there on return (a patch's pool is a few hundred vertices of
  // the mesh: no allocation as long as the mesh).
  thread_local std::vector<std::int32_t> slot_of;
  auto slot = [&](std::uint32_t v) -> std::int32_t { return v < slot_of.size() ? slot_of[v] : -1; };
  for (std::size_t k = 0; k < pool.size(); ++k) {
    if (pool[k] >= slot_of.size()) slot_of.resize(std::size_t(pool[k]) + 1, -1);
    slot_of[pool[k]] = std::int32_t(k);
  }
  struct Reset {
    std::span<const std::uint32_t> pool;
    ~Reset() {
      for (std::uint32_t v : pool) slot_of[v] = -1;
    }
  } reset{pool};
  auto nbrs = [&](std::int32_t k) {
    return std::span<const std::uint32_t>(adj.data() + start[std::size_t(k)], adj.data() + start[std::size_t(k) + 1]);
  };
  const std::int32_t first = std::int32_t(out.members.size());
  // Phase 1: roots with an untouched star, grown `ring` rings over unaggregated pool vertices.
  std::vector<std::uint32_t> front, next;
  for (std::size_t k = 0; k < pool.size(); ++k) {
    const std::uint32_t v = pool[k];
    if (!ok(v) || out.of[v] >= 0) continue;
    const auto nb = nbrs(std::int32_t(k));
    if (nb.empty() ||
        std::any_of(nb.begin(), nb.end(), [&](std::uint32_t w) { return out.of[w] >= 0 || slot(w) < 0; }))
      continue;
    const std::int32_t id = std::int32_t(out.members.size());
    out.members.emplace_back();
    auto& m = out.members.back();
    out.of[v] = id;
    m.push_back(v);
    front.assign(1, v);
    for (int r = 0; r < ring && !front.empty(); ++r) {
      next.clear();
      for (std::uint32_t u : front)
        for (std::uint32_t w : nbrs(slot(u)))
          if (out.of[w] < 0 && slot(w) >= 0) {
            out.of[w] = id;
            m.push_back(w);
            next.push_back(w);
          }
      front.swap(next);
    }
  }
  const std::int32_t phase1 = std::int32_t(out.members.size());
  // Phase 2: join the phase-1 aggregate (of this call) most connected to the vertex, decided
  // on phase-1 membership only, so aggregates do not creep along chains.
  std::vector<std::int32_t> join(pool.size(), -1);
  std::vector<std::uint32_t> nb;
  for (std::size_t k = 0; k < pool.size(); ++k) {
    const std::uint32_t v = pool[k];
    if (!ok(v) || out.of[v] >= 0) continue;
    const auto span = nbrs(std::int32_t(k));
    nb.assign(span.begin(), span.end());
    std::sort(nb.begin(), nb.end(), [&](std::uint32_t a, std::uint32_t b) { return out.of[a] < out.of[b]; });
    std::int32_t best = -1;
    std::size_t best_n = 0;
    for (std::size_t i = 0; i < nb.size();) {
      const std::int32_t a = out.of[nb[i]];
      std::size_t j = i;
      while (j < nb.size() && out.of[nb[j]] == a) ++j;
      if (a >= first && a < phase1 && j - i > best_n) best = a, best_n = j - i;
      i = j;
    }
    join[k] = best;
  }
  for (std::size_t k = 0; k < pool.size(); ++k)
    if (join[k] >= 0) {
      out.of[pool[k]] = join[k];
      out.members[std::size_t(join[k])].push_back(pool[k]);
    }
  // Phase 3: leftovers (no phase-1 aggregate among their neighbours) group by star.
  for (std::size_t k = 0; k < pool.size(); ++k) {
    const std::uint32_t v = pool[k];
    if (!ok(v) || out.of[v] >= 0) continue;
    const std::int32_t id = std::int32_t(out.members.size());
    out.members.emplace_back(1, v);
    out.of[v] = id;
    for (std::uint32_t w : nbrs(std::int32_t(k)))
      if (out.of[w] < 0 && slot(w) >= 0) {
        out.of[w] = id;
        out.members.back().push_back(w);
      }
  }
  for (std::size_t a = std::size_t(first); a < out.members.size(); ++a)
    std::sort(out.members[a].begin(), out.members[a].end());
}

VertexAggregates aggregate_vertices(const TetMesh& mesh, const std::vector<std::uint8_t>& eligible, int ring) {
  std::vector<std::uint32_t> all(mesh.vertex_capacity());
  for (std::uint32_t v = 0; v < all.size(); ++v) all[v] = v;
  VertexAggregates out;
  aggregate_more(mesh, eligible, ring, all, out);
  return out;
}

}  // namespace incise
