#include "cut/specks.h"

#include <algorithm>
#include <unordered_set>

namespace incise::cut_detail {

namespace {

std::uint64_t key(TetId t, int f) { return 4 * std::uint64_t(t.idx()) + std::uint64_t(f); }

}  // namespace

std::size_t keep_specks_attached(const TetMesh& m, std::vector<CutFacePair>& faces, std::span<const VertexId> crease) {
  if (faces.empty() || crease.empty()) return 0;
  IdSet on_crease;
  for (VertexId v : crease) on_crease.insert(v.idx());
  std::unordered_set<std::uint64_t> opening;
  for (const CutFacePair& p : faces)
    for (const FaceRef& r : {p.a, p.b}) opening.insert(key(r.tet, r.local));
  IdSet seen;  // tets already in a group looked at
  std::unordered_set<std::uint64_t> keep;  // faces (both sides) that stay shut
  std::size_t specks = 0;
  std::vector<TetId> group;
  for (const CutFacePair& p : faces)
    for (const FaceRef& start : {p.a, p.b}) {
      if (!m.is_alive(start.tet) || seen.count(start.tet.idx())) continue;
      // The group `start` would belong to once `faces` are open: tets joined across faces that
      // stay interior, stopping as soon as it is larger than a speck.
      group.assign(1, start.tet);
      IdSet in{start.tet.idx()};
      bool closed = true;
      for (std::size_t i = 0; i < group.size() && closed; ++i)
        for (int f = 0; f < 4; ++f) {
          const TetId n = m.neighbor(group[i], f);
          if (!n.is_valid() || opening.count(key(group[i], f)) || in.count(n.idx())) continue;
          if (group.size() == kSpeckTets) {
            closed = false;
            break;
          }
          in.insert(n.idx());
          group.push_back(n);
        }
      for (TetId t : group) seen.insert(t.idx());
      if (!closed) continue;
      bool at_crease = false;
      for (TetId t : group)
        for (VertexId v : m.tet_vertices(t)) at_crease = at_crease || on_crease.count(v.idx());
      if (!at_crease) continue;
      // Its largest face among those about to open stays shut.
      double largest = -1;
      std::uint64_t best = 0;
      for (TetId t : group)
        for (int f = 0; f < 4; ++f) {
          if (!opening.count(key(t, f))) continue;
          const auto fv = m.face_vertices(t, f);
          const double area = (m.rest(fv[1]) - m.rest(fv[0])).cross(m.rest(fv[2]) - m.rest(fv[0])).norm();
          if (area > largest) largest = area, best = key(t, f);
        }
      if (largest < 0) continue;
      keep.insert(best);
      ++specks;
    }
  if (keep.empty()) return 0;
  std::erase_if(faces, [&](const CutFacePair& p) { return keep.count(key(p.a.tet, p.a.local)) || keep.count(key(p.b.tet, p.b.local)); });
  return specks;
}

}  // namespace incise::cut_detail
