#include "quality/boundary_flips.h"

#include <algorithm>
#include <cmath>
#include <map>

#include "mesh/errors.h"
#include "quality/edge_removal.h"

namespace incise {

namespace {

bool has_edge(const TetMesh& mesh, VertexId x, VertexId y) {
  for (TetId t : mesh.incident_tets(x))
    if (mesh.local_index(t, y) >= 0) return true;
  return false;
}

// Local face of t holding vertices x, y, z (the one opposite its fourth vertex).
int face_of(const TetMesh& mesh, TetId t, VertexId x, VertexId y, VertexId z) {
  for (int f = 0; f < 4; ++f) {
    const VertexId o = mesh.tet_vertices(t)[f];
    if (o != x && o != y && o != z) return f;
  }
  return -1;
}

using FaceKey = std::array<std::uint32_t, 3>;
FaceKey key(VertexId x, VertexId y, VertexId z) {
  FaceKey k{x.idx(), y.idx(), z.idx()};
  std::sort(k.begin(), k.end());
  return k;
}

// The new tets of a triangulation of the open ring, as TetMesh::remove_edge builds them.
std::vector<std::array<VertexId, 4>> new_tets(const std::vector<VertexId>& ring, VertexId a, VertexId b,
                                              const std::vector<std::array<int, 3>>& tris) {
  std::vector<std::array<VertexId, 4>> out;
  for (const auto& t : tris) {
    out.push_back({ring[t[0]], ring[t[1]], ring[t[2]], b});
    out.push_back({ring[t[0]], ring[t[2]], ring[t[1]], a});
  }
  return out;
}

}  // namespace

std::optional<BoundaryEdgeRemoval> plan_boundary_edge_removal(const TetMesh& mesh, VertexId a, VertexId b,
                                                              const ImproveScope& scope, int max_ring,
                                                              const SurfaceReshape* reshape) {
  TetMesh::EdgeStar star;
  try {
    star = mesh.edge_star(a, b);
  } catch (const InvalidMesh&) {
    return std::nullopt;
  }
  const int m = static_cast<int>(star.tets.size());
  if (star.closed || m < 1 || m + 1 > max_ring || (m == 1 && !reshape)) return std::nullopt;
  for (TetId t : star.tets)
    if (!scope.contains(t) || mesh.label(t) != mesh.label(star.tets.front())) return std::nullopt;
  const VertexId c0 = star.ring.front(), cm = star.ring.back();
  const TetId t0 = star.tets.front(), tm = star.tets.back();
  const int f0 = face_of(mesh, t0, a, b, c0), fm = face_of(mesh, tm, a, b, cm);
  if (mesh.neighbor(t0, f0).is_valid() || mesh.neighbor(tm, fm).is_valid()) return std::nullopt;
  if (mesh.face_tag(t0, f0) != mesh.face_tag(tm, fm)) return std::nullopt;
  // Coplanar: c_m on the plane of (a, b, c_0), to a tiny fraction of the quad's size.
  const Vec3 pa = mesh.rest(a), pb = mesh.rest(b), p0 = mesh.rest(c0), pm = mesh.rest(cm);
  const Vec3 n = (pb - pa).cross(p0 - pa);
  const double h = std::max({(pb - pa).norm(), (p0 - pa).norm(), (pm - pa).norm()});
  const bool coplanar = m > 1 && n.norm() > 0 && std::abs(n.normalized().dot(pm - pa)) <= 1e-10 * h;
  double six_v = 0;  // 6 V(a, b, c0, cm): what the surface moves by
  if (!coplanar) {
    // A cut is made of tet faces exactly where the blade went: its faces never move.
    if (!reshape || mesh.face_tag(t0, f0) == kTagCut) return std::nullopt;
    // The old edge must stay near the new one (a cap triangle's long edge, a gently bent quad).
    const Vec3 u = pb - pa, w = pm - p0;
    const double cross = u.cross(w).norm(), shorter = std::min(u.norm(), w.norm());
    if (!(cross > 0)) return std::nullopt;
    six_v = std::abs(u.cross(p0 - pa).dot(pm - pa));
    if (six_v / cross > reshape->deviation * shorter) return std::nullopt;
  }
  if (m == 1) {
    // Peeling t0 off: its two other faces must be interior (c0-cm not yet on the boundary) and
    // a, b must keep other tets.
    for (int f = 0; f < 4; ++f)
      if (f != f0 && f != fm && !mesh.neighbor(t0, f).is_valid()) return std::nullopt;
    if (mesh.incident_tets(a).size() < 2 || mesh.incident_tets(b).size() < 2) return std::nullopt;
    try {
      if (!mesh.edge_star(c0, cm).closed) return std::nullopt;
    } catch (const InvalidMesh&) {
      return std::nullopt;
    }
  } else if (has_edge(mesh, c0, cm)) {
    return std::nullopt;
  }
  std::vector<Vec3> ring;
  for (VertexId c : star.ring) ring.push_back(mesh.rest(c));
  RingTriangulation best;  // m = 1: no tets at all, nothing worse than before
  if (m > 1) best = best_ring_triangulation(ring, pa, pb, scope.targets);
  AngleQuality before;
  for (TetId t : star.tets) before.combine(angle_quality(mesh, t, scope.targets));
  if (!(best.worst.q > 0) || !better(best.worst, before, scope.targets)) return std::nullopt;
  // Clearly positive, so no evaluation order can see a new tet flat or inverted.
  for (const auto& q : new_tets(star.ring, a, b, best.triangles)) {
    const Vec3 e1 = mesh.rest(q[1]) - mesh.rest(q[0]), e2 = mesh.rest(q[2]) - mesh.rest(q[0]),
               e3 = mesh.rest(q[3]) - mesh.rest(q[0]);
    const double l = std::max({e1.norm(), e2.norm(), e3.norm()});
    if (!(e1.dot(e2.cross(e3)) > 1e-12 * l * l * l)) return std::nullopt;
  }
  // Interior diagonals of the triangulation must be new edges.
  for (const auto& t : best.triangles)
    for (int k = 0; k < 3; ++k) {
      const int i = std::min(t[k], t[(k + 1) % 3]), j = std::max(t[k], t[(k + 1) % 3]);
      if (j - i > 1 && !(i == 0 && j == m) && has_edge(mesh, star.ring[i], star.ring[j])) return std::nullopt;
    }
  // Tiling: the new tets' volumes add up to the star's, plus or minus the tet (a, b, c0, cm)
  // when the faces were not coplanar (a ridge loses it, a valley gains it).
  double v_old = 0, v_new = 0;
  for (TetId t : star.tets) v_old += mesh.volume(t);
  for (const auto& q : new_tets(star.ring, a, b, best.triangles))
    v_new += (mesh.rest(q[1]) - mesh.rest(q[0])).cross(mesh.rest(q[2]) - mesh.rest(q[0])).dot(mesh.rest(q[3]) - mesh.rest(q[0])) / 6;
  const double change = coplanar ? 0 : v_new - v_old;
  if (!coplanar) {
    if (std::abs(std::abs(change) - six_v / 6) > 1e-9 * v_old) return std::nullopt;
    if (reshape->volume && !reshape->volume->allows(mesh.label(t0), change)) return std::nullopt;
  }
  return BoundaryEdgeRemoval{a, b, std::move(best.triangles), best.worst, star.tets, change, mesh.label(t0)};
}

std::vector<TetId> remove_boundary_edge(TetMesh& mesh, const BoundaryEdgeRemoval& plan) {
  const TetMesh::EdgeStar star = mesh.edge_star(plan.a, plan.b);
  if (star.tets != plan.removed) throw InvalidArgument("remove_boundary_edge: the plan is stale");
  const VertexId c0 = star.ring.front(), cm = star.ring.back();
  // Boundary tags of the old tets, by vertex set; the quad's two new faces take its tag.
  std::map<FaceKey, std::uint16_t> tags;
  std::uint16_t quad_tag = kTagNone;
  for (TetId t : star.tets)
    for (int f = 0; f < 4; ++f)
      if (!mesh.neighbor(t, f).is_valid()) {
        const auto fv = mesh.face_vertices(t, f);
        tags[key(fv[0], fv[1], fv[2])] = mesh.face_tag(t, f);
        // The quad's faces hold the edge itself (every tet of the star holds a and b, but a
        // tet at a rim also has a face of another tag, e.g. a cut face beside the surface).
        const bool has_a = fv[0] == plan.a || fv[1] == plan.a || fv[2] == plan.a;
        const bool has_b = fv[0] == plan.b || fv[1] == plan.b || fv[2] == plan.b;
        if (has_a && has_b) quad_tag = mesh.face_tag(t, f);
      }
  tags[key(plan.a, c0, cm)] = quad_tag;
  tags[key(plan.b, c0, cm)] = quad_tag;
  const int label = mesh.label(star.tets.front());
  // A peeled tet (one in the star) exposes its neighbours' faces (a, c0, cm), (b, c0, cm).
  std::vector<TetId> beside;
  if (star.tets.size() == 1)
    for (int f = 0; f < 4; ++f)
      if (mesh.neighbor(star.tets[0], f).is_valid()) beside.push_back(mesh.neighbor(star.tets[0], f));
  for (TetId t : star.tets) mesh.remove_tet(t);
  for (TetId t : beside)
    for (int f = 0; f < 4; ++f)
      if (!mesh.neighbor(t, f).is_valid()) {
        const auto fv = mesh.face_vertices(t, f);
        const FaceKey k = key(fv[0], fv[1], fv[2]);
        if (k == key(plan.a, c0, cm) || k == key(plan.b, c0, cm)) mesh.set_face_tag(t, f, quad_tag);
      }
  std::vector<TetId> out;
  for (const auto& q : new_tets(star.ring, plan.a, plan.b, plan.triangles))
    out.push_back(mesh.add_tet(q[0], q[1], q[2], q[3], label));
  for (TetId t : out)
    for (int f = 0; f < 4; ++f)
      if (!mesh.neighbor(t, f).is_valid()) {
        const auto fv = mesh.face_vertices(t, f);
        auto it = tags.find(key(fv[0], fv[1], fv[2]));
        if (it != tags.end()) mesh.set_face_tag(t, f, it->second);
      }
  return out;
}

}  // namespace incise
