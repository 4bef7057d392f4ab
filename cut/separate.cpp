#include "cut/separate.h"

#include <algorithm>
#include <map>
#include <unordered_map>
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

// Opening the cut faces around v leaves v's boundary manifold only when, in v's link (the
// surface of triangles opposite v), the edges of the cut faces form a connected graph (interior
// v) or every part of that graph reaches the link's boundary (v on the boundary). Otherwise two
// cut sheets would touch at v only (two crack tips meeting at a point, or a sheet touching the
// surface at one vertex): such sheets lose their faces at v (not opened; the cut surface gets
// a hole there the size of v's star), and their other vertices are checked again.
std::vector<CutFacePair> drop_pinches(const TetMesh& mesh, std::span<const CutFacePair> faces, std::size_t& dropped) {
  std::vector<char> active(faces.size(), 1);
  std::unordered_map<std::uint32_t, std::vector<std::size_t>> at;  // vertex -> cut faces containing it
  std::vector<VertexId> work;
  for (std::size_t i = 0; i < faces.size(); ++i)
    for (VertexId v : mesh.face_vertices(faces[i].a.tet, faces[i].a.local)) {
      auto& list = at[v.idx()];
      if (list.empty()) work.push_back(v);
      list.push_back(i);
    }
  std::unordered_map<std::uint32_t, std::uint32_t> parent;
  auto find = [&](std::uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  auto unite = [&](std::uint32_t a, std::uint32_t b) {
    if (!parent.count(a)) parent[a] = a;
    if (!parent.count(b)) parent[b] = b;
    parent[find(a)] = find(b);
  };
  constexpr std::uint32_t kBoundary = 0xffffffffu;  // the link's boundary, as one node
  while (!work.empty()) {
    const VertexId v = work.back();
    work.pop_back();
    parent.clear();
    auto other_two = [&](const std::array<VertexId, 3>& fv) {
      std::array<std::uint32_t, 2> e{};
      int k = 0;
      for (VertexId x : fv)
        if (x != v && k < 2) e[std::size_t(k++)] = x.idx();
      return e;
    };
    bool on_boundary = false;
    for (TetId t : mesh.incident_tets(v)) {
      const int lv = mesh.local_index(t, v);
      for (int f = 0; f < 4; ++f)
        if (f != lv && !mesh.neighbor(t, f).is_valid()) {
          const auto e = other_two(mesh.face_vertices(t, f));
          unite(e[0], kBoundary);
          unite(e[1], kBoundary);
          on_boundary = true;
        }
    }
    std::vector<std::size_t> mine;
    for (std::size_t i : at[v.idx()])
      if (active[i]) {
        const auto e = other_two(mesh.face_vertices(faces[i].a.tet, faces[i].a.local));
        unite(e[0], e[1]);
        mine.push_back(i);
      }
    if (mine.size() < 2 && !on_boundary) continue;
    // Group this vertex's cut faces by the component of their link edge.
    std::unordered_map<std::uint32_t, std::vector<std::size_t>> groups;
    for (std::size_t i : mine) {
      const auto e = other_two(mesh.face_vertices(faces[i].a.tet, faces[i].a.local));
      groups[find(e[0])].push_back(i);
    }
    std::uint32_t keep = kBoundary;
    if (!on_boundary) {
      std::size_t best = 0;
      for (const auto& [root, list] : groups)
        if (list.size() > best) {
          best = list.size();
          keep = root;
        }
    } else {
      keep = find(kBoundary);
    }
    for (const auto& [root, list] : groups) {
      if (root == keep) continue;
      for (std::size_t i : list) {
        active[i] = 0;
        ++dropped;
        for (VertexId x : mesh.face_vertices(faces[i].a.tet, faces[i].a.local))
          if (x != v) work.push_back(x);
      }
    }
  }
  std::vector<CutFacePair> out;
  for (std::size_t i = 0; i < faces.size(); ++i)
    if (active[i]) out.push_back(faces[i]);
  return out;
}

SeparationResult separate(TetMesh& mesh, std::span<const CutFacePair> all_faces) {
  SeparationResult r;
  // A cut face opens only if one of its vertices ends up with its two tets in different star
  // components; faces along the front (all three vertices undivided) stay closed. The pinch
  // analysis must see only the faces that open, and dropping faces changes components, so the
  // two alternate until nothing changes (faces only ever leave the set).
  std::vector<CutFacePair> faces(all_faces.begin(), all_faces.end());
  std::unordered_set<std::uint32_t> blocked;
  std::vector<VertexId> verts;
  std::unordered_map<std::uint32_t, std::vector<std::vector<TetId>>> comps_of;
  for (;;) {
    faces = drop_pinches(mesh, faces, r.faces_dropped);
    blocked.clear();
    verts.clear();
    comps_of.clear();
    std::unordered_set<std::uint32_t> seen;
    for (const CutFacePair& p : faces) {
      blocked.insert(face_key(p.a.tet, p.a.local));
      blocked.insert(face_key(p.b.tet, p.b.local));
      for (VertexId v : mesh.face_vertices(p.a.tet, p.a.local))
        if (seen.insert(v.idx()).second) verts.push_back(v);
    }
    std::unordered_map<std::uint64_t, int> comp_index;  // (vertex, tet) -> component
    for (VertexId v : verts) {
      auto comps = star_components(mesh, v, blocked);
      for (std::size_t c = 0; c < comps.size(); ++c)
        for (TetId t : comps[c]) comp_index[(std::uint64_t(v.idx()) << 32) | t.idx()] = int(c);
      comps_of[v.idx()] = std::move(comps);
    }
    std::vector<CutFacePair> opening;
    for (const CutFacePair& p : faces) {
      bool opens = false;
      for (VertexId v : mesh.face_vertices(p.a.tet, p.a.local))
        opens = opens || comp_index[(std::uint64_t(v.idx()) << 32) | p.a.tet.idx()] !=
                             comp_index[(std::uint64_t(v.idx()) << 32) | p.b.tet.idx()];
      if (opens) opening.push_back(p);
    }
    // Edges: the tets around an edge with opening cut faces fall into arcs between them (and
    // the boundary faces already there); two arcs that keep the same copies of both edge vertices would give the edge four
    // boundary faces (two sheets touching along it). Those faces stay closed.
    std::unordered_map<std::uint64_t, std::vector<std::size_t>> around;  // edge -> opening faces
    for (std::size_t i = 0; i < opening.size(); ++i) {
      const auto fv = mesh.face_vertices(opening[i].a.tet, opening[i].a.local);
      for (int k = 0; k < 3; ++k) {
        const std::uint32_t a = fv[std::size_t(k)].idx(), b = fv[std::size_t((k + 1) % 3)].idx();
        around[(std::uint64_t(std::min(a, b)) << 32) | std::max(a, b)].push_back(i);
      }
    }
    std::vector<char> drop(opening.size(), 0);
    for (const auto& [key, list] : around) {
      // (A single new face also counts: the edge may already be the tip of an earlier cut.)
      const VertexId v(std::uint32_t(key >> 32)), w(std::uint32_t(key & 0xffffffffu));
      std::vector<TetId> ring;
      for (TetId t : mesh.incident_tets(v))
        if (mesh.local_index(t, w) >= 0) ring.push_back(t);
      std::vector<int> arc(ring.size(), -1);
      int arcs = 0;
      for (std::size_t i = 0; i < ring.size(); ++i) {
        if (arc[i] >= 0) continue;
        std::vector<std::size_t> stack{i};
        arc[i] = arcs;
        while (!stack.empty()) {
          const TetId t = ring[stack.back()];
          stack.pop_back();
          for (int f = 0; f < 4; ++f) {
            const int lv = mesh.local_index(t, v), lw = mesh.local_index(t, w);
            if (f == lv || f == lw || blocked.count(face_key(t, f))) continue;
            const TetId n = mesh.neighbor(t, f);
            for (std::size_t j = 0; j < ring.size(); ++j)
              if (ring[j] == n && arc[j] < 0) {
                arc[j] = arcs;
                stack.push_back(j);
              }
          }
        }
        ++arcs;
      }
      std::map<std::pair<int, int>, int> copy_arc;
      bool pinch = false;
      for (std::size_t i = 0; i < ring.size() && !pinch; ++i) {
        const std::pair<int, int> copies{comp_index[(std::uint64_t(v.idx()) << 32) | ring[i].idx()],
                                         comp_index[(std::uint64_t(w.idx()) << 32) | ring[i].idx()]};
        auto [it, inserted] = copy_arc.emplace(copies, arc[i]);
        pinch = !inserted && it->second != arc[i];
      }
      if (pinch)
        for (std::size_t i : list) drop[i] = 1;
    }
    std::vector<CutFacePair> kept;
    for (std::size_t i = 0; i < opening.size(); ++i)
      if (!drop[i]) kept.push_back(opening[i]);
      else ++r.faces_dropped;
    if (kept.size() == faces.size()) break;
    faces = std::move(kept);
  }
  for (VertexId v : verts) {
    auto& comps = comps_of[v.idx()];
    if (comps.size() < 2) continue;  // on the cut front, or the cut does not separate here
    // The largest component keeps v (fewest tets renumbered).
    std::sort(comps.begin(), comps.end(), [](const auto& a, const auto& b) { return a.size() > b.size(); });
    for (std::size_t c = 1; c < comps.size(); ++c) {
      const VertexId parent[1] = {v};
      const double one[1] = {1.0};
      const VertexId nv = mesh.add_vertex_interpolated(parent, one);
      for (TetId t : comps[c]) mesh.replace_vertex(t, v, nv);
      r.duplicates.emplace_back(v, nv);
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
