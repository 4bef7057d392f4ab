#include "mesh/isosurface_stuffing_graded.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <unordered_map>
#include <unordered_set>

#include "mesh/errors.h"

// Octree cells are (level l, q): q is the cell's lowest finest cube, a multiple of 2^l; the
// cell spans 2^l finest cubes per axis. Nodes (leaves and internal) live in one hash map;
// every internal node has all 8 children, so the leaf covering a region is found by walking
// up from the region's own level.

namespace incise::stuffing_detail {
namespace {

constexpr int kMaxLevel = 15;                 // 4 bits in the node key
constexpr int kMaxExtent = (1 << 20) - 1;     // doubled coordinates must fit 21 bits
constexpr std::size_t kMaxNodesPerLevel = std::size_t(1) << 24;

using Q = std::array<int, 3>;

std::uint64_t node_key(int level, const Q& q) {
  return std::uint64_t(level) | (std::uint64_t(q[0]) << 4) | (std::uint64_t(q[1]) << 24) | (std::uint64_t(q[2]) << 44);
}
std::uint64_t point_key(const Key3& k) {
  return std::uint64_t(std::uint32_t(k[0])) | (std::uint64_t(std::uint32_t(k[1])) << 21) |
         (std::uint64_t(std::uint32_t(k[2])) << 42);
}
Q align(const Q& q, int level) { return {q[0] >> level << level, q[1] >> level << level, q[2] >> level << level}; }
int sgn(double v) { return v < 0 ? -1 : (v > 0 ? 1 : 0); }

[[noreturn]] void internal(const char* what) {
  throw Error(std::string("isosurface_stuffing: internal error in the graded lattice: ") + what);
}

class Builder {
public:
  Builder(const GradedLatticeInput& in, const std::function<void(const std::array<Key3, 4>&, bool)>& emit)
      : in_(in), emit_(emit) {}

  void run() {
    choose_domain();
    std::vector<Q> candidates = candidate_blocks();
    mark_required(candidates);
    build_tree();
    balance();
    emit_tets();
  }

private:
  // The coarsest level and the domain, rounded up to whole root cells.
  void choose_domain() {
    const int n = std::max({in_.cells[0], in_.cells[1], in_.cells[2]});
    top_ = 0;
    while (top_ < kMaxLevel && (1 << top_) < n) ++top_;
    for (;; --top_) {
      bool fits = true;
      for (int d = 0; d < 3; ++d) {
        const int s = 1 << top_;
        n_[d] = (in_.cells[d] + s - 1) / s * s;
        fits &= n_[d] <= kMaxExtent;
      }
      if (fits) break;
      if (top_ == 0) internal("domain too large");
    }
  }

  bool inside_domain(const Q& q) const {
    return q[0] >= 0 && q[1] >= 0 && q[2] >= 0 && q[0] < n_[0] && q[1] < n_[1] && q[2] < n_[2];
  }
  bool point_in_domain(const Key3& k) const {
    for (int d = 0; d < 3; ++d)
      if (k[d] < 0 || k[d] > 2 * n_[d]) return false;
    return true;
  }

  std::vector<Q> roots() const {
    std::vector<Q> r;
    const int s = 1 << top_;
    for (int k = 0; k < n_[2]; k += s)
      for (int j = 0; j < n_[1]; j += s)
        for (int i = 0; i < n_[0]; i += s) r.push_back({i, j, k});
    return r;
  }

  double value_at(const Key3& k) const { return in_.value(k); }
  Key3 centre(int level, const Q& q) const {
    const int s = 1 << level;  // half the doubled size
    return {2 * q[0] + s, 2 * q[1] + s, 2 * q[2] + s};
  }

  // Level-1 blocks (2x2x2 finest cubes) whose closure may hold a lattice vertex within h of
  // the surface: a vertex that ends a sign-changing edge (length <= h) or where f = 0 lies
  // there when f is 1-Lipschitz. Coarse-to-fine, dropping blocks the Lipschitz bound clears.
  std::vector<Q> candidate_blocks() {
    std::vector<Q> level = roots(), next;
    for (int l = top_; l >= 1; --l) {
      next.clear();
      const double reach = std::sqrt(3.0) / 2 * double(1 << l) * in_.h + 1.05 * in_.h;
      std::size_t passed = 0;
      for (const Q& q : level) {
        if (!(std::abs(value_at(centre(l, q))) <= reach)) continue;
        ++passed;
        if (l == 1) {
          next.push_back(q);
          continue;
        }
        const int s = 1 << (l - 1);
        for (int c = 0; c < 8; ++c) {
          Q k{q[0] + (c & 1) * s, q[1] + ((c >> 1) & 1) * s, q[2] + ((c >> 2) & 1) * s};
          if (inside_domain(k)) next.push_back(k);
        }
      }
      // Once the surface spans many blocks, their count multiplies by about 4 per level, with
      // a few tens of output tets per level-1 block (docs/tetra.md#behind-the-estimate). A few
      // blocks say nothing: a huge block around a small object.
      const double estimate = 15.0 * double(passed) * std::pow(4.0, l);
      if ((passed >= 64 && estimate > 2.0 * double(in_.max_tets)) || next.size() > kMaxNodesPerLevel)
        in_.refuse(estimate);
      level.swap(next);
    }
    return level;
  }

  void add_required_cube(const Q& c) {
    if (inside_domain(c)) required_.insert(node_key(0, c));
  }

  // The finest cubes: the stars of the band vertices (f = 0, or an edge to a vertex of the
  // opposite sign) among the candidates' lattice points, plus the neighbourhoods of `forced`.
  void mark_required(const std::vector<Q>& candidates) {
    static constexpr int kNbr[14][3] = {{2, 0, 0},  {-2, 0, 0}, {0, 2, 0},  {0, -2, 0}, {0, 0, 2},
                                        {0, 0, -2}, {1, 1, 1},  {1, 1, -1}, {1, -1, 1}, {1, -1, -1},
                                        {-1, 1, 1}, {-1, 1, -1}, {-1, -1, 1}, {-1, -1, -1}};
    std::unordered_set<std::uint64_t> seen;
    seen.reserve(candidates.size() * 16);
    auto visit = [&](const Key3& k) {
      if (!seen.insert(point_key(k)).second) return;
      const int s = sgn(value_at(k));
      bool band = s == 0;
      for (int e = 0; e < 14 && !band; ++e) {
        Key3 w{k[0] + kNbr[e][0], k[1] + kNbr[e][1], k[2] + kNbr[e][2]};
        if (point_in_domain(w) && sgn(value_at(w)) == -s) band = true;
      }
      if (!band) return;
      if ((k[0] & 1) == 0) {  // corner: the 8 cubes around it
        for (int c = 0; c < 8; ++c)
          add_required_cube({k[0] / 2 - 1 + (c & 1), k[1] / 2 - 1 + ((c >> 1) & 1), k[2] / 2 - 1 + ((c >> 2) & 1)});
      } else {  // centre: its cube and the 6 cubes across its faces
        Q c{(k[0] - 1) / 2, (k[1] - 1) / 2, (k[2] - 1) / 2};
        add_required_cube(c);
        for (int d = 0; d < 3; ++d)
          for (int side : {-1, 1}) {
            Q o = c;
            o[d] += side;
            add_required_cube(o);
          }
      }
    };
    for (const Q& q : candidates) {
      for (int z = 0; z <= 4; ++z)
        for (int y = 0; y <= 4; ++y)
          for (int x = 0; x <= 4; ++x) {
            // Corners (all even offsets) and centres (all odd) of the block's 8 cubes.
            const bool even = (x & 1) == 0 && (y & 1) == 0 && (z & 1) == 0;
            const bool odd = (x & 1) && (y & 1) && (z & 1);
            if (even || odd) visit({2 * q[0] + x, 2 * q[1] + y, 2 * q[2] + z});
          }
    }
    for (const Key3& k : in_.forced) {
      // Every cube within one cube of the point.
      for (int z = -2; z <= 2; ++z)
        for (int y = -2; y <= 2; ++y)
          for (int x = -2; x <= 2; ++x) {
            Q c{(k[0] + 2 * x) >> 1, (k[1] + 2 * y) >> 1, (k[2] + 2 * z) >> 1};
            add_required_cube(c);
          }
    }
  }

  // Top-down: a node splits when it holds a required cube.
  void build_tree() {
    std::vector<std::unordered_set<std::uint64_t>> ancestors(top_ + 1);
    std::vector<Q> cur;
    cur.reserve(required_.size());
    for (std::uint64_t key : required_)
      cur.push_back({int((key >> 4) & 0xFFFFF), int((key >> 24) & 0xFFFFF), int((key >> 44) & 0xFFFFF)});
    for (int l = 1; l <= top_; ++l) {
      ancestors[l].reserve(cur.size());
      std::vector<Q> up;
      for (const Q& c : cur) {
        Q a = align(c, l);
        if (ancestors[l].insert(node_key(l, a)).second) up.push_back(a);
      }
      cur.swap(up);
    }
    nodes_.reserve(required_.size() * 2 + 64);
    std::vector<Q> level = roots(), next;
    for (int l = top_; l >= 0; --l) {
      next.clear();
      for (const Q& q : level) {
        const bool split = l > 0 && ancestors[l].count(node_key(l, q));
        nodes_[node_key(l, q)] = !split;
        if (!split) continue;
        const int s = 1 << (l - 1);
        for (int c = 0; c < 8; ++c) next.push_back({q[0] + (c & 1) * s, q[1] + ((c >> 1) & 1) * s, q[2] + ((c >> 2) & 1) * s});
      }
      level.swap(next);
    }
  }

  // Level of the leaf covering the level-l cell q (in the domain), or -1 when that cell is
  // subdivided.
  int leaf_level(int l, const Q& q) const {
    for (int L = l; L <= top_; ++L) {
      auto it = nodes_.find(node_key(L, align(q, L)));
      if (it == nodes_.end()) continue;
      if (it->second) return L;
      if (L == l) return -1;
      internal("broken octree");
    }
    internal("no leaf covers a cell");
  }

  void split(int L, const Q& q, std::vector<std::pair<int, Q>>& work) {
    nodes_[node_key(L, q)] = false;
    const int s = 1 << (L - 1);
    for (int c = 0; c < 8; ++c) {
      Q k{q[0] + (c & 1) * s, q[1] + ((c >> 1) & 1) * s, q[2] + ((c >> 2) & 1) * s};
      nodes_[node_key(L - 1, k)] = true;
      work.push_back({L - 1, k});
    }
  }

  // 2:1 across faces and edges. Splitting only ever creates cells that must be checked
  // themselves, so a worklist of leaves suffices.
  void balance() {
    std::vector<std::pair<int, Q>> work;
    work.reserve(nodes_.size());
    for (const auto& [key, leaf] : nodes_)
      if (leaf) work.push_back({int(key & 15), {int((key >> 4) & 0xFFFFF), int((key >> 24) & 0xFFFFF), int((key >> 44) & 0xFFFFF)}});
    // Deterministic order (the hash map's is not).
    std::sort(work.begin(), work.end());
    while (!work.empty()) {
      auto [l, q] = work.back();
      work.pop_back();
      auto it = nodes_.find(node_key(l, q));
      if (it == nodes_.end() || !it->second) continue;
      const int s = 1 << l;
      for (int dz = -1; dz <= 1; ++dz)
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const int nz = (dx != 0) + (dy != 0) + (dz != 0);
            if (nz == 0 || nz == 3) continue;  // faces and edges only
            Q nq{q[0] + dx * s, q[1] + dy * s, q[2] + dz * s};
            if (!inside_domain(nq)) continue;
            for (;;) {
              int L = leaf_level(l, nq);
              if (L <= l + 1) break;
              split(L, align(nq, L), work);
            }
          }
    }
  }

  // Whether the midpoint of the edge a-b of a leaf of level l (l >= 1) is a lattice vertex:
  // some cell around the edge is subdivided.
  bool edge_split(int l, const Key3& a, const Key3& b) const {
    const int s = 1 << l;
    int axis = a[0] != b[0] ? 0 : (a[1] != b[1] ? 1 : 2);
    const int u = (axis + 1) % 3, v = (axis + 2) % 3;
    for (int i = 0; i < 2; ++i)
      for (int j = 0; j < 2; ++j) {
        Q q;
        q[axis] = std::min(a[axis], b[axis]) / 2;
        q[u] = a[u] / 2 - (i ? s : 0);
        q[v] = a[v] / 2 - (j ? s : 0);
        if (inside_domain(q) && leaf_level(l, q) == -1) return true;
      }
    return false;
  }

  static Key3 mid(const Key3& a, const Key3& b) { return {(a[0] + b[0]) / 2, (a[1] + b[1]) / 2, (a[2] + b[2]) / 2}; }

  void emit_tets() {
    std::vector<std::pair<int, Q>> leaves;
    for (const auto& [key, leaf] : nodes_)
      if (leaf) leaves.push_back({int(key & 15), {int((key >> 4) & 0xFFFFF), int((key >> 24) & 0xFFFFF), int((key >> 44) & 0xFFFFF)}});
    std::sort(leaves.begin(), leaves.end(), [](const auto& x, const auto& y) {
      return x.second != y.second ? x.second < y.second : x.first < y.first;
    });
    for (const auto& [l, q] : leaves) emit_leaf(l, q);
  }

  void emit_leaf(int l, const Q& q) {
    const int S = 1 << l, D = 2 * S;  // size in cubes, in doubled units
    const Key3 m{2 * q[0], 2 * q[1], 2 * q[2]};
    const Key3 c{m[0] + S, m[1] + S, m[2] + S};
    for (int a = 0; a < 3; ++a)
      for (int side = 0; side < 2; ++side) {
        Q nq = q;
        nq[a] += side ? S : -S;
        if (!inside_domain(nq)) continue;  // the domain border lies outside the object
        const int L = leaf_level(l, nq);
        const int b = (a + 1) % 3, e = (a + 2) % 3;
        auto corner = [&](int u, int v) {
          Key3 p = m;
          p[a] += side * D;
          p[b] += u * D;
          p[e] += v * D;
          return p;
        };
        // The face's corners in cyclic order.
        const Key3 ring[4] = {corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)};
        if (L == l) {
          if (!side) continue;  // the lower cell of the pair emits
          Key3 cn = c;
          cn[a] += D;
          for (int i = 0; i < 4; ++i) {
            const Key3 &p = ring[i], &r = ring[(i + 1) % 4];
            if (l > 0 && edge_split(l, p, r)) {
              const Key3 md = mid(p, r);
              emit_({c, cn, p, md}, false);
              emit_({c, cn, md, r}, false);
            } else {
              emit_({c, cn, p, r}, l == 0);
            }
          }
        } else if (L == l + 1) {
          // Half pyramids: the diagonal through the coarse face's centre, which is the corner
          // of this face nearest the coarse cell's middle.
          const Q big = align(nq, l + 1);
          const int ub = m[b] == 2 * big[b] ? 1 : 0, ve = m[e] == 2 * big[e] ? 1 : 0;
          const Key3 p0 = corner(ub, ve), p2 = corner(1 - ub, 1 - ve);
          const Key3 p1 = corner(1 - ub, ve), p3 = corner(ub, 1 - ve);
          if (l > 0 && (edge_split(l, p0, p1) || edge_split(l, p1, p2) || edge_split(l, p2, p3) || edge_split(l, p3, p0)))
            internal("split edge on a face against a coarser cell");
          emit_({c, p0, p1, p2}, false);
          emit_({c, p0, p3, p2}, false);
        } else if (L == -1) {
          Key3 f = c;
          f[a] = m[a] + side * D;
          for (int i = 0; i < 4; ++i) {
            const Key3 &p = ring[i], &r = ring[(i + 1) % 4];
            const Key3 md = mid(p, r);
            emit_({c, f, p, md}, false);
            emit_({c, f, md, r}, false);
          }
        } else {
          internal("unbalanced octree");
        }
      }
  }

  const GradedLatticeInput& in_;
  const std::function<void(const std::array<Key3, 4>&, bool)>& emit_;
  int top_ = 0;
  Q n_{};
  std::unordered_set<std::uint64_t> required_;      // finest cubes, node_key(0, c)
  std::unordered_map<std::uint64_t, bool> nodes_;   // node_key -> is a leaf
};

}  // namespace

void graded_bcc_lattice(const GradedLatticeInput& in, const std::function<void(const std::array<Key3, 4>&, bool)>& emit) {
  Builder(in, emit).run();
}

}  // namespace incise::stuffing_detail
