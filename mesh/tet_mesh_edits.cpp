// Refinement (edge / face / tet splits) and flips (2-3, 3-2, 4-4, edge removal, multi-face
// removal, cavity insertion).
// Every operation is "remove these tets, add those", so incidence upkeep is the one path in
// tet_mesh.cpp and the cost is proportional to the tets involved.
#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include <Eigen/LU>

#include "mesh/errors.h"
#include "mesh/tet_mesh.h"

namespace incise {

namespace {
// A tet built by a flip must be clearly positive: a computed volume of 1e-20 on a
// coplanar configuration can turn negative when the same tet is evaluated with its
// vertices in another order. The margin is relative to the longest edge, so it is scale-free.
bool clearly_positive(const std::array<Vec3, 4>& p) {
  const Vec3 e1 = p[1] - p[0], e2 = p[2] - p[0], e3 = p[3] - p[0];
  double l2 = std::max({e1.squaredNorm(), e2.squaredNorm(), e3.squaredNorm(), (p[2] - p[1]).squaredNorm(),
                        (p[3] - p[1]).squaredNorm(), (p[3] - p[2]).squaredNorm()});
  return e1.dot(e2.cross(e3)) > 1e-12 * l2 * std::sqrt(l2);
}

std::array<std::uint32_t, 3> sorted_key(VertexId a, VertexId b, VertexId c) {
  std::array<std::uint32_t, 3> k{a.idx(), b.idx(), c.idx()};
  std::sort(k.begin(), k.end());
  return k;
}
}  // namespace

void TetMesh::star_split(TetId t, VertexId p, const std::array<double, 4>& w) {
  const auto parent = tet_v_[t.idx()];
  const auto tags = face_tag_[t.idx()];
  const int lab = label_[t.idx()];
  remove_tet(t);
  for (int s = 0; s < 4; ++s) {
    if (!(w[s] > 0)) continue;
    auto child = parent;
    child[s] = p;
    TetId c = add_tet(child[0], child[1], child[2], child[3], lab);
    // Child face j lies in parent face j when j == s (it is that face, shrunk to nothing
    // new) or when p lies on parent face j (w[j] == 0); only those inherit a tag.
    for (int j = 0; j < 4; ++j)
      if ((j == s || w[j] == 0) && !tet_n_[c.idx()][j].is_valid()) face_tag_[c.idx()][j] = tags[j];
  }
}

VertexId TetMesh::split_edge(VertexId a, VertexId b, double s) {
  if (!(s > 0 && s < 1)) throw InvalidArgument("split_edge: parameter must be in (0,1)");
  if (a == b) throw InvalidArgument("split_edge: the edge's two vertices are the same (" + std::to_string(a.idx()) + ")");
  // Every tet containing the edge; no ordering needed, so an edge whose tets form several
  // fans (possible after remove_tet) splits as well.
  std::vector<TetId> around;
  for (TetId t : vertex_tets_[a.idx()]) {
    ++counters_.visits;
    if (local_index(t, b) >= 0) around.push_back(t);
  }
  if (around.empty()) throw InvalidArgument("split_edge: no tet has edge (" + std::to_string(a.idx()) + "," +
                                            std::to_string(b.idx()) + ")");
  const VertexId par[2] = {a, b};
  const double wt[2] = {1 - s, s};
  VertexId p = add_vertex_interpolated(par, wt);
  for (TetId t : around) {
    std::array<double, 4> w{0, 0, 0, 0};
    w[local_index(t, a)] = 1 - s;
    w[local_index(t, b)] = s;
    star_split(t, p, w);
  }
  return p;
}

VertexId TetMesh::split_face(TetId t, int f, const std::array<double, 3>& w) {
  if (!is_alive(t) || f < 0 || f > 3) throw InvalidArgument("split_face: bad tet or face");
  for (double x : w)
    if (!(x > 0)) throw InvalidArgument("split_face: barycentric weights must be positive");
  auto fv = face_vertices(t, f);
  TetId u = tet_n_[t.idx()][f];
  VertexId p = add_vertex_interpolated(fv, w);
  for (TetId x : {t, u}) {
    if (!x.is_valid()) continue;
    std::array<double, 4> wx{0, 0, 0, 0};
    for (int k = 0; k < 3; ++k) wx[local_index(x, fv[k])] = w[k];
    star_split(x, p, wx);
  }
  return p;
}

VertexId TetMesh::split_tet(TetId t, const std::array<double, 4>& w) {
  if (!is_alive(t)) throw InvalidArgument("split_tet: tet is not alive");
  for (double x : w)
    if (!(x > 0)) throw InvalidArgument("split_tet: barycentric weights must be positive");
  // Weights that do not sum to 1 put the vertex outside the tet (its children invert).
  const double sum = w[0] + w[1] + w[2] + w[3];
  if (!(std::abs(sum - 1) <= 1e-6))
    throw InvalidArgument("split_tet: barycentric weights must sum to 1 (they sum to " + std::to_string(sum) + ")");
  VertexId p = add_vertex_interpolated(tet_v_[t.idx()], w);
  star_split(t, p, w);
  return p;
}

std::vector<TetId> TetMesh::retriangulate(std::span<const TetId> old_tets,
                                          std::span<const std::array<VertexId, 4>> new_tets) {
  std::map<std::array<std::uint32_t, 3>, std::uint16_t> tags;
  const int lab = label_[old_tets.front().idx()];
  for (TetId t : old_tets)
    for (int f = 0; f < 4; ++f)
      if (!tet_n_[t.idx()][f].is_valid() && face_tag_[t.idx()][f] != kTagNone) {
        auto fv = face_vertices(t, f);
        tags[sorted_key(fv[0], fv[1], fv[2])] = face_tag_[t.idx()][f];
      }
  for (TetId t : old_tets) remove_tet(t);
  std::vector<TetId> out;
  out.reserve(new_tets.size());
  for (const auto& q : new_tets) {
    TetId c = add_tet(q[0], q[1], q[2], q[3], lab);
    out.push_back(c);
  }
  if (!tags.empty())
    for (TetId c : out)
      for (int f = 0; f < 4; ++f)
        if (!tet_n_[c.idx()][f].is_valid()) {
          auto fv = face_vertices(c, f);
          auto it = tags.find(sorted_key(fv[0], fv[1], fv[2]));
          if (it != tags.end()) face_tag_[c.idx()][f] = it->second;
        }
  return out;
}

bool TetMesh::is_flip23_ok(TetId t, int f) const {
  if (!is_alive(t) || f < 0 || f > 3) return false;
  TetId u = tet_n_[t.idx()][f];
  if (!u.is_valid() || label_[u.idx()] != label_[t.idx()]) return false;
  VertexId a = tet_v_[t.idx()][f];
  int g = -1;
  for (int k = 0; k < 4; ++k)
    if (tet_n_[u.idx()][k] == t) g = k;
  VertexId b = tet_v_[u.idx()][g];
  // The new edge a-b must not exist already.
  for (TetId w : vertex_tets_[a.idx()])
    if (local_index(w, b) >= 0) return false;
  auto x = face_vertices(t, f);
  for (int k = 0; k < 3; ++k)
    if (!clearly_positive({rest_[x[k].idx()], rest_[x[(k + 1) % 3].idx()], rest_[a.idx()], rest_[b.idx()]})) return false;
  return true;
}

std::array<TetId, 3> TetMesh::flip23(TetId t, int f) {
  if (!is_flip23_ok(t, f)) throw InvalidArgument("flip23: flip of tet " + std::to_string(t.idx()) + " face " +
                                                 std::to_string(f) + " is not valid");
  TetId u = tet_n_[t.idx()][f];
  VertexId a = tet_v_[t.idx()][f];
  int g = -1;
  for (int k = 0; k < 4; ++k)
    if (tet_n_[u.idx()][k] == t) g = k;
  VertexId b = tet_v_[u.idx()][g];
  auto x = face_vertices(t, f);
  // (x, y, z) has its normal towards b, so (x_k, x_k+1, a, b) is positively oriented.
  std::array<std::array<VertexId, 4>, 3> q;
  for (int k = 0; k < 3; ++k) q[k] = {x[k], x[(k + 1) % 3], a, b};
  const TetId old[2] = {t, u};
  auto out = retriangulate(old, q);
  return {out[0], out[1], out[2]};
}

std::vector<std::array<VertexId, 4>> TetMesh::edge_removal_tets(const EdgeStar& star, VertexId a, VertexId b,
                                                                std::span<const std::array<int, 3>> triangles) const {
  const int n = static_cast<int>(star.tets.size());
  if (!star.closed || n < 3) throw InvalidArgument("edge removal: edge is on the boundary or has fewer than 3 tets");
  if (static_cast<int>(triangles.size()) != n - 2)
    throw InvalidArgument("edge removal: a ring of " + std::to_string(n) + " needs " + std::to_string(n - 2) +
                          " triangles");
  // A triangulation of the ring polygon uses each ring side once and each diagonal twice.
  std::map<std::pair<int, int>, int> uses;
  std::vector<std::array<VertexId, 4>> out;
  for (auto tri : triangles) {
    std::sort(tri.begin(), tri.end());  // increasing ring order = the ring's orientation
    if (tri[0] < 0 || tri[2] >= n || tri[0] == tri[1] || tri[1] == tri[2])
      throw InvalidArgument("edge removal: bad triangle indices");
    for (int k = 0; k < 3; ++k) ++uses[{std::min(tri[k], tri[(k + 1) % 3]), std::max(tri[k], tri[(k + 1) % 3])}];
    VertexId ci = star.ring[tri[0]], cj = star.ring[tri[1]], ck = star.ring[tri[2]];
    out.push_back({ci, cj, ck, b});
    out.push_back({ci, ck, cj, a});
  }
  for (const auto& [e, cnt] : uses) {
    bool side = (e.second - e.first == 1) || (e.first == 0 && e.second == n - 1);
    if (cnt != (side ? 1 : 2)) throw InvalidArgument("edge removal: triangles do not triangulate the ring");
  }
  if (static_cast<int>(uses.size()) != n + (n - 3)) throw InvalidArgument("edge removal: triangles do not triangulate the ring");
  return out;
}

bool TetMesh::is_edge_removal_ok(VertexId a, VertexId b, std::span<const std::array<int, 3>> triangles) const {
  if (!is_alive(a) || !is_alive(b)) return false;
  EdgeStar star;
  try {
    star = edge_star(a, b);
  } catch (const InvalidMesh&) {
    return false;
  }
  if (!star.closed || star.tets.size() < 3) return false;
  for (TetId t : star.tets)
    if (label_[t.idx()] != label_[star.tets.front().idx()]) return false;
  std::vector<std::array<VertexId, 4>> q;
  try {
    q = edge_removal_tets(star, a, b, triangles);
  } catch (const InvalidArgument&) {
    return false;
  }
  for (const auto& x : q)
    if (!clearly_positive({rest_[x[0].idx()], rest_[x[1].idx()], rest_[x[2].idx()], rest_[x[3].idx()]})) return false;
  // New interior diagonals must not already be mesh edges elsewhere.
  for (const auto& tri : triangles)
    for (int k = 0; k < 3; ++k) {
      int i = std::min(tri[k], tri[(k + 1) % 3]), j = std::max(tri[k], tri[(k + 1) % 3]);
      int n = static_cast<int>(star.ring.size());
      if (j - i == 1 || (i == 0 && j == n - 1)) continue;
      VertexId ci = star.ring[i], cj = star.ring[j];
      for (TetId w : vertex_tets_[ci.idx()])
        if (local_index(w, cj) >= 0) return false;
    }
  return true;
}

std::vector<TetId> TetMesh::remove_edge(VertexId a, VertexId b, std::span<const std::array<int, 3>> triangles) {
  if (!is_edge_removal_ok(a, b, triangles))
    throw InvalidArgument("remove_edge: removing edge (" + std::to_string(a.idx()) + "," + std::to_string(b.idx()) +
                          ") with this triangulation is not valid");
  EdgeStar star = edge_star(a, b);
  auto q = edge_removal_tets(star, a, b, triangles);
  return retriangulate(star.tets, q);
}

bool TetMesh::is_flip32_ok(VertexId a, VertexId b) const {
  const std::array<int, 3> tri[1] = {{0, 1, 2}};
  return is_edge_removal_ok(a, b, tri);
}

std::array<TetId, 2> TetMesh::flip32(VertexId a, VertexId b) {
  const std::array<int, 3> tri[1] = {{0, 1, 2}};
  auto out = remove_edge(a, b, tri);
  return {out[0], out[1]};
}

namespace {
std::array<std::array<int, 3>, 2> flip44_triangles(int k) {
  if (k == 0) return {{{0, 1, 2}, {0, 2, 3}}};
  return {{{1, 2, 3}, {0, 1, 3}}};
}
}  // namespace

bool TetMesh::is_flip44_ok(VertexId a, VertexId b, int k) const {
  if (k != 0 && k != 1) return false;
  auto tri = flip44_triangles(k);
  return is_edge_removal_ok(a, b, tri);
}

std::array<TetId, 4> TetMesh::flip44(VertexId a, VertexId b, int k) {
  if (k != 0 && k != 1) throw InvalidArgument("flip44: k must be 0 or 1");
  auto tri = flip44_triangles(k);
  auto out = remove_edge(a, b, tri);
  return {out[0], out[1], out[2], out[3]};
}

bool TetMesh::multi_face_removal_tets(VertexId u, VertexId w, std::span<const std::array<VertexId, 3>> faces,
                                      std::vector<TetId>& old_tets,
                                      std::vector<std::array<VertexId, 4>>& new_tets) const {
  old_tets.clear();
  new_tets.clear();
  if (!is_alive(u) || !is_alive(w) || u == w || faces.empty()) return false;
  // The new edge u-w must not exist already.
  for (TetId t : vertex_tets_[u.idx()])
    if (local_index(t, w) >= 0) return false;
  // The tet with vertices {f, apex}, found among apex's tets.
  auto tet_with = [&](VertexId apex, const std::array<VertexId, 3>& f) {
    for (TetId t : vertex_tets_[apex.idx()])
      if (local_index(t, f[0]) >= 0 && local_index(t, f[1]) >= 0 && local_index(t, f[2]) >= 0) return t;
    return TetId();
  };
  const std::size_t m = faces.size();
  std::set<std::array<std::uint32_t, 3>> seen;
  std::set<std::pair<std::uint32_t, std::uint32_t>> directed;  // edges of the faces oriented towards w
  std::set<std::uint32_t> verts;
  for (const auto& f : faces) {
    if (!is_alive(f[0]) || !is_alive(f[1]) || !is_alive(f[2])) return false;
    if (!seen.insert(sorted_key(f[0], f[1], f[2])).second) return false;
    const TetId tu = tet_with(u, f), tw = tet_with(w, f);
    if (!tu.is_valid() || !tw.is_valid()) return false;
    const int lab = label_[tu.idx()];
    if (label_[tw.idx()] != lab || (!old_tets.empty() && label_[old_tets[0].idx()] != lab)) return false;
    old_tets.push_back(tu);
    old_tets.push_back(tw);
    // Out of tu = towards w: (x_k, x_k+1, u, w) is positive, as in flip23.
    const auto x = face_vertices(tu, local_index(tu, u));
    for (int k = 0; k < 3; ++k) {
      verts.insert(x[k].idx());
      // The same directed edge twice: two faces fold onto each other.
      if (!directed.insert({x[k].idx(), x[(k + 1) % 3].idx()}).second) return false;
    }
  }
  // The rim: directed edges whose reverse is not there. A disc with every vertex on its rim has
  // m + 2 of them forming one cycle through all m + 2 vertices (an inner vertex would lose its
  // last tets).
  std::map<std::uint32_t, std::uint32_t> next;
  for (const auto& [a, b] : directed)
    if (!directed.count({b, a}) && !next.emplace(a, b).second) return false;
  if (next.size() != m + 2 || verts.size() != m + 2) return false;
  std::uint32_t v = next.begin()->first;
  for (std::size_t k = 0; k < m + 2; ++k) {
    const auto it = next.find(v);
    if (it == next.end()) return false;
    new_tets.push_back({VertexId(it->first), VertexId(it->second), u, w});
    v = it->second;
  }
  if (v != next.begin()->first) return false;
  std::set<std::uint32_t> on_rim;
  for (const auto& q : new_tets) on_rim.insert(q[0].idx());
  return on_rim.size() == m + 2;
}

bool TetMesh::is_multi_face_removal_ok(VertexId u, VertexId w, std::span<const std::array<VertexId, 3>> faces) const {
  std::vector<TetId> old_tets;
  std::vector<std::array<VertexId, 4>> q;
  if (!multi_face_removal_tets(u, w, faces, old_tets, q)) return false;
  // Every new tet positive is enough: the new tets have the old ones' outer faces (the cones of
  // the rim from u and from w), so positive ones tile exactly the old region.
  for (const auto& x : q)
    if (!clearly_positive({rest_[x[0].idx()], rest_[x[1].idx()], rest_[x[2].idx()], rest_[x[3].idx()]})) return false;
  return true;
}

std::vector<TetId> TetMesh::remove_faces(VertexId u, VertexId w, std::span<const std::array<VertexId, 3>> faces) {
  if (!is_multi_face_removal_ok(u, w, faces))
    throw InvalidArgument("remove_faces: removing " + std::to_string(faces.size()) + " faces between vertices " +
                          std::to_string(u.idx()) + " and " + std::to_string(w.idx()) + " is not valid");
  std::vector<TetId> old_tets;
  std::vector<std::array<VertexId, 4>> q;
  multi_face_removal_tets(u, w, faces, old_tets, q);
  return retriangulate(old_tets, q);
}

std::vector<std::array<VertexId, 3>> TetMesh::cavity_boundary(std::span<const TetId> cavity) const {
  std::vector<std::array<VertexId, 3>> faces;
  if (cavity.empty()) return faces;
  std::set<std::uint32_t> in;
  const int lab = is_alive(cavity.front()) ? label_[cavity.front().idx()] : 0;
  for (TetId t : cavity)
    if (!is_alive(t) || label_[t.idx()] != lab || !in.insert(t.idx()).second) return {};
  for (TetId t : cavity)
    for (int f = 0; f < 4; ++f) {
      const TetId n = tet_n_[t.idx()][f];
      if (n.is_valid() && in.count(n.idx())) continue;
      const auto x = face_vertices(t, f);  // outward: reversed, it faces the inside
      faces.push_back({x[0], x[2], x[1]});
    }
  return faces;
}

namespace {
// The checks of a cavity insertion at p over the cavity's boundary `faces`; the cones over
// `oriented` (all faces but those a boundary insertion splits) must be clearly positive.
bool cavity_ok(const std::vector<std::array<VertexId, 3>>& faces, std::span<const std::array<VertexId, 4>> tets,
               const std::vector<Vec3>& rest, const Vec3& p,
               const std::vector<std::array<VertexId, 3>>& oriented) {
  if (faces.empty()) return false;
  // Edge-manifold boundary: each edge in two faces, once in each direction.
  std::set<std::pair<std::uint32_t, std::uint32_t>> directed;
  std::set<std::uint32_t> on_boundary;
  for (const auto& f : faces)
    for (int k = 0; k < 3; ++k) {
      on_boundary.insert(f[k].idx());
      if (!directed.insert({f[k].idx(), f[(k + 1) % 3].idx()}).second) return false;
    }
  for (const auto& [a, b] : directed)
    if (!directed.count({b, a})) return false;
  for (const auto& tv : tets)
    for (VertexId v : tv)
      if (!on_boundary.count(v.idx())) return false;  // it would lose all its tets
  for (const auto& f : oriented)
    if (!clearly_positive({rest[f[0].idx()], rest[f[1].idx()], rest[f[2].idx()], p})) return false;
  return true;
}
}  // namespace

bool TetMesh::is_cavity_insertion_ok(std::span<const TetId> cavity, const Vec3& p) const {
  std::vector<std::array<VertexId, 4>> tv;
  for (TetId t : cavity)
    if (is_alive(t)) tv.push_back(tet_v_[t.idx()]);
  const auto faces = cavity_boundary(cavity);
  return cavity_ok(faces, tv, rest_, p, faces);
}

VertexId TetMesh::insert_in_cavity(std::span<const TetId> cavity, std::span<const VertexId> parents,
                                   std::span<const double> weights) {
  Vec3 p = Vec3::Zero();
  for (std::size_t k = 0; k < parents.size() && k < weights.size(); ++k)
    if (is_alive(parents[k])) p += weights[k] * rest_[parents[k].idx()];
  if (parents.empty() || parents.size() != weights.size() || !is_cavity_insertion_ok(cavity, p))
    throw InvalidArgument("insert_in_cavity: inserting into " + std::to_string(cavity.size()) +
                          " tets is not valid");
  const auto faces = cavity_boundary(cavity);
  const std::vector<TetId> old(cavity.begin(), cavity.end());  // cavity may alias mesh data
  std::vector<std::array<VertexId, 4>> around;
  for (TetId t : old) around.push_back(tet_v_[t.idx()]);
  const VertexId v = add_vertex_interpolated(parents, weights);
  express_before_moves(pending_vertices_.back(), around, p);
  std::vector<std::array<VertexId, 4>> q;
  q.reserve(faces.size());
  for (const auto& f : faces) q.push_back({f[0], f[1], f[2], v});
  retriangulate(old, q);
  return v;
}

void TetMesh::express_before_moves(VertexOrigin& o, std::span<const std::array<VertexId, 4>> around,
                                   const Vec3& p) const {
  if (batch_origin_.empty()) return;
  bool moved = false;
  for (VertexId x : o.parents) moved = moved || (x.is_valid() && batch_origin_.count(x.idx()));
  if (!moved) return;
  const auto origin = [&](VertexId x) {
    const auto it = batch_origin_.find(x.idx());
    return it == batch_origin_.end() ? rest_[x.idx()] : it->second;
  };
  // The tet whose smallest barycentric coordinate of p is largest (inside if any holds it;
  // otherwise linear extrapolation, still exact for affine fields). Flat ones are skipped.
  double best = -1e300;
  for (const auto& t : around) {
    const Vec3 x0 = origin(t[0]);
    Eigen::Matrix3d m;
    for (int k = 0; k < 3; ++k) m.col(k) = origin(t[k + 1]) - x0;
    const double l = std::max({m.col(0).norm(), m.col(1).norm(), m.col(2).norm()});
    if (!(std::abs(m.determinant()) > 1e-9 * l * l * l)) continue;
    const Vec3 b = m.partialPivLu().solve(p - x0);
    const std::array<double, 4> w = {1 - b.sum(), b[0], b[1], b[2]};
    const double lo = *std::min_element(w.begin(), w.end());
    if (lo > best) {
      best = lo;
      o.parents = t;
      o.weights = w;
    }
  }
}

namespace {
// The cavity boundary faces a boundary insertion splits: faces of the mesh boundary (no tet
// across) holding every parent. Empty when there are not 1 (point in a face) or 2 (on an edge).
std::vector<int> split_faces(const TetMesh& m, std::span<const TetId> cavity, std::span<const VertexId> parents,
                             const std::vector<std::array<VertexId, 3>>& faces) {
  std::vector<int> out;
  std::size_t i = 0;
  for (TetId t : cavity)  // the order cavity_boundary lists faces in
    for (int f = 0; f < 4; ++f) {
      const TetId n = m.neighbor(t, f);
      if (n.is_valid() && std::find(cavity.begin(), cavity.end(), n) != cavity.end()) continue;
      if (!n.is_valid()) {
        bool all = true;
        for (VertexId p : parents) all = all && std::find(faces[i].begin(), faces[i].end(), p) != faces[i].end();
        if (all) out.push_back(static_cast<int>(i));
      }
      ++i;
    }
  if (out.size() != (parents.size() == 3 ? 1u : 2u)) out.clear();
  return out;
}
}  // namespace

bool TetMesh::is_boundary_cavity_insertion_ok(std::span<const TetId> cavity, std::span<const VertexId> parents,
                                              std::span<const double> weights) const {
  if ((parents.size() != 2 && parents.size() != 3) || weights.size() != parents.size()) return false;
  Vec3 p = Vec3::Zero();
  for (std::size_t k = 0; k < parents.size(); ++k) {
    if (!is_alive(parents[k]) || !(weights[k] > 0)) return false;
    p += weights[k] * rest_[parents[k].idx()];
  }
  const auto faces = cavity_boundary(cavity);
  if (faces.empty()) return false;
  const auto skip = split_faces(*this, cavity, parents, faces);
  if (skip.empty()) return false;
  std::vector<std::array<VertexId, 4>> tv;
  for (TetId c : cavity) tv.push_back(tet_v_[c.idx()]);
  // The split faces' cones are flat (p lies in them); every other cone must be positive.
  std::vector<std::array<VertexId, 3>> rest_faces;
  for (std::size_t i = 0; i < faces.size(); ++i)
    if (std::find(skip.begin(), skip.end(), static_cast<int>(i)) == skip.end()) rest_faces.push_back(faces[i]);
  return cavity_ok(faces, tv, rest_, p, rest_faces);
}

VertexId TetMesh::insert_in_cavity_on_boundary(std::span<const TetId> cavity, std::span<const VertexId> parents,
                                               std::span<const double> weights) {
  if (!is_boundary_cavity_insertion_ok(cavity, parents, weights))
    throw InvalidArgument("insert_in_cavity_on_boundary: inserting into " + std::to_string(cavity.size()) +
                          " tets is not valid");
  const auto faces = cavity_boundary(cavity);
  const auto skip = split_faces(*this, cavity, parents, faces);
  // Tags of the split faces, by their vertex sets.
  std::vector<std::pair<std::array<VertexId, 3>, std::uint16_t>> split;
  for (TetId t : cavity)
    for (int f = 0; f < 4; ++f)
      if (!tet_n_[t.idx()][f].is_valid()) {
        const auto fv = face_vertices(t, f);
        for (int i : skip)
          if (sorted_key(fv[0], fv[1], fv[2]) == sorted_key(faces[i][0], faces[i][1], faces[i][2]))
            split.push_back({fv, face_tag_[t.idx()][f]});
      }
  const std::vector<TetId> old(cavity.begin(), cavity.end());
  std::vector<std::array<VertexId, 4>> around;
  for (TetId t : old) around.push_back(tet_v_[t.idx()]);
  const VertexId v = add_vertex_interpolated(parents, weights);
  express_before_moves(pending_vertices_.back(), around, rest_[v.idx()]);
  std::vector<std::array<VertexId, 4>> q;
  for (std::size_t i = 0; i < faces.size(); ++i)
    if (std::find(skip.begin(), skip.end(), static_cast<int>(i)) == skip.end())
      q.push_back({faces[i][0], faces[i][1], faces[i][2], v});
  // A new boundary face (x, y, v) is a part of the split face holding x and y.
  for (TetId c : retriangulate(old, q))
    for (int g = 0; g < 4; ++g) {
      if (tet_n_[c.idx()][g].is_valid() || tet_v_[c.idx()][g] == v) continue;
      const auto fv = face_vertices(c, g);
      for (const auto& [sf, tag] : split) {
        int shared = 0;
        for (VertexId x : fv) shared += x != v && std::find(sf.begin(), sf.end(), x) != sf.end();
        if (shared == 2) face_tag_[c.idx()][g] = tag;
      }
    }
  return v;
}

}  // namespace incise
