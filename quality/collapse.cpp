#include "quality/collapse.h"

#include <algorithm>

#include "mesh/edge_collapse.h"

namespace incise {

std::optional<CollapseOutcome> improve_by_collapse(TetMesh& mesh, TetId t, const ImproveScope& scope,
                                                   const CollapseOptions& opt) {
  const auto tv = mesh.tet_vertices(t);
  struct Edge {
    double len;
    int i, j;
  };
  std::vector<Edge> edges;
  double longest = 0;
  for (int i = 0; i < 4; ++i)
    for (int j = i + 1; j < 4; ++j) {
      const double l = (mesh.rest(tv[i]) - mesh.rest(tv[j])).norm();
      edges.push_back({l, i, j});
      longest = std::max(longest, l);
    }
  std::sort(edges.begin(), edges.end(), [](const Edge& a, const Edge& b) { return a.len < b.len; });
  auto removable = [&](VertexId v) {
    if (opt.frozen && opt.frozen->count(v.idx())) return false;
    if (!opt.remove_boundary)
      for (TetId u : mesh.incident_tets(v))
        for (int f = 0; f < 4; ++f)
          if (!mesh.neighbor(u, f).is_valid() && mesh.tet_vertices(u)[f] != v) return false;
    return true;
  };
  std::optional<CollapsePlan> best;
  AngleQuality best_q;
  // The two shortest edges at most: a cap or a sliver has one or two short ones.
  for (int e = 0; e < 2; ++e) {
    if (!(edges[e].len < opt.edge_ratio * longest)) break;
    for (int dir = 0; dir < 2; ++dir) {
      const VertexId keep = tv[dir ? edges[e].j : edges[e].i], remove = tv[dir ? edges[e].i : edges[e].j];
      if (!removable(remove)) continue;
      bool in_scope = true;
      for (TetId u : mesh.incident_tets(remove)) in_scope = in_scope && scope.contains(u);
      if (!in_scope) continue;
      CollapseCheck c = check_collapse(mesh, keep, remove, opt.tolerance);
      if (!c.ok()) continue;
      AngleQuality before;
      for (TetId u : mesh.incident_tets(remove)) before.combine(angle_quality(mesh, u, scope.targets));
      const AngleQuality after = angle_quality(mesh, c.plan.tets, scope.targets);
      if (!better(after, before, scope.targets)) continue;
      if (!best || after.q > best_q.q) {
        best = std::move(c.plan);
        best_q = after;
      }
    }
  }
  if (!best) return std::nullopt;
  CollapseOutcome out;
  out.kept = best->keep;
  out.removed_vertex = best->remove;
  out.removed = best->removed;
  out.removed.insert(out.removed.end(), best->rebuilt.begin(), best->rebuilt.end());
  out.rebuilt = best->rebuilt;
  out.volume_change = best->volume_change;
  collapse_edge(mesh, *best);
  return out;
}

}  // namespace incise
