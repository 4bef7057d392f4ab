#include "quality/surface_star.h"

#include <algorithm>
#include <iterator>
#include <map>
#include <set>

namespace incise {

bool is_surface_face(const TetMesh& m, TetId t, int f) {
  const TetId u = m.neighbor(t, f);
  return !u.is_valid() || m.label(u) != m.label(t);
}

std::uint64_t patch_of(const TetMesh& m, TetId t, int f) {
  const TetId u = m.neighbor(t, f);
  if (!u.is_valid()) return kBoundarySheet | m.face_tag(t, f);
  auto a = std::uint32_t(m.label(t)), b = std::uint32_t(m.label(u));
  if (a > b) std::swap(a, b);
  return (std::uint64_t(a) << 32) | b;
}

std::uint64_t sheet_of(const TetMesh& m, TetId t, int f) {
  const TetId u = m.neighbor(t, f);
  return u.is_valid() ? patch_of(m, t, f) : kBoundarySheet;
}

Vec3 patch_normal(const TetMesh& m, TetId t, int f) {
  const auto fv = m.face_vertices(t, f);
  Vec3 n = (m.rest(fv[1]) - m.rest(fv[0])).cross(m.rest(fv[2]) - m.rest(fv[0]));
  const TetId u = m.neighbor(t, f);
  if (u.is_valid() && m.label(u) < m.label(t)) n = -n;
  const double l = n.norm();
  return l > 0 ? Vec3(n / l) : Vec3::Zero();
}

std::vector<SurfaceFace> surface_faces_after(const TetMesh& m, VertexId v, VertexId keep, VertexId remove) {
  std::vector<SurfaceFace> out;
  std::set<std::array<std::uint32_t, 3>> seen;
  auto gather = [&](VertexId at) {
    for (TetId t : m.incident_tets(at))
      for (int f = 0; f < 4; ++f) {
        if (m.tet_vertices(t)[f] == at || !is_surface_face(m, t, f)) continue;
        auto fv = m.face_vertices(t, f);
        if (remove.is_valid())
          for (VertexId& w : fv)
            if (w == remove) w = keep;
        if (fv[0] == fv[1] || fv[1] == fv[2] || fv[0] == fv[2]) continue;
        if (std::find(fv.begin(), fv.end(), v) == fv.end()) continue;
        std::array<std::uint32_t, 3> k{fv[0].idx(), fv[1].idx(), fv[2].idx()};
        std::sort(k.begin(), k.end());
        if (seen.insert(k).second) out.push_back({fv, sheet_of(m, t, f)});
      }
  };
  gather(v);
  if (remove.is_valid() && v == keep) gather(remove);
  return out;
}

std::vector<std::uint64_t> surface_sheets(const TetMesh& m, VertexId v) {
  std::vector<std::uint64_t> out;
  for (TetId t : m.incident_tets(v))
    for (int f = 0; f < 4; ++f)
      if (m.tet_vertices(t)[f] != v && is_surface_face(m, t, f)) out.push_back(sheet_of(m, t, f));
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

std::vector<std::uint32_t> surface_neighbours(const TetMesh& m, VertexId v) {
  std::vector<std::uint32_t> out;
  for (TetId t : m.incident_tets(v))
    for (int f = 0; f < 4; ++f) {
      if (m.tet_vertices(t)[f] == v || !is_surface_face(m, t, f)) continue;
      for (VertexId w : m.face_vertices(t, f))
        if (w != v) out.push_back(w.idx());
    }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

bool surface_link_ok(const TetMesh& m, VertexId keep, VertexId remove) {
  const auto nk = surface_neighbours(m, keep), nr = surface_neighbours(m, remove);
  if (!std::binary_search(nr.begin(), nr.end(), keep.idx())) return false;  // not a surface edge
  std::vector<std::uint32_t> common, apex;
  std::set_intersection(nk.begin(), nk.end(), nr.begin(), nr.end(), std::back_inserter(common));
  for (TetId t : m.incident_tets(remove)) {
    if (m.local_index(t, keep) < 0) continue;
    for (int f = 0; f < 4; ++f) {
      const VertexId opp = m.tet_vertices(t)[f];
      if (opp == keep || opp == remove || !is_surface_face(m, t, f)) continue;
      for (VertexId w : m.face_vertices(t, f))
        if (w != keep && w != remove) apex.push_back(w.idx());
    }
  }
  std::sort(apex.begin(), apex.end());
  apex.erase(std::unique(apex.begin(), apex.end()), apex.end());
  return common == apex;
}

std::vector<std::uint32_t> feature_neighbours(const TetMesh& m, VertexId v, double cos_feature) {
  std::map<std::uint32_t, EdgeFaceTally> edges;
  std::set<std::array<std::uint32_t, 3>> seen;  // an interface face is seen from both sides
  for (TetId t : m.incident_tets(v))
    for (int f = 0; f < 4; ++f) {
      if (m.tet_vertices(t)[f] == v || !is_surface_face(m, t, f)) continue;
      const auto fv = m.face_vertices(t, f);
      std::array<std::uint32_t, 3> k{fv[0].idx(), fv[1].idx(), fv[2].idx()};
      std::sort(k.begin(), k.end());
      if (!seen.insert(k).second) continue;
      const std::uint64_t patch = patch_of(m, t, f);
      const Vec3 n = patch_normal(m, t, f);
      for (VertexId w : fv)
        if (w != v) edges[w.idx()].add(patch, n);
    }
  std::vector<std::uint32_t> out;
  for (const auto& [w, e] : edges)
    if (e.feature(cos_feature)) out.push_back(w);
  return out;
}

}  // namespace incise
