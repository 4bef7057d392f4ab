#include "quality/components.h"

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <utility>

namespace incise {

namespace {

class UnionFind {
public:
  explicit UnionFind(std::size_t n) : parent_(n) { std::iota(parent_.begin(), parent_.end(), 0u); }
  std::uint32_t find(std::uint32_t x) {
    while (parent_[x] != x) x = parent_[x] = parent_[parent_[x]];  // path halving
    return x;
  }
  void unite(std::uint32_t a, std::uint32_t b) {
    a = find(a);
    b = find(b);
    if (a != b) parent_[std::max(a, b)] = std::min(a, b);  // root = lowest index
  }

private:
  std::vector<std::uint32_t> parent_;
};

}  // namespace

TetComponents tet_components(const TetMesh& mesh) {
  const std::size_t n = mesh.tet_capacity();
  UnionFind uf(n);
  for (std::uint32_t i = 0; i < n; ++i) {
    TetId t(i);
    if (!mesh.is_alive(t)) continue;
    for (int f = 0; f < 4; ++f) {
      TetId u = mesh.neighbor(t, f);
      if (u.is_valid() && u.idx() < i) uf.unite(i, u.idx());
    }
  }
  TetComponents c;
  c.of_tet.assign(n, -1);
  for (std::uint32_t i = 0; i < n; ++i) {
    if (!mesh.is_alive(TetId(i))) continue;
    std::uint32_t r = uf.find(i);
    if (r == i) {  // roots are the lowest id of their component, so seen first
      c.of_tet[i] = static_cast<int>(c.count++);
      c.sizes.push_back(0);
    } else {
      c.of_tet[i] = c.of_tet[r];
    }
    ++c.sizes[c.of_tet[i]];
  }
  return c;
}

BoundaryTopology boundary_topology(const TetMesh& mesh) {
  const std::vector<BoundaryFace> faces = mesh.boundary_faces();
  BoundaryTopology bt;
  bt.faces = faces.size();
  if (faces.empty()) return bt;

  struct EdgeUse {
    std::uint32_t a, b;          // a < b
    std::uint32_t face;
    std::uint32_t ca, cb;        // corner (3 face + k) of a and of b in that face
    bool forward;                // the face traverses a -> b
  };
  std::vector<EdgeUse> uses;
  uses.reserve(3 * faces.size());
  for (std::uint32_t f = 0; f < faces.size(); ++f) {
    for (std::uint32_t k = 0; k < 3; ++k) {
      std::uint32_t k2 = (k + 1) % 3;
      std::uint32_t u = faces[f].vertices[k].idx(), w = faces[f].vertices[k2].idx();
      if (u < w)
        uses.push_back({u, w, f, 3 * f + k, 3 * f + k2, true});
      else
        uses.push_back({w, u, f, 3 * f + k2, 3 * f + k, false});
    }
  }
  std::sort(uses.begin(), uses.end(), [](const EdgeUse& x, const EdgeUse& y) {
    return x.a != y.a ? x.a < y.a : x.b < y.b;
  });

  UnionFind face_uf(faces.size()), corner_uf(3 * faces.size());
  for (std::size_t i = 0; i < uses.size();) {
    std::size_t j = i + 1;
    while (j < uses.size() && uses[j].a == uses[i].a && uses[j].b == uses[i].b) ++j;
    const std::size_t n = j - i;
    ++bt.edges;
    for (std::size_t k = i + 1; k < j; ++k) face_uf.unite(uses[i].face, uses[k].face);
    if (n == 1) {
      ++bt.open_edges;
    } else if (n == 2) {
      if (uses[i].forward == uses[i + 1].forward) ++bt.misoriented_edges;
      // The two fans at each end continue across a two-face edge.
      corner_uf.unite(uses[i].ca, uses[i + 1].ca);
      corner_uf.unite(uses[i].cb, uses[i + 1].cb);
    } else {
      ++bt.non_manifold_edges;
    }
    i = j;
  }
  for (std::uint32_t f = 0; f < faces.size(); ++f)
    if (face_uf.find(f) == f) ++bt.shells;

  // Fans per vertex: distinct corner roots among its corners.
  std::vector<std::pair<std::uint32_t, std::uint32_t>> fans;
  fans.reserve(3 * faces.size());
  for (std::uint32_t f = 0; f < faces.size(); ++f)
    for (std::uint32_t k = 0; k < 3; ++k) fans.emplace_back(faces[f].vertices[k].idx(), corner_uf.find(3 * f + k));
  std::sort(fans.begin(), fans.end());
  fans.erase(std::unique(fans.begin(), fans.end()), fans.end());
  for (std::size_t i = 1; i < fans.size(); ++i)
    if (fans[i].first == fans[i - 1].first && (i < 2 || fans[i - 2].first != fans[i].first)) ++bt.non_manifold_vertices;
  return bt;
}

}  // namespace incise
