#include "mesh/overlap.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace incise {
namespace {

struct Box {
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity());
  Vec3 hi = Vec3::Constant(-std::numeric_limits<double>::infinity());
  void add(const Vec3& p) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  void add(const Box& b) {
    lo = lo.cwiseMin(b.lo);
    hi = hi.cwiseMax(b.hi);
  }
  bool meets(const Box& b) const { return (lo.array() <= b.hi.array()).all() && (b.lo.array() <= hi.array()).all(); }
};

using Corners = std::array<Vec3, 4>;

constexpr int kFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
constexpr int kEdge[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};

// A tet with what every test of it needs: its unit face normals (zero for a degenerate face)
// and its own extent along each, and its longest edge.
struct Solid {
  Corners c;
  std::array<Vec3, 4> normal;
  std::array<double, 4> lo, hi;
  double longest = 0;
  std::array<std::uint32_t, 4> v;

  Solid(const TetMesh& mesh, TetId t) {
    const auto& tv = mesh.tet_vertices(t);
    for (int k = 0; k < 4; ++k) {
      c[k] = mesh.rest(tv[k]);
      v[k] = tv[k].idx();
    }
    for (int f = 0; f < 4; ++f) {
      Vec3 n = (c[kFace[f][1]] - c[kFace[f][0]]).cross(c[kFace[f][2]] - c[kFace[f][0]]);
      const double len = n.norm();
      normal[f] = len > 0 ? Vec3(n / len) : Vec3::Zero();
      lo[f] = hi[f] = c[0].dot(normal[f]);
      for (int k = 1; k < 4; ++k) {
        const double p = c[k].dot(normal[f]);
        lo[f] = std::min(lo[f], p);
        hi[f] = std::max(hi[f], p);
      }
    }
    for (const auto& e : kEdge) longest = std::max(longest, (c[e[1]] - c[e[0]]).squaredNorm());
    longest = std::sqrt(longest);
  }
  int shared_vertices(const Solid& o) const {
    int n = 0;
    for (std::uint32_t a : v)
      for (std::uint32_t b : o.v) n += a == b;
    return n;
  }
};

// A node covers items_[begin, end); an inner node's children are left and left + 1.
struct Node {
  Box box;
  std::uint32_t begin = 0, end = 0, left = 0;
};

// A bounding-box tree whose items are numbered in its own order: a node covers the items
// begin..end-1, so a query for the pairs (p, k > p) skips whole subtrees, and queries made in
// that order touch the tree in a cache-friendly sweep.
class BoxTree {
public:
  explicit BoxTree(std::vector<Box> boxes) : order_(boxes.size()) {
    for (std::uint32_t i = 0; i < order_.size(); ++i) order_[i] = i;
    centres_.reserve(boxes.size());
    for (const Box& b : boxes) centres_.push_back(0.5 * (b.lo + b.hi));
    boxes_ = std::move(boxes);
    nodes_.reserve(2 * boxes_.size() / kLeaf + 2);
    nodes_.push_back({});
    build(0, 0, std::uint32_t(order_.size()));
    std::vector<Box> sorted(boxes_.size());
    for (std::size_t k = 0; k < order_.size(); ++k) sorted[k] = boxes_[order_[k]];
    boxes_ = std::move(sorted);
    centres_ = {};
  }

  // order()[k]: the input index of the item at position k.
  const std::vector<std::uint32_t>& order() const { return order_; }
  const Box& box(std::uint32_t k) const { return boxes_[k]; }

  // Calls visit(k) for every position k > p whose box meets that of p; stops when visit
  // returns true (and returns true).
  template <class F>
  bool any_after(std::uint32_t p, F&& visit) const {
    const Box& q = boxes_[p];
    std::uint32_t stack[128];  // depth <= log2(items) + 1: the split is at the median
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
      const Node& n = nodes_[stack[--top]];
      if (n.end <= p + 1 || !n.box.meets(q)) continue;
      if (n.left == 0) {
        for (std::uint32_t k = std::max(n.begin, p + 1); k < n.end; ++k)
          if (boxes_[k].meets(q) && visit(k)) return true;
      } else {
        stack[top++] = n.left;
        stack[top++] = n.left + 1;
      }
    }
    return false;
  }

private:
  static constexpr std::uint32_t kLeaf = 4;

  void build(std::uint32_t node, std::uint32_t begin, std::uint32_t end) {
    Box box, centres;
    for (std::uint32_t k = begin; k < end; ++k) {
      box.add(boxes_[order_[k]]);
      centres.add(centres_[order_[k]]);
    }
    nodes_[node].box = box;
    nodes_[node].begin = begin;
    nodes_[node].end = end;
    if (end - begin <= kLeaf) return;
    int axis = 0;
    (centres.hi - centres.lo).maxCoeff(&axis);
    const std::uint32_t mid = begin + (end - begin) / 2;
    std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end,
                     [&](std::uint32_t a, std::uint32_t b) { return centres_[a][axis] < centres_[b][axis]; });
    const auto left = std::uint32_t(nodes_.size());
    nodes_[node].left = left;
    nodes_.push_back({});
    nodes_.push_back({});
    build(left, begin, mid);
    build(left + 1, mid, end);
  }

  std::vector<Box> boxes_;  // by position once built
  std::vector<std::uint32_t> order_;
  std::vector<Vec3> centres_;
  std::vector<Node> nodes_;
};

void extent(const Vec3& axis, const Corners& c, double& lo, double& hi) {
  lo = hi = c[0].dot(axis);
  for (int k = 1; k < 4; ++k) {
    const double p = c[k].dot(axis);
    lo = std::min(lo, p);
    hi = std::max(hi, p);
  }
}

// Separating-axis test: convex polyhedra have disjoint interiors exactly when one of their
// face normals or one of the cross products of an edge of each separates them. Tets sharing
// an edge are separated by a face plane through it when they do not overlap, so the edge
// directions are only tried for tets sharing a vertex or nothing.
bool interiors_overlap(const Solid& a, const Solid& b, int shared, double depth) {
  for (int f = 0; f < 4; ++f) {
    if (a.normal[f].isZero()) continue;  // degenerate face: another axis decides
    double lo, hi;
    extent(a.normal[f], b.c, lo, hi);
    if (std::min(a.hi[f], hi) - std::max(a.lo[f], lo) <= depth) return false;
  }
  for (int f = 0; f < 4; ++f) {
    if (b.normal[f].isZero()) continue;
    double lo, hi;
    extent(b.normal[f], a.c, lo, hi);
    if (std::min(b.hi[f], hi) - std::max(b.lo[f], lo) <= depth) return false;
  }
  if (shared >= 2) return true;
  // Tets sharing vertex v overlap exactly where their cones at v do: only planes through v
  // spanned by an edge at v of each can separate those beyond the faces.
  int va = -1, vb = -1;
  if (shared == 1)
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j)
        if (a.v[i] == b.v[j]) va = i, vb = j;
  for (const auto& ea : kEdge)
    for (const auto& eb : kEdge) {
      if (va >= 0 && ((ea[0] != va && ea[1] != va) || (eb[0] != vb && eb[1] != vb))) continue;
      const Vec3 da = a.c[ea[1]] - a.c[ea[0]], db = b.c[eb[1]] - b.c[eb[0]];
      const Vec3 n = da.cross(db);
      const double n2 = n.squaredNorm();
      if (!(n2 > 1e-24 * da.squaredNorm() * db.squaredNorm())) continue;  // parallel edges
      const Vec3 axis = n / std::sqrt(n2);
      double alo, ahi, blo, bhi;
      extent(axis, a.c, alo, ahi);
      extent(axis, b.c, blo, bhi);
      if (std::min(ahi, bhi) - std::max(alo, blo) <= depth) return false;
    }
  return true;
}

}  // namespace

std::optional<std::pair<TetId, TetId>> find_overlapping_tets(const TetMesh& mesh, const OverlapOptions& options) {
  const std::vector<TetId> tets = mesh.tets();
  if (tets.size() < 2) return std::nullopt;
  std::vector<Box> boxes(tets.size());
  for (std::size_t i = 0; i < tets.size(); ++i)
    for (VertexId v : mesh.tet_vertices(tets[i])) boxes[i].add(mesh.rest(v));
  const BoxTree tree(std::move(boxes));
  std::vector<Solid> solids;  // by tree position
  solids.reserve(tets.size());
  for (std::uint32_t i : tree.order()) solids.emplace_back(mesh, tets[i]);
  // Positions are searched in parallel blocks; the hit at the lowest position wins, so the
  // answer does not depend on the threads, and blocks past a hit are skipped.
  const auto n = std::uint32_t(solids.size());
  std::atomic<std::uint32_t> first(n);
  std::vector<std::uint32_t> partner(n, 0);
  tbb::parallel_for(tbb::blocked_range<std::uint32_t>(0, n, 256), [&](const tbb::blocked_range<std::uint32_t>& r) {
    for (std::uint32_t p = r.begin(); p != r.end() && p < first.load(std::memory_order_relaxed); ++p) {
      const Solid& a = solids[p];
      const bool found = tree.any_after(p, [&](std::uint32_t k) {
        const Solid& b = solids[k];
        const int shared = a.shared_vertices(b);
        if (shared >= 3) return false;  // face neighbours: the reader checks their sides
        const double depth = options.relative_tolerance * std::max(a.longest, b.longest);
        if (!interiors_overlap(a, b, shared, depth)) return false;
        partner[p] = k;
        return true;
      });
      if (!found) continue;
      std::uint32_t seen = first.load();
      while (p < seen && !first.compare_exchange_weak(seen, p)) {
      }
      return;
    }
  });
  const std::uint32_t p = first.load();
  if (p < n) {
    const TetId x = tets[tree.order()[p]], y = tets[tree.order()[partner[p]]];
    return x.idx() < y.idx() ? std::make_pair(x, y) : std::make_pair(y, x);
  }
  return std::nullopt;
}

}  // namespace incise
