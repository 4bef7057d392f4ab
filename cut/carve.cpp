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

namespace {

// Tets of v's star grouped by adjacency across faces that contain v (and, when `w` is valid,
// only tets that contain w too: the fans around edge vw).
std::vector<std::vector<TetId>> fans(const TetMesh& mesh, VertexId v, VertexId w) {
  std::vector<TetId> tets;
  for (TetId t : mesh.incident_tets(v))
    if (!w.is_valid() || mesh.local_index(t, w) >= 0) tets.push_back(t);
  std::vector<int> comp(tets.size(), -1);
  std::vector<std::vector<TetId>> out;
  for (std::size_t i = 0; i < tets.size(); ++i) {
    if (comp[i] >= 0) continue;
    out.emplace_back();
    std::vector<std::size_t> stack{i};
    comp[i] = int(out.size()) - 1;
    while (!stack.empty()) {
      const TetId t = tets[stack.back()];
      stack.pop_back();
      out.back().push_back(t);
      for (int f = 0; f < 4; ++f) {
        if (f == mesh.local_index(t, v) || (w.is_valid() && f == mesh.local_index(t, w))) continue;
        const TetId n = mesh.neighbor(t, f);
        const auto it = std::find(tets.begin(), tets.end(), n);
        if (!n.is_valid() || it == tets.end() || comp[std::size_t(it - tets.begin())] >= 0) continue;
        comp[std::size_t(it - tets.begin())] = comp[i];
        stack.push_back(std::size_t(it - tets.begin()));
      }
    }
  }
  return out;
}

}  // namespace

namespace {

// True when the boundary faces around v form one fan (or there are none): the same test as
// validate()'s, on v's star only.
bool link_is_disk(const TetMesh& mesh, VertexId v) {
  std::vector<std::pair<VertexId, VertexId>> edges;
  for (TetId t : mesh.incident_tets(v)) {
    const int lv = mesh.local_index(t, v);
    for (int f = 0; f < 4; ++f) {
      if (f == lv || mesh.neighbor(t, f).is_valid()) continue;
      const auto fv = mesh.face_vertices(t, f);
      const int k = fv[0] == v ? 0 : fv[1] == v ? 1 : 2;
      edges.emplace_back(fv[(k + 1) % 3], fv[(k + 2) % 3]);
    }
  }
  if (edges.empty()) return true;
  std::size_t steps = 0;
  VertexId cur = edges.front().first;
  do {
    const auto it = std::find_if(edges.begin(), edges.end(), [&](const auto& e) { return e.first == cur; });
    if (it == edges.end()) return false;
    cur = it->second;
    ++steps;
  } while (cur != edges.front().first && steps <= edges.size());
  return steps == edges.size();
}

}  // namespace

void repair_manifold(TetMesh& mesh, std::vector<VertexId>& touched, IdSet& doomed,
                     const std::function<void(TetId)>& remove) {
  for (;;) {
    // Edges first: a non-manifold edge (several fans of tets meeting only along it) loses
    // every fan but the largest; that exposes faces and may pinch more edges, so the loop
    // also visits the vertices the removals append.
    for (std::size_t i = 0; i < touched.size(); ++i) {
      const VertexId v = touched[i];
      if (!mesh.is_alive(v)) continue;
      std::vector<VertexId> others;
      for (TetId t : mesh.incident_tets(v))
        for (VertexId w : mesh.tet_vertices(t))
          if (w != v) others.push_back(w);
      std::sort(others.begin(), others.end());
      others.erase(std::unique(others.begin(), others.end()), others.end());
      for (VertexId w : others) {
        auto f = fans(mesh, v, w);
        if (f.size() < 2) continue;
        std::sort(f.begin(), f.end(), [](const auto& a, const auto& b) { return a.size() > b.size(); });
        for (std::size_t k = 1; k < f.size(); ++k)
          for (TetId t : f[k]) {
            doomed.insert(t.idx());
            remove(t);
          }
      }
    }
    // Then vertices: a star in several face-connected parts (touching at the vertex only)
    // gets one vertex per part, as the cutter does when it opens a cut.
    std::sort(touched.begin(), touched.end());
    touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
    const std::size_t n = touched.size();
    for (std::size_t i = 0; i < n; ++i) {
      const VertexId v = touched[i];
      if (!mesh.is_alive(v)) continue;
      auto parts = fans(mesh, v, VertexId());
      if (parts.size() < 2) continue;
      std::sort(parts.begin(), parts.end(), [](const auto& a, const auto& b) { return a.size() > b.size(); });
      for (std::size_t k = 1; k < parts.size(); ++k) {
        const VertexId parent[1] = {v};
        const double one[1] = {1.0};
        const VertexId nv = mesh.add_vertex_interpolated(parent, one);
        for (TetId t : parts[k]) mesh.replace_vertex(t, v, nv);
        touched.push_back(nv);
      }
    }
    // Last, a connected star whose boundary is not one fan (e.g. a ring of tets left around
    // the vertex): nothing but removing the star makes it manifold; then check again.
    std::vector<VertexId> bad;
    for (VertexId v : touched)
      if (mesh.is_alive(v) && !link_is_disk(mesh, v)) bad.push_back(v);
    if (bad.empty()) return;
    for (VertexId v : bad) {
      if (!mesh.is_alive(v)) continue;
      const auto star = mesh.incident_tets(v);
      for (TetId t : std::vector<TetId>(star.begin(), star.end()))
        if (mesh.is_alive(t)) {
          doomed.insert(t.idx());
          remove(t);
        }
    }
  }
}

CarveResult carve(TetMesh& mesh, std::span<const Piece> pieces, std::span<const TetId> seeds,
                  const std::function<std::vector<TetId>()>& fallback, const std::function<Vec3(VertexId)>& positions) {
  CarveResult r;
  CutStep finder(mesh, positions, 0);
  IdSet doomed;
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
  // Removing tets one by one: each exposes its live neighbours' faces (tagged kTagCut) and
  // hands their vertices to the manifold repair below.
  std::vector<VertexId> touched;
  IdSet nb;
  auto remove = [&](TetId t) {
    for (int f = 0; f < 4; ++f) {
      const TetId n = mesh.neighbor(t, f);
      if (!n.is_valid() || doomed.count(n.idx())) continue;
      for (int g = 0; g < 4; ++g)
        if (mesh.neighbor(n, g) == t) {
          // set after removal: the face is interior until then
          r.exposed.emplace_back(n, g);
        }
    }
    for (VertexId v : mesh.tet_vertices(t)) touched.push_back(v);
    mesh.remove_tet(t);
    ++r.removed;
  };
  for (TetId t : doomed_list) remove(t);
  repair_manifold(mesh, touched, doomed, remove);
  for (const auto& [n, g] : r.exposed) {
    if (!mesh.is_alive(n) || mesh.neighbor(n, g).is_valid()) continue;
    mesh.set_face_tag(n, g, kTagCut);
    const auto fv = mesh.face_vertices(n, g);
    r.area += 0.5 * (mesh.rest(fv[1]) - mesh.rest(fv[0])).cross(mesh.rest(fv[2]) - mesh.rest(fv[0])).norm();
    ++r.faces_exposed;
    if (nb.insert(n.idx()).second) r.neighbours.push_back(n);
  }
  std::sort(touched.begin(), touched.end());
  touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
  for (VertexId v : touched)
    if (mesh.is_alive(v) && mesh.incident_tets(v).empty()) mesh.remove_vertex(v);
  return r;
}

}  // namespace incise::cut_detail
