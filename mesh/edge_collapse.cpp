// Edge contraction: link condition, geometric checks, and the edit through TetMesh's API.
#include "mesh/edge_collapse.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <span>

#include "mesh/errors.h"

namespace incise {

namespace {

// The virtual vertex every boundary face is coned to, so that the link condition also keeps
// the boundary a manifold (two boundary vertices joined by an interior edge fail it).
constexpr std::uint32_t kOmega = 0xfffffffeu;

std::uint64_t edge_key(std::uint32_t x, std::uint32_t y) {
  if (x > y) std::swap(x, y);
  return (std::uint64_t(x) << 32) | y;
}
std::array<std::uint32_t, 3> tri_key(std::uint32_t x, std::uint32_t y, std::uint32_t z) {
  std::array<std::uint32_t, 3> k{x, y, z};
  std::sort(k.begin(), k.end());
  return k;
}

template <class T>
void sort_unique(std::vector<T>& v) {
  std::sort(v.begin(), v.end());
  v.erase(std::unique(v.begin(), v.end()), v.end());
}

template <class T>
std::size_t common(const std::vector<T>& a, const std::vector<T>& b) {
  std::size_t n = 0;
  for (auto i = a.begin(), j = b.begin(); i != a.end() && j != b.end();) {
    if (*i < *j) ++i;
    else if (*j < *i) ++j;
    else ++n, ++i, ++j;
  }
  return n;
}

// The link of a vertex in the mesh coned at the boundary: its vertices, edges and triangles.
struct Link {
  std::vector<std::uint32_t> verts;
  std::vector<std::uint64_t> edges;
  std::vector<std::array<std::uint32_t, 3>> tris;
  void finish() {
    sort_unique(verts);
    sort_unique(edges);
    sort_unique(tris);
  }
};

Link vertex_link(const TetMesh& m, VertexId v) {
  Link l;
  for (TetId t : m.incident_tets(v)) {
    const auto& tv = m.tet_vertices(t);
    const int iv = m.local_index(t, v);
    std::uint32_t o[3];
    int k = 0;
    for (int i = 0; i < 4; ++i)
      if (i != iv) o[k++] = tv[i].idx();
    l.verts.insert(l.verts.end(), o, o + 3);
    l.edges.push_back(edge_key(o[0], o[1]));
    l.edges.push_back(edge_key(o[1], o[2]));
    l.edges.push_back(edge_key(o[0], o[2]));
    l.tris.push_back(tri_key(o[0], o[1], o[2]));
    for (int f = 0; f < 4; ++f) {
      if (f == iv || m.neighbor(t, f).is_valid()) continue;
      std::uint32_t xy[2];
      int n = 0;
      for (VertexId w : m.face_vertices(t, f))
        if (w != v) xy[n++] = w.idx();
      l.verts.push_back(kOmega);
      l.edges.push_back(edge_key(xy[0], kOmega));
      l.edges.push_back(edge_key(xy[1], kOmega));
      l.tris.push_back(tri_key(xy[0], xy[1], kOmega));
    }
  }
  l.finish();
  return l;
}

double orient6(const Vec3& p0, const Vec3& p1, const Vec3& p2, const Vec3& p3) {
  return (p1 - p0).dot((p2 - p0).cross(p3 - p0));
}

double longest_edge(const std::array<Vec3, 4>& p) {
  double l = 0;
  for (int i = 0; i < 4; ++i)
    for (int j = i + 1; j < 4; ++j) l = std::max(l, (p[i] - p[j]).norm());
  return l;
}

// The boundary faces around `remove` form one cycle (a disc). It may go when that disc is flat
// with one tag and `keep` is on its rim, or when it is two such flat parts meeting along a
// straight crease through `remove` (two boundary edges in line: where a cut meets the surface,
// or a box's edge) and `keep` is on that crease. Every face retiled from `keep` must keep its
// orientation in its plane, so the new faces cover the same polygons.
// Faces around `remove` retiled from `keep` must not turn over: the new normal within 60 degrees
// of the old one (what the tolerance mode asks of boundary and interface faces instead of
// flatness). Faces holding `keep` vanish.
bool keeps_facing(const TetMesh& m, VertexId keep, VertexId x, VertexId y, const Vec3& n_old) {
  if (x == keep || y == keep) return true;
  const Vec3 pk = m.rest(keep);
  const Vec3 n = (m.rest(x) - pk).cross(m.rest(y) - pk);
  return n.dot(n_old) > 0.5 * n.norm() * n_old.norm();
}

bool boundary_disc_ok(const TetMesh& m, VertexId keep, VertexId remove, std::span<const TetId> star, bool tolerant) {
  struct Face {
    VertexId x, y;  // the face is (remove, x, y), outward
    std::uint16_t tag;
    Vec3 n;  // (x - remove) x (y - remove)
  };
  const Vec3 pr = m.rest(remove), pk = m.rest(keep);
  std::vector<Face> disc;
  for (TetId t : star) {
    const int ir = m.local_index(t, remove);
    for (int f = 0; f < 4; ++f) {
      if (f == ir || m.neighbor(t, f).is_valid()) continue;
      auto fv = m.face_vertices(t, f);
      while (fv[0] != remove) std::rotate(fv.begin(), fv.begin() + 1, fv.end());
      disc.push_back({fv[1], fv[2], m.face_tag(t, f), (m.rest(fv[1]) - pr).cross(m.rest(fv[2]) - pr)});
    }
  }
  if (disc.empty()) return true;  // an interior vertex
  // Order the faces as one cycle x -> y around `remove` (two fans would be a pinch).
  std::vector<Face> cyc{disc[0]};
  while (cyc.size() < disc.size()) {
    auto it = std::find_if(disc.begin(), disc.end(), [&](const Face& f) { return f.x == cyc.back().y; });
    if (it == disc.end() || it->x == disc[0].x) return false;
    cyc.push_back(*it);
  }
  if (cyc.back().y != cyc.front().x) return false;
  const std::size_t n = cyc.size();
  if (tolerant) {  // a tiny edge: any shape of boundary, as long as no face turns over
    for (const Face& f : cyc)
      if (!keeps_facing(m, keep, f.x, f.y, f.n)) return false;
    return true;
  }
  // A crease at rim vertex cyc[i].x: the faces on either side of edge (remove, cyc[i].x) differ
  // in tag or are not coplanar (the test smoothing uses).
  std::vector<std::size_t> creases;
  for (std::size_t i = 0; i < n; ++i) {
    const Face& a = cyc[(i + n - 1) % n];
    const Face& b = cyc[i];
    const bool coplanar = a.n.dot(b.n) > 0 && a.n.cross(b.n).norm() <= 1e-10 * a.n.norm() * b.n.norm();
    if (a.tag != b.tag || !coplanar) creases.push_back(i);
  }
  // Parts of the disc, as ranges [begin, begin + count) of cyc.
  std::vector<std::pair<std::size_t, std::size_t>> parts;
  if (creases.empty()) {
    bool on_rim = false;
    for (const Face& f : cyc) on_rim = on_rim || f.x == keep;
    if (!on_rim) return false;
    parts.push_back({0, n});
  } else if (creases.size() == 2) {
    const VertexId p = cyc[creases[0]].x, q = cyc[creases[1]].x;
    if (keep != p && keep != q) return false;  // `remove` would leave the crease
    const Vec3 ep = m.rest(p) - pr, eq = m.rest(q) - pr;
    if (!(ep.dot(eq) < 0) || ep.cross(eq).norm() > 1e-10 * ep.norm() * eq.norm()) return false;  // bent: a corner
    parts.push_back({creases[0], creases[1] - creases[0]});
    parts.push_back({creases[1], n - (creases[1] - creases[0])});
  } else {
    return false;  // a corner, or a tag border meeting a crease
  }
  for (const auto& [begin, count] : parts) {
    // Flat: every vertex of the part within 1e-10 of its size from its plane through `remove`.
    Vec3 nrm = Vec3::Zero();
    double h = 0;
    for (std::size_t k = 0; k < count; ++k) {
      const Face& f = cyc[(begin + k) % n];
      nrm += f.n;
      h = std::max({h, (m.rest(f.x) - pr).norm(), (m.rest(f.y) - pr).norm()});
    }
    if (!(nrm.norm() > 0) || !(h > 0)) return false;
    nrm.normalize();
    for (std::size_t k = 0; k < count; ++k) {
      const Face& f = cyc[(begin + k) % n];
      if (std::abs(nrm.dot(m.rest(f.x) - pr)) > 1e-10 * h || std::abs(nrm.dot(m.rest(f.y) - pr)) > 1e-10 * h)
        return false;
      if (f.x == keep || f.y == keep) continue;
      // Retiled from `keep`: clearly the same orientation in the plane.
      const Vec3 e1 = m.rest(f.x) - pk, e2 = m.rest(f.y) - pk;
      if (!(nrm.dot(e1.cross(e2)) > 1e-12 * e1.norm() * e2.norm())) return false;
    }
  }
  return true;
}

}  // namespace

const char* to_string(CollapseRefusal r) {
  switch (r) {
    case CollapseRefusal::None: return "ok";
    case CollapseRefusal::NotAnEdge: return "not an edge";
    case CollapseRefusal::Link: return "link condition fails";
    case CollapseRefusal::Orientation: return "a tet would invert";
    case CollapseRefusal::Volume: return "the star would not be retiled";
    case CollapseRefusal::Boundary: return "the removed vertex is not on a flat disc of the boundary with the kept one";
    case CollapseRefusal::Labels: return "the removed vertex lies on a label interface";
  }
  return "?";
}

CollapseCheck check_collapse(const TetMesh& m, VertexId keep, VertexId remove, double tolerance) {
  CollapseCheck out;
  out.plan.keep = keep;
  out.plan.remove = remove;
  auto refuse = [&](CollapseRefusal r) {
    out.refusal = r;
    return out;
  };
  if (!m.is_alive(keep) || !m.is_alive(remove) || keep == remove) return refuse(CollapseRefusal::NotAnEdge);
  const auto star = m.incident_tets(remove);
  for (TetId t : star) (m.local_index(t, keep) >= 0 ? out.plan.removed : out.plan.rebuilt).push_back(t);
  if (out.plan.removed.empty()) return refuse(CollapseRefusal::NotAnEdge);
  const double edge_len = (m.rest(keep) - m.rest(remove)).norm();
  double reach = 0;  // longest edge at `remove`
  for (TetId t : star)
    for (VertexId w : m.tet_vertices(t)) reach = std::max(reach, (m.rest(w) - m.rest(remove)).norm());
  const bool tolerant = edge_len <= tolerance * reach;
  bool one_label = true;
  for (TetId t : star) one_label = one_label && m.label(t) == m.label(star[0]);
  if (!one_label) {
    if (!tolerant) return refuse(CollapseRefusal::Labels);
    // Interface faces (remove, x, y) between two labels keep facing the same way.
    for (TetId t : star) {
      const int ir = m.local_index(t, remove);
      for (int f = 0; f < 4; ++f) {
        const TetId u = m.neighbor(t, f);
        if (f == ir || !u.is_valid() || m.label(u) == m.label(t)) continue;
        auto fv = m.face_vertices(t, f);
        while (fv[0] != remove) std::rotate(fv.begin(), fv.begin() + 1, fv.end());
        const Vec3 pr = m.rest(remove);
        if (!keeps_facing(m, keep, fv[1], fv[2], (m.rest(fv[1]) - pr).cross(m.rest(fv[2]) - pr)))
          return refuse(CollapseRefusal::Labels);
      }
    }
  }

  // Link condition: Lk(keep) ∩ Lk(remove) == Lk(edge) in vertices and edges, and no common
  // triangle (the edge's link has none). Lk(edge) is always inside the intersection, so
  // comparing sizes suffices.
  Link edge;
  for (TetId t : out.plan.removed) {
    const auto& tv = m.tet_vertices(t);
    std::uint32_t o[2];
    int k = 0;
    for (VertexId w : tv)
      if (w != keep && w != remove) o[k++] = w.idx();
    edge.verts.insert(edge.verts.end(), o, o + 2);
    edge.edges.push_back(edge_key(o[0], o[1]));
    for (int f = 0; f < 4; ++f) {
      const VertexId opp = tv[f];
      if (opp == keep || opp == remove || m.neighbor(t, f).is_valid()) continue;
      // Boundary face (keep, remove, y): y - omega is in the edge's link.
      const std::uint32_t y = (o[0] == opp.idx()) ? o[1] : o[0];
      edge.verts.push_back(kOmega);
      edge.edges.push_back(edge_key(y, kOmega));
    }
  }
  edge.finish();
  const Link lk = vertex_link(m, keep), lr = vertex_link(m, remove);
  if (common(lk.verts, lr.verts) != edge.verts.size() || common(lk.edges, lr.edges) != edge.edges.size() ||
      common(lk.tris, lr.tris) != 0)
    return refuse(CollapseRefusal::Link);
  if (!boundary_disc_ok(m, keep, remove, star, tolerant)) return refuse(CollapseRefusal::Boundary);
  // A cut's two sides lie on each other: a cut face that moved outwards, even by a hair, would
  // push into the tissue across the cut (the mesh stays valid tet by tet, but the body
  // overlaps itself and no reader takes it back). In tolerance mode `keep` may therefore not
  // lie outside the plane of any cut face at `remove`; the face may move inwards (the cut opens
  // by that hair) or within its plane.
  if (tolerant)
    for (TetId t : star) {
      const int ir = m.local_index(t, remove);
      for (int f = 0; f < 4; ++f) {
        if (f == ir || m.neighbor(t, f).is_valid() || m.face_tag(t, f) != kTagCut) continue;
        const auto& tv = m.tet_vertices(t);
        const auto fv = m.face_vertices(t, f);
        const Vec3 &a = m.rest(fv[0]), &b = m.rest(fv[1]), &c = m.rest(fv[2]);
        const Vec3 n = (b - a).cross(c - a);
        const double inside = n.dot(m.rest(tv[f]) - a), at_keep = n.dot(m.rest(keep) - a);
        const double l = std::max({(b - a).norm(), (c - a).norm(), (c - b).norm()});
        if (at_keep * (inside > 0 ? 1 : -1) < -1e-12 * l * l * l) return refuse(CollapseRefusal::Boundary);
      }
    }
  // Nothing would be left where `remove`'s star was: its volume would be lost.
  if (out.plan.rebuilt.empty()) return refuse(CollapseRefusal::Volume);

  // Geometry: every rebuilt tet clearly positive, and together they cover the star's volume.
  double before = 0, after = 0;
  std::vector<std::pair<int, double>> by_label;  // label volume after - before (a few labels)
  auto add_label = [&](int label, double dv) {
    for (auto& [l, v] : by_label)
      if (l == label) return void(v += dv);
    by_label.push_back({label, dv});
  };
  for (TetId t : star) {
    before += m.volume(t);
    add_label(m.label(t), -m.volume(t));
  }
  for (TetId t : out.plan.rebuilt) {
    std::array<VertexId, 4> v = m.tet_vertices(t);
    std::array<Vec3, 4> p;
    for (int i = 0; i < 4; ++i) {
      if (v[i] == remove) v[i] = keep;
      p[i] = m.rest(v[i]);
    }
    const double l = longest_edge(p);
    const double o = orient6(p[0], p[1], p[2], p[3]);
    if (!(o > 1e-12 * l * l * l)) return refuse(CollapseRefusal::Orientation);
    after += o / 6;
    add_label(m.label(t), o / 6);
    out.plan.tets.push_back(v);
  }
  // Exact retiling, or (tolerance mode) no more than the boundary faces sweep when their
  // corner moves by the edge's length.
  double sweep = 0;
  if (tolerant)
    for (TetId t : star) {
      const int ir = m.local_index(t, remove);
      for (int f = 0; f < 4; ++f) {
        const TetId u = m.neighbor(t, f);
        if (f == ir || (u.is_valid() && m.label(u) == m.label(t))) continue;
        const auto fv = m.face_vertices(t, f);
        sweep += 0.5 * (m.rest(fv[1]) - m.rest(fv[0])).cross(m.rest(fv[2]) - m.rest(fv[0])).norm() * edge_len;
      }
    }
  if (!(std::abs(after - before) <= 1e-8 * std::abs(before) + sweep)) return refuse(CollapseRefusal::Volume);
  if (tolerant)  // an exact retiling moves only rounding
    for (const auto& [l, dv] : by_label) out.plan.volume_change += std::abs(dv);
  out.refusal = CollapseRefusal::None;
  return out;
}

void collapse_edge(TetMesh& m, const CollapsePlan& plan) {
  const VertexId keep = plan.keep, remove = plan.remove;
  if (!m.is_alive(keep) || !m.is_alive(remove) || plan.rebuilt.size() != plan.tets.size() ||
      plan.removed.size() + plan.rebuilt.size() != m.incident_tets(remove).size())
    throw InvalidArgument("collapse_edge: the plan does not match the mesh (check_collapse, then act)");
  // Boundary faces of the star keep their tags: after the collapse a boundary face with the
  // same vertices (`remove` read as `keep`) gets the tag back, whichever tet now owns it. Faces
  // holding both vertices collapse to edges and are dropped.
  struct Tagged {
    std::array<std::uint32_t, 3> key;
    std::uint16_t tag;
  };
  std::vector<Tagged> tags;
  std::vector<TetId> fix(plan.rebuilt.begin(), plan.rebuilt.end());
  auto in_star = [&](TetId u) {
    return std::find(plan.removed.begin(), plan.removed.end(), u) != plan.removed.end() ||
           std::find(plan.rebuilt.begin(), plan.rebuilt.end(), u) != plan.rebuilt.end();
  };
  for (const auto* list : {&plan.removed, &plan.rebuilt})
    for (TetId t : *list)
      for (int f = 0; f < 4; ++f) {
        const TetId u = m.neighbor(t, f);
        if (u.is_valid()) {
          // A tet outside the star across a face of a removed tet may become boundary there.
          if (!in_star(u)) fix.push_back(u);
          continue;
        }
        auto fv = m.face_vertices(t, f);
        bool has_keep = false, has_remove = false;
        for (VertexId& w : fv) {
          has_keep = has_keep || w == keep;
          if (w == remove) has_remove = true, w = keep;
        }
        if (has_keep && has_remove) continue;
        tags.push_back({tri_key(fv[0].idx(), fv[1].idx(), fv[2].idx()), m.face_tag(t, f)});
      }
  for (TetId t : plan.removed) m.remove_tet(t);
  for (TetId t : plan.rebuilt) m.replace_vertex(t, remove, keep);
  m.remove_vertex(remove);
  for (TetId t : fix) {
    if (!m.is_alive(t)) continue;
    for (int f = 0; f < 4; ++f) {
      if (m.neighbor(t, f).is_valid()) continue;
      const auto fv = m.face_vertices(t, f);
      const auto key = tri_key(fv[0].idx(), fv[1].idx(), fv[2].idx());
      for (const Tagged& g : tags)
        if (g.key == key) m.set_face_tag(t, f, g.tag);
    }
  }
}

bool collapse_edge(TetMesh& m, VertexId keep, VertexId remove, double tolerance) {
  const CollapseCheck c = check_collapse(m, keep, remove, tolerance);
  if (!c.ok()) return false;
  collapse_edge(m, c.plan);
  return true;
}

}  // namespace incise
