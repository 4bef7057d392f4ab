#include "cut/carve.h"

#include <algorithm>
#include <unordered_set>

#include "cut/cut_step.h"

namespace incise::cut_detail {

bool tet_intersects_triangle(const std::array<Vec3, 4>& tet, const CutTriangle& tri) {
  static constexpr int kEdges[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};
  auto separated = [&](const Vec3& axis) {
    const double n = axis.norm();
    if (!(n > 0)) return false;
    double a0 = 1e300, a1 = -1e300, b0 = 1e300, b1 = -1e300;
    for (const Vec3& x : tet) {
      const double d = axis.dot(x);
      a0 = std::min(a0, d);
      a1 = std::max(a1, d);
    }
    for (const Vec3& x : tri.p) {
      const double d = axis.dot(x);
      b0 = std::min(b0, d);
      b1 = std::max(b1, d);
    }
    // Touching counts as intersecting; a relative margin absorbs rounding of the projections.
    const double eps = 1e-12 * (std::abs(a0) + std::abs(a1) + std::abs(b0) + std::abs(b1));
    return a1 < b0 - eps || b1 < a0 - eps;
  };
  if (separated(tri.normal())) return false;
  for (int f = 0; f < 4; ++f) {
    const auto& l = kFaceLocal[f];
    if (separated((tet[l[1]] - tet[l[0]]).cross(tet[l[2]] - tet[l[0]]))) return false;
  }
  for (const auto& e : kEdges)
    for (int k = 0; k < 3; ++k)
      if (separated((tet[e[1]] - tet[e[0]]).cross(tri.p[(k + 1) % 3] - tri.p[k]))) return false;
  return true;
}

CarveResult carve(TetMesh& mesh, std::span<const Piece> pieces, std::span<const TetId> seeds,
                  const std::function<std::vector<TetId>()>& fallback, const std::function<Vec3(VertexId)>& positions) {
  CarveResult r;
  CutStep finder(mesh, positions, 0);
  std::unordered_set<std::uint32_t> doomed;
  std::vector<TetId> doomed_list;
  for (const Piece& p : pieces) {
    finder.collect(p, seeds, fallback);
    for (TetId t : finder.live_candidates()) {
      if (doomed.count(t.idx())) continue;
      const auto& tv = mesh.tet_vertices(t);
      const std::array<Vec3, 4> x = {finder.position(tv[0]), finder.position(tv[1]), finder.position(tv[2]),
                                     finder.position(tv[3])};
      for (const CutTriangle& tri : p.triangles)
        if (tet_intersects_triangle(x, tri)) {
          doomed.insert(t.idx());
          doomed_list.push_back(t);
          break;
        }
    }
  }
  // Faces that become boundary: the survivors' sides of faces shared with doomed tets.
  std::vector<std::pair<TetId, int>> exposed;
  std::vector<VertexId> verts;
  for (TetId t : doomed_list)
    for (int f = 0; f < 4; ++f) {
      const TetId n = mesh.neighbor(t, f);
      if (!n.is_valid() || doomed.count(n.idx())) continue;
      for (int g = 0; g < 4; ++g)
        if (mesh.neighbor(n, g) == t) exposed.emplace_back(n, g);
    }
  for (TetId t : doomed_list) {
    for (VertexId v : mesh.tet_vertices(t)) verts.push_back(v);
    mesh.remove_tet(t);
  }
  std::sort(verts.begin(), verts.end());
  verts.erase(std::unique(verts.begin(), verts.end()), verts.end());
  for (VertexId v : verts)
    if (mesh.incident_tets(v).empty()) mesh.remove_vertex(v);
  std::unordered_set<std::uint32_t> nb;
  for (const auto& [n, g] : exposed) {
    mesh.set_face_tag(n, g, kTagCut);
    const auto fv = mesh.face_vertices(n, g);
    r.area += 0.5 * (mesh.rest(fv[1]) - mesh.rest(fv[0])).cross(mesh.rest(fv[2]) - mesh.rest(fv[0])).norm();
    if (nb.insert(n.idx()).second) r.neighbours.push_back(n);
  }
  r.removed = doomed_list.size();
  r.faces_exposed = exposed.size();
  return r;
}

}  // namespace incise::cut_detail
