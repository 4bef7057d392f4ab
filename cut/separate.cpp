#include "cut/separate.h"

#include <algorithm>
#include <unordered_set>

namespace incise::cut_detail {

namespace {
std::uint32_t face_key(TetId t, int f) { return 4 * t.idx() + std::uint32_t(f); }

// Components of v's star: tets joined across faces that contain v and are not blocked.
std::vector<std::vector<TetId>> star_components(const TetMesh& mesh, VertexId v,
                                                const std::unordered_set<std::uint32_t>& blocked) {
  const auto star = mesh.incident_tets(v);
  std::vector<TetId> tets(star.begin(), star.end());
  std::vector<int> comp(tets.size(), -1);
  std::vector<std::vector<TetId>> out;
  for (std::size_t i = 0; i < tets.size(); ++i) {
    if (comp[i] >= 0) continue;
    const int c = int(out.size());
    out.emplace_back();
    std::vector<std::size_t> stack{i};
    comp[i] = c;
    while (!stack.empty()) {
      const std::size_t j = stack.back();
      stack.pop_back();
      const TetId t = tets[j];
      out[c].push_back(t);
      const int lv = mesh.local_index(t, v);
      for (int f = 0; f < 4; ++f) {
        if (f == lv || blocked.count(face_key(t, f))) continue;  // face f contains v iff f != lv
        const TetId n = mesh.neighbor(t, f);
        if (!n.is_valid()) continue;
        const auto it = std::find(tets.begin(), tets.end(), n);
        if (it == tets.end()) continue;
        const std::size_t k = std::size_t(it - tets.begin());
        if (comp[k] < 0) {
          comp[k] = c;
          stack.push_back(k);
        }
      }
    }
  }
  return out;
}
}  // namespace

SeparationResult separate(TetMesh& mesh, std::span<const CutFacePair> faces) {
  SeparationResult r;
  std::unordered_set<std::uint32_t> blocked;
  std::vector<VertexId> verts;
  std::unordered_set<std::uint32_t> seen;
  for (const CutFacePair& p : faces) {
    blocked.insert(face_key(p.a.tet, p.a.local));
    blocked.insert(face_key(p.b.tet, p.b.local));
    for (VertexId v : mesh.face_vertices(p.a.tet, p.a.local))
      if (seen.insert(v.idx()).second) verts.push_back(v);
  }
  for (VertexId v : verts) {
    auto comps = star_components(mesh, v, blocked);
    if (comps.size() < 2) continue;  // on the cut front, or the cut does not separate here
    // The largest component keeps v (fewest tets renumbered).
    std::sort(comps.begin(), comps.end(), [](const auto& a, const auto& b) { return a.size() > b.size(); });
    for (std::size_t c = 1; c < comps.size(); ++c) {
      const VertexId parent[1] = {v};
      const double one[1] = {1.0};
      const VertexId nv = mesh.add_vertex_interpolated(parent, one);
      for (TetId t : comps[c]) mesh.replace_vertex(t, v, nv);
      ++r.vertices_duplicated;
    }
  }
  for (const CutFacePair& p : faces) {
    if (mesh.neighbor(p.a.tet, p.a.local).is_valid()) continue;  // still joined (front only)
    mesh.set_face_tag(p.a.tet, p.a.local, kTagCut);
    mesh.set_face_tag(p.b.tet, p.b.local, kTagCut);
    const auto fv = mesh.face_vertices(p.a.tet, p.a.local);
    r.area += 0.5 * (mesh.rest(fv[1]) - mesh.rest(fv[0])).cross(mesh.rest(fv[2]) - mesh.rest(fv[0])).norm();
    ++r.faces_opened;
    r.opened_tets.push_back(p.a.tet);
    r.opened_tets.push_back(p.b.tet);
  }
  return r;
}

}  // namespace incise::cut_detail
