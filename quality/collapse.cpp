#include "quality/collapse.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <span>

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

double signed_volume(const TetMesh& m, const std::array<VertexId, 4>& v) {
  const Vec3& a = m.rest(v[0]);
  return (m.rest(v[1]) - a).dot((m.rest(v[2]) - a).cross(m.rest(v[3]) - a)) / 6;
}

bool holds(std::span<const TetId> tets, TetId t) { return std::find(tets.begin(), tets.end(), t) != tets.end(); }

// CollapseOptions::restore_volume: the shift of `keep`, after the plan, that gives the label of
// the two stars back the volume the plan moves (zero where it moves none, nothing where no
// shift may: see there). A star's volume is linear in its centre's position, so the shift
// is exact: along d, by -dV / (g . d) for the volume's gradient g, d being g without its
// components across the cut planes at the two vertices (cut faces stay in their planes).
std::optional<Vec3> volume_restoring_shift(const TetMesh& mesh, const CollapsePlan& plan, double bound) {
  int label = mesh.label(*mesh.incident_tets(plan.remove).begin());
  double before = 0, after = 0, scale = 0;
  for (TetId t : mesh.incident_tets(plan.remove)) {
    if (mesh.label(t) != label) return std::nullopt;
    const double v = signed_volume(mesh, mesh.tet_vertices(t));
    before += v;
    scale += std::abs(v);
  }
  for (const auto& tv : plan.tets) after += signed_volume(mesh, tv);
  const double dv = after - before;
  if (std::abs(dv) <= 1e-10 * scale) return Vec3::Zero();  // an exact retiling, up to rounding
  // The gradient of the volume of keep's star after the plan, over its tets' faces opposite keep.
  const Vec3 p = mesh.rest(plan.keep);
  Vec3 g = Vec3::Zero();
  auto add = [&](const std::array<VertexId, 4>& tv) {
    int i = 0;
    while (tv[std::size_t(i)] != plan.keep) ++i;
    const Vec3 &a = mesh.rest(tv[std::size_t((i + 1) % 4)]), &b = mesh.rest(tv[std::size_t((i + 2) % 4)]),
               &c = mesh.rest(tv[std::size_t((i + 3) % 4)]);
    Vec3 n = (b - a).cross(c - a);
    if (n.dot(p - a) < 0) n = -n;
    g += n / 6;
  };
  for (TetId t : mesh.incident_tets(plan.keep)) {
    if (holds(plan.removed, t)) continue;
    if (mesh.label(t) != label) return std::nullopt;
    add(mesh.tet_vertices(t));
  }
  for (const auto& tv : plan.tets) add(tv);
  // The cut planes at either vertex: an orthonormal set of their normals.
  std::vector<Vec3> planes;
  for (VertexId v : {plan.keep, plan.remove})
    for (TetId t : mesh.incident_tets(v))
      for (int f = 0; f < 4; ++f) {
        const auto& tv = mesh.tet_vertices(t);
        if (tv[std::size_t(f)] == v || mesh.neighbor(t, f).is_valid() || mesh.face_tag(t, f) != kTagCut) continue;
        std::array<Vec3, 3> q;
        for (int k = 0, j = 0; k < 4; ++k)
          if (k != f) q[std::size_t(j++)] = mesh.rest(tv[std::size_t(k)]);
        Vec3 n = (q[1] - q[0]).cross(q[2] - q[0]);
        if (!(n.norm() > 0)) return std::nullopt;
        n.normalize();
        for (const Vec3& e : planes) n -= n.dot(e) * e;
        if (n.norm() > 1e-3) planes.push_back(n.normalized());
      }
  if (planes.size() >= 3) return std::nullopt;
  Vec3 d = g;
  for (const Vec3& e : planes) d -= d.dot(e) * e;
  if (!(d.squaredNorm() >= 0.01 * g.squaredNorm()) || !(g.squaredNorm() > 0)) return std::nullopt;
  const Vec3 shift = (-dv / g.dot(d)) * d;
  // At most `bound` times the mean surface edge at keep.
  double h = 0;
  const auto around = surface_neighbours(mesh, plan.keep);
  for (std::uint32_t w : around) h += (mesh.rest(VertexId(w)) - p).norm();
  if (!(shift.norm() <= bound * h / double(std::max<std::size_t>(around.size(), 1)))) return std::nullopt;
  return shift;
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
  Vec3 best_shift = Vec3::Zero();
  std::vector<std::array<VertexId, 4>> after_tets;
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
      Vec3 shift = Vec3::Zero();
      if (opt.restore_volume) {
        const auto s = volume_restoring_shift(mesh, c.plan, std::max(opt.surface_deviation, opt.tolerance));
        if (!s) continue;
        shift = *s;
        c.plan.volume_change = 0;
      }
      const bool moves_keep = shift != Vec3::Zero();
      if (moves_keep && opt.frozen && opt.frozen->count(keep.idx())) continue;
      AngleQuality before;
      for (TetId u : mesh.incident_tets(remove)) before.combine(angle_quality(mesh, u, scope.targets));
      AngleQuality after;
      if (!moves_keep) {
        after = angle_quality(mesh, c.plan.tets, scope.targets);
      } else {
        // keep's other tets change shape too: judged with the rebuilt ones, where the shift puts
        // keep (set for the evaluation, put back after).
        after_tets = c.plan.tets;
        bool keep_in_scope = true;
        for (TetId u : mesh.incident_tets(keep))
          if (!holds(c.plan.removed, u)) {
            keep_in_scope = keep_in_scope && scope.contains(u);
            before.combine(angle_quality(mesh, u, scope.targets));
            after_tets.push_back(mesh.tet_vertices(u));
          }
        if (!keep_in_scope) continue;
        const Vec3 at = mesh.rest(keep);
        mesh.set_rest(keep, at + shift);
        bool upright = true;
        for (const auto& q : after_tets) {
          double l = 0;
          for (int a = 0; a < 4; ++a)
            for (int b = a + 1; b < 4; ++b)
              l = std::max(l, (mesh.rest(q[std::size_t(a)]) - mesh.rest(q[std::size_t(b)])).norm());
          upright = upright && signed_volume(mesh, q) > 1e-12 * l * l * l;
        }
        after = angle_quality(mesh, after_tets, scope.targets);
        mesh.set_rest(keep, at);
        if (!upright) continue;
      }
      if (!better(after, before, scope.targets)) continue;
      if (!best || after.q > best_q.q) {
        best = std::move(c.plan);
        best_q = after;
        best_shift = shift;
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
  const Vec3 target = mesh.rest(best->keep) + best_shift;
  collapse_edge(mesh, *best);
  if (best_shift != Vec3::Zero()) {
    std::vector<VertexId> parents;
    std::vector<double> weights;
    star_coordinates(mesh, out.kept, target, parents, weights);  // weights < 0 where it moved out
    mesh.move_vertex(out.kept, parents, weights);
    out.kept_moved = true;
    for (TetId u : mesh.incident_tets(out.kept))
      if (!holds(out.rebuilt, u)) {
        out.removed.push_back(u);
        out.rebuilt.push_back(u);
      }
  }
  return out;
}

}  // namespace incise
