#include "cut/separate.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <unordered_map>
#include <unordered_set>

namespace incise::cut_detail {

namespace {
std::uint32_t face_key(TetId t, int f) { return 4 * t.idx() + std::uint32_t(f); }

// Components of v's star: tets joined across faces that contain v and are not blocked.
std::vector<std::vector<TetId>> star_components(const TetMesh& mesh, VertexId v,
                                                const IdSet& blocked) {
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

// The cut face with vertices x, y, z (an interior face), both sides; nullopt when gone.
std::optional<CutFacePair> find_face(const TetMesh& mesh, const std::array<VertexId, 3>& xyz) {
  for (TetId t : mesh.incident_tets(xyz[0])) {
    const int ly = mesh.local_index(t, xyz[1]), lz = mesh.local_index(t, xyz[2]);
    if (ly < 0 || lz < 0) continue;
    const int f = 6 - mesh.local_index(t, xyz[0]) - ly - lz;
    const TetId n = mesh.neighbor(t, f);
    if (!n.is_valid()) return std::nullopt;
    for (int g = 0; g < 4; ++g)
      if (mesh.neighbor(n, g) == t) return CutFacePair{{t, f}, {n, g}};
    return std::nullopt;
  }
  return std::nullopt;
}

// The tets around edge v-w, grouped into arcs: runs of tets joined across faces of the edge
// that are neither blocked nor boundary.
struct EdgeArcs {
  std::vector<TetId> ring;
  std::vector<int> arc;
  int arcs = 0;
};
EdgeArcs edge_arcs(const TetMesh& mesh, VertexId v, VertexId w, const IdSet& blocked) {
  EdgeArcs e;
  for (TetId t : mesh.incident_tets(v))
    if (mesh.local_index(t, w) >= 0) e.ring.push_back(t);
  e.arc.assign(e.ring.size(), -1);
  for (std::size_t i = 0; i < e.ring.size(); ++i) {
    if (e.arc[i] >= 0) continue;
    std::vector<std::size_t> stack{i};
    e.arc[i] = e.arcs;
    while (!stack.empty()) {
      const TetId t = e.ring[stack.back()];
      stack.pop_back();
      const int lv = mesh.local_index(t, v), lw = mesh.local_index(t, w);
      for (int f = 0; f < 4; ++f) {
        if (f == lv || f == lw || blocked.count(face_key(t, f))) continue;
        const TetId n = mesh.neighbor(t, f);
        for (std::size_t j = 0; j < e.ring.size(); ++j)
          if (e.ring[j] == n && e.arc[j] < 0) {
            e.arc[j] = e.arcs;
            stack.push_back(j);
          }
      }
    }
    ++e.arcs;
  }
  return e;
}

// Smallest angle of triangle abc, in degrees.
double min_angle(const Vec3& a, const Vec3& b, const Vec3& c) {
  auto angle = [](const Vec3& p, const Vec3& q, const Vec3& r) {
    return std::atan2((q - p).cross(r - p).norm(), (q - p).dot(r - p)) * 180 / 3.14159265358979323846;
  };
  return std::min({angle(a, b, c), angle(b, c, a), angle(c, a, b)});
}
// A chord is split only where the halves of the cut faces through it keep this angle.
constexpr double kMinChordAngle = 10;

// Whether splitting edge a-b at its midpoint gives children of clearly positive rest volume.
bool midpoint_split_ok(const TetMesh& mesh, VertexId a, VertexId b) {
  const Vec3 p = 0.5 * (mesh.rest(a) + mesh.rest(b));
  for (TetId t : mesh.incident_tets(a)) {
    if (mesh.local_index(t, b) < 0) continue;
    const auto& tv = mesh.tet_vertices(t);
    double l2 = 0;
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j) l2 = std::max(l2, (mesh.rest(tv[i]) - mesh.rest(tv[j])).squaredNorm());
    const double margin = 1e-13 * l2 * std::sqrt(l2);
    for (VertexId moved : {a, b}) {
      std::array<Vec3, 4> x;
      for (int i = 0; i < 4; ++i) x[i] = tv[i] == moved ? p : mesh.rest(tv[i]);
      if (!((x[1] - x[0]).dot((x[2] - x[0]).cross(x[3] - x[0])) > margin)) return false;
    }
  }
  return true;
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
  IdMap<std::vector<std::size_t>> at;  // vertex -> cut faces containing it
  std::vector<VertexId> work;
  for (std::size_t i = 0; i < faces.size(); ++i)
    for (VertexId v : mesh.face_vertices(faces[i].a.tet, faces[i].a.local)) {
      auto& list = at[v.idx()];
      if (list.empty()) work.push_back(v);
      list.push_back(i);
    }
  IdMap<std::uint32_t> parent;
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
    IdMap<std::vector<std::size_t>> groups;
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

// A chord: an edge of the cut surface whose two vertices both keep a single star component
// (both on the rim: a corner of the blade inside the body and a vertex on each of the two
// segments meeting there, or two rim vertices across a strip of the cut narrower than an
// element) with cut faces on both sides of it. Opening those faces would give the edge four
// boundary faces, so they stayed shut, which left their other vertices undivided and closed
// their neighbours in turn (a third of a swept area on a box). Split at its midpoint, the
// chord becomes two edges to a vertex inside the cut surface, which separates: the rim is then
// the only place where the two sides stay joined.
struct ChordSplit {
  VertexId v, w, mid;  // mid invalid: no chord left
};
ChordSplit split_a_chord(TetMesh& mesh, std::span<const CutFacePair> faces,
                         const IdSet& blocked,
                         const IdMap<std::vector<std::vector<TetId>>>& comps_of,
                         std::unordered_set<std::uint64_t>& unsplittable) {
  auto single = [&](VertexId x) {
    auto it = comps_of.find(x.idx());
    return it != comps_of.end() && it->second.size() == 1;
  };
  std::unordered_set<std::uint64_t> tried;
  for (const CutFacePair& p : faces) {
    const auto fv = mesh.face_vertices(p.a.tet, p.a.local);
    for (int k = 0; k < 3; ++k) {
      const VertexId v = fv[std::size_t(k)], w = fv[std::size_t((k + 1) % 3)];
      if (!single(v) || !single(w)) continue;
      const std::uint64_t key = (std::uint64_t(std::min(v.idx(), w.idx())) << 32) | std::max(v.idx(), w.idx());
      if (unsplittable.count(key) || !tried.insert(key).second) continue;
      if (edge_arcs(mesh, v, w, blocked).arcs < 2) continue;  // a rim edge: cut faces on one side only
      // A face through the chord that cannot open otherwise (its third vertex on the rim too)
      // and whose third vertex lies near the chord's line would leave a sliver half (and a flat
      // tet beside it that no later pass repairs): that face, a sliver of little area, stays
      // shut instead, and the faces that open do not need the split (only opening faces count
      // around an edge, below).
      bool thin = false;
      for (const CutFacePair& q : faces) {
        const auto qv = mesh.face_vertices(q.a.tet, q.a.local);
        if (std::find(qv.begin(), qv.end(), v) == qv.end() || std::find(qv.begin(), qv.end(), w) == qv.end()) continue;
        VertexId x;
        for (VertexId y : qv)
          if (y != v && y != w) x = y;
        if (!single(x)) continue;  // a face that opens anyway: the chord must go
        const Vec3 a = mesh.rest(v), b = mesh.rest(w), m = 0.5 * (a + b), c = mesh.rest(x);
        thin = thin || min_angle(a, m, c) < kMinChordAngle || min_angle(m, b, c) < kMinChordAngle;
      }
      if (thin || !midpoint_split_ok(mesh, v, w)) {  // it stays a chord
        unsplittable.insert(key);
        continue;
      }
      return {v, w, mesh.split_edge(v, w, 0.5)};
    }
  }
  return {};
}

// Finds the faces (given by their vertices) again after a chord split replaced tets; a face
// through the chord is now its two halves.
std::vector<CutFacePair> refind_faces(const TetMesh& mesh, const std::vector<std::array<VertexId, 3>>& triples,
                                      const ChordSplit& s) {
  std::vector<CutFacePair> out;
  for (const auto& xyz : triples) {
    const bool hv = std::find(xyz.begin(), xyz.end(), s.v) != xyz.end();
    const bool hw = std::find(xyz.begin(), xyz.end(), s.w) != xyz.end();
    if (hv && hw) {
      VertexId x;
      for (VertexId y : xyz)
        if (y != s.v && y != s.w) x = y;
      for (const std::array<VertexId, 3>& half : {std::array<VertexId, 3>{x, s.v, s.mid}, std::array<VertexId, 3>{x, s.mid, s.w}})
        if (auto f = find_face(mesh, half)) out.push_back(*f);
    } else if (auto f = find_face(mesh, xyz)) {
      out.push_back(*f);
    }
  }
  return out;
}

SeparationResult separate(TetMesh& mesh, std::span<const CutFacePair> all_faces, bool split_chords) {
  SeparationResult r;
  // A cut face opens only if one of its vertices ends up with its two tets in different star
  // components; faces along the front (all three vertices undivided) stay closed. The pinch
  // analysis must see only the faces that open, and dropping faces changes components, so the
  // two alternate until nothing changes (faces only ever leave the set; a chord split halves
  // the faces through the chord, and chords only get fewer).
  std::vector<CutFacePair> all(all_faces.begin(), all_faces.end());  // the input, through chord splits
  std::vector<CutFacePair> faces = all;
  IdSet blocked;
  std::vector<VertexId> verts;
  IdMap<std::vector<std::vector<TetId>>> comps_of;
  std::unordered_set<std::uint64_t> unsplittable;
  auto triples = [&](const std::vector<CutFacePair>& list) {
    std::vector<std::array<VertexId, 3>> out;
    out.reserve(list.size());
    for (const CutFacePair& p : list) out.push_back(mesh.face_vertices(p.a.tet, p.a.local));
    return out;
  };
  for (;;) {
    faces = drop_pinches(mesh, faces, r.faces_dropped);
    blocked.clear();
    verts.clear();
    comps_of.clear();
    IdSet seen;
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
    if (split_chords) {
      const auto all_t = triples(all), faces_t = triples(faces);
      const ChordSplit s = split_a_chord(mesh, faces, blocked, comps_of, unsplittable);
      if (s.mid.is_valid()) {
        all = refind_faces(mesh, all_t, s);
        faces = refind_faces(mesh, faces_t, s);
        r.splits.push_back({s.mid, s.v, s.w});
        continue;
      }
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
    // the boundary faces already there); two arcs that keep the same copies of both edge
    // vertices would give the edge four boundary faces (two sheets touching along it). Those
    // faces stay closed.
    std::unordered_map<std::uint64_t, std::vector<std::size_t>> around;  // edge -> opening faces
    for (std::size_t i = 0; i < opening.size(); ++i) {
      const auto fv = mesh.face_vertices(opening[i].a.tet, opening[i].a.local);
      for (int k = 0; k < 3; ++k) {
        const std::uint32_t a = fv[std::size_t(k)].idx(), b = fv[std::size_t((k + 1) % 3)].idx();
        around[(std::uint64_t(std::min(a, b)) << 32) | std::max(a, b)].push_back(i);
      }
    }
    // Faces that do not open stay joined whatever the set says: only opening faces (and the
    // boundary) cut the ring around an edge. (Counting a face that stays shut, e.g. one with
    // all three vertices on the rim, made its edge look like two sheets meeting.)
    IdSet opened;
    for (const CutFacePair& p : opening) {
      opened.insert(face_key(p.a.tet, p.a.local));
      opened.insert(face_key(p.b.tet, p.b.local));
    }
    std::vector<char> drop(opening.size(), 0);
    for (const auto& [key, list] : around) {
      // (A single new face also counts: the edge may already be the tip of an earlier cut.)
      const VertexId v(std::uint32_t(key >> 32)), w(std::uint32_t(key & 0xffffffffu));
      const EdgeArcs e = edge_arcs(mesh, v, w, opened);
      std::map<std::pair<int, int>, int> copy_arc;
      bool pinch = false;
      for (std::size_t i = 0; i < e.ring.size() && !pinch; ++i) {
        const std::pair<int, int> copies{comp_index[(std::uint64_t(v.idx()) << 32) | e.ring[i].idx()],
                                         comp_index[(std::uint64_t(w.idx()) << 32) | e.ring[i].idx()]};
        auto [it, inserted] = copy_arc.emplace(copies, e.arc[i]);
        pinch = !inserted && it->second != e.arc[i];
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
  // The input faces still shut (dropped, or along the front), with their tets as they are now.
  for (const CutFacePair& p : all)
    if (mesh.is_alive(p.a.tet) && mesh.neighbor(p.a.tet, p.a.local).is_valid()) r.shut.push_back(p);
  return r;
}

}  // namespace incise::cut_detail
