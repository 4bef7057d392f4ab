#include "quality/collapse.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "mesh/edge_collapse.h"
#include "mesh/point_locator.h"
#include "quality/surface_star.h"

namespace incise {

namespace {

Vec3 face_normal(const TetMesh& m, const SurfaceFace& f) {
  const Vec3 n = (m.rest(f.v[1]) - m.rest(f.v[0])).cross(m.rest(f.v[2]) - m.rest(f.v[0]));
  const double l = n.norm();
  return l > 0 ? Vec3(n / l) : Vec3::Zero();
}

}  // namespace

CollapseCheck check_surface_contraction(const TetMesh& mesh, VertexId keep, VertexId remove,
                                        const CollapseOptions& opt) {
  CollapseCheck refused;
  refused.refusal = CollapseRefusal::Boundary;
  const std::vector<std::uint64_t> sheets = surface_sheets(mesh, remove);
  if (sheets.empty()) return refused;
  const double cos_feature = std::cos(opt.feature_angle_deg * std::numbers::pi / 180);
  const auto features = feature_neighbours(mesh, remove, cos_feature);
  if (features.size() == 1 || features.size() > 2) return refused;  // a corner, or a feature's end
  if (features.size() == 2) {  // a crease vertex stays on its line, which may not fold onto another
    if (std::find(features.begin(), features.end(), keep.idx()) == features.end()) return refused;
    const auto at_keep = feature_neighbours(mesh, keep, cos_feature);
    for (std::uint32_t w : features)
      if (w != keep.idx() && std::find(at_keep.begin(), at_keep.end(), w) != at_keep.end()) return refused;
  }
  if (!surface_link_ok(mesh, keep, remove)) return refused;
  CollapseCheck c = check_collapse(mesh, keep, remove, 1.0);
  if (!c.ok()) return c;
  double h = 0;
  const auto around = surface_neighbours(mesh, remove);
  for (std::uint32_t w : around) h += (mesh.rest(VertexId(w)) - mesh.rest(remove)).norm();
  const double bound = opt.surface_deviation * h / double(std::max<std::size_t>(around.size(), 1));
  const Vec3 p = mesh.rest(remove);
  const auto faces = surface_faces_after(mesh, keep, keep, remove);
  // The boundary may not fold: every two boundary faces on an edge at `keep` afterwards bend
  // no more than the feature angle, or than the sharpest pair at either end before (a sharper
  // rim would lower the bound every mesh of the body is held to).
  auto sharpest = [&](std::span<const SurfaceFace> fs) {
    double worst = 1;
    for (std::size_t i = 0; i < fs.size(); ++i)
      for (std::size_t j = i + 1; j < fs.size(); ++j) {
        if (fs[i].sheet != kBoundarySheet || fs[j].sheet != kBoundarySheet) continue;
        int shared = 0;
        for (VertexId a : fs[i].v) shared += std::find(fs[j].v.begin(), fs[j].v.end(), a) != fs[j].v.end();
        if (shared == 2) worst = std::min(worst, face_normal(mesh, fs[i]).dot(face_normal(mesh, fs[j])));
      }
    return worst;
  };
  const double before = std::min({cos_feature, sharpest(surface_faces_after(mesh, keep, {}, {})),
                                  sharpest(surface_faces_after(mesh, remove, {}, {}))});
  if (sharpest(faces) < before) return refused;
  for (std::uint64_t sheet : sheets) {
    double best = 1e300;
    for (const SurfaceFace& f : faces)
      if (f.sheet == sheet)
        best = std::min(best, (p - closest_on_triangle(p, mesh.rest(f.v[0]), mesh.rest(f.v[1]), mesh.rest(f.v[2]))).norm());
    if (!(best <= bound)) return refused;
  }
  return c;
}

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
      if (opt.surface_deviation > 0 &&
          (c.refusal == CollapseRefusal::Boundary || c.refusal == CollapseRefusal::Labels))
        c = check_surface_contraction(mesh, keep, remove, opt);
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
