// Surface checks (topology by hand, self-intersections and distances with CGAL).
#include "mesh/tetrahedralize/surface_check.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <random>
#include <set>
#include <sstream>
#include <unordered_map>

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Polygon_mesh_processing/triangulate_hole.h>
#include <CGAL/Surface_mesh.h>

#include "mesh/errors.h"
#include "mesh/tetrahedralize/tetrahedralize.h"

namespace incise {
namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = K::Point_3;
namespace PMP = CGAL::Polygon_mesh_processing;

struct UnionFind {
  std::vector<int> p;
  explicit UnionFind(std::size_t n) : p(n) { std::iota(p.begin(), p.end(), 0); }
  int find(int x) {
    while (p[x] != x) x = p[x] = p[p[x]];
    return x;
  }
  void unite(int a, int b) { p[find(a)] = find(b); }
};

struct Vec3Hash {
  std::size_t operator()(const Vec3& v) const {
    std::size_t h = 0;
    for (int i = 0; i < 3; ++i) h = h * 1000003u ^ std::hash<double>()(v[i]);
    return h;
  }
};

std::uint64_t edge_key(int a, int b) {
  if (a > b) std::swap(a, b);
  return (std::uint64_t(std::uint32_t(a)) << 32) | std::uint32_t(b);
}

}  // namespace

std::vector<std::string> SurfaceCheck::findings() const {
  std::vector<std::string> f;
  auto add = [&](std::size_t n, const std::string& what) {
    if (n) f.push_back(std::to_string(n) + " " + what);
  };
  if (triangles == 0) f.push_back("no triangles");
  add(welded_vertices, "duplicate vertices (welded)");
  add(degenerate_faces, "degenerate faces (dropped)");
  add(duplicate_faces, "duplicate faces (dropped)");
  if (holes) {
    std::ostringstream os;
    os << holes << " holes (" << border_edges << " border edges), largest radius " << largest_hole_radius;
    f.push_back(os.str());
  }
  add(nonmanifold_edges, "non-manifold edges");
  add(misoriented_edges, "edges between inconsistently oriented faces");
  if (components > 1) f.push_back(std::to_string(components) + " shells");
  add(self_intersections, "pairs of self-intersecting faces");
  if (signed_volume < 0) f.push_back("inverted orientation (negative enclosed volume; flipped)");
  return f;
}

std::string SurfaceCheck::summary() const {
  auto f = findings();
  if (f.empty()) return "clean";
  std::string s;
  for (auto& x : f) s += (s.empty() ? "" : "; ") + x;
  return s;
}

SurfaceCheck check_surface(const SurfaceMesh& in, SurfaceMesh* cleaned_out) {
  SurfaceCheck c;
  c.triangles = in.triangles.size();
  c.diagonal = 0;
  if (!in.vertices.empty()) {
    Eigen::AlignedBox3d box;
    for (const Vec3& p : in.vertices) box.extend(p);
    c.diagonal = box.diagonal().norm();
  }

  // Weld exactly coincident vertices (STL and many exporters repeat them per face).
  SurfaceMesh s;
  std::vector<int> remap(in.vertices.size());
  {
    std::unordered_map<Vec3, int, Vec3Hash> seen;
    seen.reserve(in.vertices.size());
    for (std::size_t i = 0; i < in.vertices.size(); ++i) {
      auto [it, fresh] = seen.try_emplace(in.vertices[i], int(s.vertices.size()));
      if (fresh) s.vertices.push_back(in.vertices[i]);
      remap[i] = it->second;
    }
  }
  // Drop degenerate and duplicate faces.
  {
    std::map<std::array<int, 3>, int> seen;
    const double eps2 = std::pow(1e-12 * c.diagonal, 4);
    for (const auto& t0 : in.triangles) {
      for (int k = 0; k < 3; ++k)
        if (t0[k] < 0 || std::size_t(t0[k]) >= in.vertices.size())
          throw InvalidArgument("check_surface: triangle index out of range");
      std::array<int, 3> t{remap[t0[0]], remap[t0[1]], remap[t0[2]]};
      const Vec3 n = (s.vertices[t[1]] - s.vertices[t[0]]).cross(s.vertices[t[2]] - s.vertices[t[0]]);
      if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2] || n.squaredNorm() <= eps2) {
        ++c.degenerate_faces;
        continue;
      }
      std::array<int, 3> key = t;
      std::sort(key.begin(), key.end());
      if (!seen.emplace(key, 1).second) {
        ++c.duplicate_faces;
        continue;
      }
      s.triangles.push_back(t);
    }
  }
  // Drop vertices no face uses any more.
  {
    std::vector<int> used(s.vertices.size(), -1);
    SurfaceMesh compact;
    for (auto& t : s.triangles)
      for (int& v : t) {
        if (used[v] < 0) {
          used[v] = int(compact.vertices.size());
          compact.vertices.push_back(s.vertices[v]);
        }
        v = used[v];
      }
    compact.triangles = std::move(s.triangles);
    c.welded_vertices = in.vertices.size() - s.vertices.size();
    s = std::move(compact);
  }
  c.vertices = s.vertices.size();

  // Edges: faces per edge and orientation agreement.
  struct EdgeUse {
    int count = 0;
    int dir = 0;  // +1 per face using it as (min,max), -1 as (max,min)
    int a = 0, b = 0;
  };
  std::unordered_map<std::uint64_t, EdgeUse> edges;
  edges.reserve(s.triangles.size() * 2);
  UnionFind shells(s.vertices.size());
  for (const auto& t : s.triangles)
    for (int k = 0; k < 3; ++k) {
      const int a = t[k], b = t[(k + 1) % 3];
      EdgeUse& e = edges[edge_key(a, b)];
      ++e.count;
      e.dir += a < b ? 1 : -1;
      e.a = a;
      e.b = b;
      shells.unite(a, b);
    }
  std::vector<std::pair<int, int>> border;
  for (auto& [key, e] : edges) {
    if (e.count == 1) {
      ++c.border_edges;
      border.emplace_back(e.a, e.b);
    } else if (e.count > 2) {
      ++c.nonmanifold_edges;
    } else if (e.dir != 0) {
      ++c.misoriented_edges;
    }
  }
  {
    std::vector<char> root(s.vertices.size(), 0);
    for (std::size_t v = 0; v < s.vertices.size(); ++v)
      if (!root[shells.find(int(v))]) {
        root[shells.find(int(v))] = 1;
        ++c.components;
      }
  }
  // Holes: connected groups of border edges; radius = farthest loop vertex from the centroid.
  if (!border.empty()) {
    std::unordered_map<int, int> idx;
    for (auto [a, b] : border) {
      idx.try_emplace(a, int(idx.size()));
      idx.try_emplace(b, int(idx.size()));
    }
    UnionFind uf(idx.size());
    for (auto [a, b] : border) uf.unite(idx[a], idx[b]);
    std::unordered_map<int, std::vector<int>> groups;
    for (auto [v, i] : idx) groups[uf.find(i)].push_back(v);
    c.holes = groups.size();
    for (auto& [r, vs] : groups) {
      Vec3 centroid = Vec3::Zero();
      for (int v : vs) centroid += s.vertices[v];
      centroid /= double(vs.size());
      for (int v : vs) c.largest_hole_radius = std::max(c.largest_hole_radius, (s.vertices[v] - centroid).norm());
    }
  }
  c.signed_volume = enclosed_volume(s);

  // Self-intersections need a halfedge mesh; a soup that is not one is already not
  // meshable (non-manifold or inconsistently oriented), so orient it first for the count.
  if (!s.triangles.empty()) {
    std::vector<Point> pts;
    pts.reserve(s.vertices.size());
    for (const Vec3& p : s.vertices) pts.emplace_back(p.x(), p.y(), p.z());
    std::vector<std::vector<std::size_t>> polys;
    polys.reserve(s.triangles.size());
    for (auto& t : s.triangles) polys.push_back({std::size_t(t[0]), std::size_t(t[1]), std::size_t(t[2])});
    if (!PMP::is_polygon_soup_a_polygon_mesh(polys)) PMP::orient_polygon_soup(pts, polys);
    if (PMP::is_polygon_soup_a_polygon_mesh(polys)) {
      CGAL::Surface_mesh<Point> sm;
      PMP::polygon_soup_to_polygon_mesh(pts, polys, sm);
      std::vector<std::pair<CGAL::Surface_mesh<Point>::Face_index, CGAL::Surface_mesh<Point>::Face_index>> pairs;
      PMP::self_intersections(faces(sm), sm, std::back_inserter(pairs));
      c.self_intersections = pairs.size();
      c.self_intersection_checked = true;
    }
  }

  if (cleaned_out) {
    // Flip a wholly inverted, consistently oriented surface; anything else keeps its faces.
    if (c.signed_volume < 0 && c.misoriented_edges == 0 && c.nonmanifold_edges == 0) {
      for (auto& t : s.triangles) std::swap(t[1], t[2]);
    }
    *cleaned_out = std::move(s);
  }
  return c;
}

bool fill_holes(SurfaceMesh& surface, std::size_t* filled) {
  using SM = CGAL::Surface_mesh<Point>;
  std::vector<Point> pts;
  for (const Vec3& p : surface.vertices) pts.emplace_back(p.x(), p.y(), p.z());
  std::vector<std::vector<std::size_t>> polys;
  for (auto& t : surface.triangles) polys.push_back({std::size_t(t[0]), std::size_t(t[1]), std::size_t(t[2])});
  // Non-manifold vertices are split apart (orient_polygon_soup) so the holes can be found.
  if (!PMP::is_polygon_soup_a_polygon_mesh(polys)) PMP::orient_polygon_soup(pts, polys);
  if (!PMP::is_polygon_soup_a_polygon_mesh(polys)) return false;
  SM sm;
  PMP::polygon_soup_to_polygon_mesh(pts, polys, sm);
  std::vector<SM::Halfedge_index> holes;
  std::set<SM::Halfedge_index> seen;
  for (SM::Halfedge_index h : halfedges(sm)) {
    if (!is_border(h, sm) || seen.count(h)) continue;
    holes.push_back(h);
    for (SM::Halfedge_index g : halfedges_around_face(h, sm)) seen.insert(g);
  }
  for (SM::Halfedge_index h : holes) {
    std::vector<SM::Face_index> patch;
    PMP::triangulate_hole(sm, h, std::back_inserter(patch));
    if (patch.empty()) return false;
  }
  for (SM::Halfedge_index h : halfedges(sm))
    if (is_border(h, sm)) return false;
  SurfaceMesh out;
  std::map<SM::Vertex_index, int> id;
  for (SM::Vertex_index v : vertices(sm)) {
    id[v] = int(out.vertices.size());
    const Point& p = sm.point(v);
    out.vertices.emplace_back(p.x(), p.y(), p.z());
  }
  for (SM::Face_index f : faces(sm)) {
    std::array<int, 3> t{};
    int k = 0;
    for (SM::Vertex_index v : vertices_around_face(sm.halfedge(f), sm)) {
      if (k < 3) t[k] = id[v];
      ++k;
    }
    if (k != 3) return false;
    out.triangles.push_back(t);
  }
  surface = std::move(out);
  if (filled) *filled = holes.size();
  return true;
}

SurfaceDistance surface_distance(const SurfaceMesh& a, const SurfaceMesh& b, std::size_t samples) {
  using Tri = K::Triangle_3;
  using Iter = std::vector<Tri>::const_iterator;
  using Primitive = CGAL::AABB_triangle_primitive<K, Iter>;
  using Tree = CGAL::AABB_tree<CGAL::AABB_traits<K, Primitive>>;
  auto tris = [](const SurfaceMesh& s) {
    std::vector<Tri> out;
    out.reserve(s.triangles.size());
    for (auto& t : s.triangles) {
      auto p = [&](int i) { return Point(s.vertices[i].x(), s.vertices[i].y(), s.vertices[i].z()); };
      out.emplace_back(p(t[0]), p(t[1]), p(t[2]));
    }
    return out;
  };
  const std::vector<Tri> ta = tris(a), tb = tris(b);
  SurfaceDistance d;
  if (ta.empty() || tb.empty()) return d;
  std::size_t count = 0;
  double sum = 0;
  auto one_way = [&](const SurfaceMesh& from, const std::vector<Tri>& from_tris, const std::vector<Tri>& to) {
    Tree tree(to.begin(), to.end());
    tree.accelerate_distance_queries();
    auto measure = [&](const Point& p) {
      const double dist = std::sqrt(tree.squared_distance(p));
      d.max = std::max(d.max, dist);
      sum += dist;
      ++count;
    };
    for (const Vec3& v : from.vertices) measure(Point(v.x(), v.y(), v.z()));
    // Area-weighted random points, fixed seed: the measure is repeatable.
    std::vector<double> cum(from_tris.size());
    double total = 0;
    for (std::size_t i = 0; i < from_tris.size(); ++i) cum[i] = total += std::sqrt(from_tris[i].squared_area());
    std::mt19937_64 rng(12345);
    std::uniform_real_distribution<double> u(0, 1);
    for (std::size_t k = 0; k < samples && total > 0; ++k) {
      const std::size_t i = std::min<std::size_t>(std::lower_bound(cum.begin(), cum.end(), u(rng) * total) - cum.begin(),
                                                  cum.size() - 1);
      double r1 = u(rng), r2 = u(rng);
      if (r1 + r2 > 1) r1 = 1 - r1, r2 = 1 - r2;
      const Tri& t = from_tris[i];
      measure(t[0] + r1 * (t[1] - t[0]) + r2 * (t[2] - t[0]));
    }
  };
  one_way(a, ta, tb);
  one_way(b, tb, ta);
  d.mean = count ? sum / double(count) : 0;
  return d;
}

}  // namespace incise
