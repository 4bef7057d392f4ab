#include "mesh/isosurface_stuffing.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "mesh/errors.h"
#include "mesh/generate.h"
#include "mesh/isosurface_stuffing_graded.h"

// Lattice layout. Cubes of side h indexed c = (i,j,k), i in [0, n). Lattice points carry
// doubled integer coordinates: corner (i,j,k) -> (2i,2j,2k), centre of cube c -> 2c+1, so
// a point's grid (corner / centre) is the parity of any coordinate. BCC tets: for each pair
// of face-adjacent cubes (c, c+e_d), the long edge between their centres and each of the 4
// edges of their shared square face span one tet. Each tet is stored as
// (centre, centre, corner, corner): its long edges are local (0,1) and (2,3), the four short
// edges join the pairs. Every tet is assigned to its lower cube c, 12 per cube.

namespace incise {
namespace {

constexpr std::uint64_t kEmptyKey = ~std::uint64_t(0);
constexpr int kKeyBits = 21;
constexpr int kMaxCells = (1 << (kKeyBits - 1)) - 2;  // doubled coordinates must fit 21 bits
constexpr int kLeafCells = 8;                           // leaf block edge, in cubes
constexpr std::size_t kMaxDescentNodes = std::size_t(1) << 22;

// Open addressing, linear probing: the lattice and edge maps are hot and large; std::unordered_map
// costs an allocation per entry.
class KeyMap {
public:
  explicit KeyMap(std::size_t expected) {
    std::size_t cap = 64;
    while (cap < 2 * expected) cap <<= 1;
    keys_.assign(cap, kEmptyKey);
    vals_.resize(cap);
  }
  // Returns the slot value for key, inserting `value` if absent; `inserted` tells which.
  std::uint32_t insert(std::uint64_t key, std::uint32_t value, bool& inserted) {
    if (2 * (size_ + 1) > keys_.size()) grow();
    std::size_t i = slot(key);
    while (keys_[i] != kEmptyKey) {
      if (keys_[i] == key) {
        inserted = false;
        return vals_[i];
      }
      i = (i + 1) & (keys_.size() - 1);
    }
    keys_[i] = key;
    vals_[i] = value;
    ++size_;
    inserted = true;
    return value;
  }
  // The value for key, or UINT32_MAX.
  std::uint32_t find(std::uint64_t key) const {
    std::size_t i = slot(key);
    while (keys_[i] != kEmptyKey) {
      if (keys_[i] == key) return vals_[i];
      i = (i + 1) & (keys_.size() - 1);
    }
    return std::numeric_limits<std::uint32_t>::max();
  }

private:
  std::size_t slot(std::uint64_t key) const {
    key ^= key >> 31;
    key *= 0x9E3779B97F4A7C15ull;
    key ^= key >> 29;
    return static_cast<std::size_t>(key) & (keys_.size() - 1);
  }
  void grow() {
    std::vector<std::uint64_t> old_keys(keys_.size() * 2, kEmptyKey);
    std::vector<std::uint32_t> old_vals(vals_.size() * 2);
    old_keys.swap(keys_);
    old_vals.swap(vals_);
    size_ = 0;
    bool dummy;
    for (std::size_t i = 0; i < old_keys.size(); ++i)
      if (old_keys[i] != kEmptyKey) insert(old_keys[i], old_vals[i], dummy);
  }
  std::vector<std::uint64_t> keys_;
  std::vector<std::uint32_t> vals_;
  std::size_t size_ = 0;
};

using Key3 = stuffing_detail::Key3;

std::uint64_t pack(const Key3& k) {
  return std::uint64_t(k[0]) | (std::uint64_t(k[1]) << kKeyBits) | (std::uint64_t(k[2]) << (2 * kKeyBits));
}
std::uint64_t edge_key(std::uint32_t a, std::uint32_t b) {
  if (a > b) std::swap(a, b);
  return (std::uint64_t(a) << 32) | b;
}

struct CutEdge {
  std::uint32_t u, w;  // lattice vertices, u < w
  bool long_edge;
  double t;            // cut point = (1-t) x_u + t x_w
  Vec3 point;
};

// A block of cubes [lo, hi) for the coarse descent.
struct Node {
  std::array<int, 3> lo, hi;
};

std::string fmt_count(double n) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.3g", n);
  return buf;
}

// Bracketed root of g on [0,1], g(0) = g0 and g(1) = g1 of opposite strict signs. Illinois
// (modified regula falsi) converges superlinearly on smooth sdfs; a bisection step whenever
// the bracket fails to halve keeps the worst case (kinks, clamped level sets) linear.
template <class G>
double find_root(G&& g, double g0, double g1, double tol_value) {
  double a = 0, b = 1, fa = g0, fb = g1;
  int side = 0;
  double x = (a * fb - b * fa) / (fb - fa);
  for (int it = 0; it < 100; ++it) {
    double width = b - a;
    x = (a * fb - b * fa) / (fb - fa);
    if (!(x > a && x < b)) x = 0.5 * (a + b);
    double fx = g(x);
    if (std::abs(fx) <= tol_value) return x;
    if ((fx < 0) == (fa < 0)) {
      a = x;
      fa = fx;
      if (side == -1) fb *= 0.5;
      side = -1;
    } else {
      b = x;
      fb = fx;
      if (side == 1) fa *= 0.5;
      side = 1;
    }
    if (b - a > 0.5 * width) {  // stalled: bisect once
      double m = 0.5 * (a + b), fm = g(m);
      if (std::abs(fm) <= tol_value) return m;
      if ((fm < 0) == (fa < 0)) {
        a = m;
        fa = fm;
      } else {
        b = m;
        fb = fm;
      }
      side = 0;
    }
    if (b - a < 1e-13) break;
  }
  return std::abs(fa) < std::abs(fb) ? a : b;
}

class Stuffer {
public:
  Stuffer(const std::function<double(const Vec3&)>& sdf, const Vec3& lo, const Vec3& hi, const StuffingOptions& opt)
      : sdf_(sdf), lo_(lo), hi_(hi), opt_(opt), h_(opt.cell_size), vertex_of_(1 << 16), cut_of_(1 << 12) {}

  TetMesh run() {
    for (int d = 0; d < 3; ++d) {
      double cells = std::ceil((hi_[d] - lo_[d]) / h_) + 2;
      if (cells > kMaxCells)
        throw InvalidArgument("isosurface_stuffing: " + fmt_count(cells) + " cells along an axis (at most " +
                              std::to_string(kMaxCells) + "); increase cell_size");
      n_[d] = static_cast<int>(cells);
    }
    // One cube of margin on each side: lattice points on the lattice's own border are
    // then strictly outside the (box-clipped) domain, so no output tet needs a missing cube.
    origin_ = lo_ - Vec3::Constant(h_);
    if (opt_.graded) {
      build_graded_lattice();
    } else {
      std::vector<Node> leaves = descend();
      build_lattice_tets(leaves);
      collect_cuts();
    }
    solve_cuts();
    warp();
    fill();
    return make_mesh();
  }

private:
  // The sdf, clipped to the box, NaN refused. max() of two 1-Lipschitz functions is one.
  double f(const Vec3& p) const {
    double s = sdf_(p);
    if (std::isnan(s))
      throw InvalidArgument("isosurface_stuffing: sdf returned NaN at (" + std::to_string(p.x()) + ", " +
                            std::to_string(p.y()) + ", " + std::to_string(p.z()) + ")");
    double box = std::max({lo_.x() - p.x(), p.x() - hi_.x(), lo_.y() - p.y(), p.y() - hi_.y(), lo_.z() - p.z(),
                           p.z() - hi_.z()});
    return std::max(s, box);
  }

  Vec3 lattice_point(const Key3& k) const { return origin_ + Vec3(k[0], k[1], k[2]) * (0.5 * h_); }

  // Coarse-to-fine subdivision of the cube range, dropping blocks the Lipschitz bound shows
  // empty, down to leaves of kLeafCells^3 cubes. Also estimates the output size so huge
  // requests are refused before the lattice is built.
  std::vector<Node> descend() {
    std::vector<Node> level{{{0, 0, 0}, {n_[0], n_[1], n_[2]}}}, leaves;
    double leaf_cells = 0;  // estimated inside cubes in accepted leaves
    while (!level.empty()) {
      std::vector<Node> next;
      double level_cells = 0, certain_cells = 0;
      for (const Node& nd : level) {
        Vec3 a = origin_ + Vec3(nd.lo[0], nd.lo[1], nd.lo[2]) * h_;
        Vec3 b = origin_ + Vec3(nd.hi[0], nd.hi[1], nd.hi[2]) * h_;
        Vec3 c = 0.5 * (a + b);
        double r = 0.5 * (b - a).norm();
        double v = f(c);
        // A tet of a cube in this block has its vertices within the block grown by one cube.
        const double reach = r + 2 * h_;
        if (v > reach) continue;
        double cubes = double(nd.hi[0] - nd.lo[0]) * (nd.hi[1] - nd.lo[1]) * (nd.hi[2] - nd.lo[2]);
        // Fraction inside, taking the surface as a plane at distance v from the centre.
        double half = 0.5 * (b - a).minCoeff();
        double frac = v < -reach ? 1.0 : std::clamp(0.5 - v / (2 * half), 0.0, 1.0);
        if (v < -reach) certain_cells += cubes;  // all 12 tets of each cube are output whole
        int ext = std::max({nd.hi[0] - nd.lo[0], nd.hi[1] - nd.lo[1], nd.hi[2] - nd.lo[2]});
        if (ext <= kLeafCells) {
          leaves.push_back(nd);
          leaf_cells += cubes * frac;
          continue;
        }
        level_cells += cubes * frac;
        std::array<int, 3> mid;
        for (int d = 0; d < 3; ++d) mid[d] = nd.hi[d] - nd.lo[d] > 1 ? (nd.lo[d] + nd.hi[d]) / 2 : nd.hi[d];
        for (int ch = 0; ch < 8; ++ch) {
          Node k;
          bool empty = false;
          for (int d = 0; d < 3; ++d) {
            bool upper = (ch >> d) & 1;
            k.lo[d] = upper ? mid[d] : nd.lo[d];
            k.hi[d] = upper ? nd.hi[d] : mid[d];
            empty |= k.lo[d] >= k.hi[d];
          }
          if (!empty) next.push_back(k);
        }
      }
      estimate_ = 12 * (leaf_cells + level_cells);
      if (12 * certain_cells > double(opt_.max_tets) || next.size() > kMaxDescentNodes) refuse();
      level.swap(next);
    }
    // The leaf-level estimate overcounts thin parts; the hard limit is applied while building.
    if (estimate_ > 2.0 * double(opt_.max_tets)) refuse();
    return leaves;
  }

  [[noreturn]] void refuse() const {
    throw InvalidArgument("isosurface_stuffing: about " + fmt_count(estimate_) + " tets at cell_size " +
                          fmt_count(h_) + " exceeds max_tets " + std::to_string(opt_.max_tets) +
                          "; increase cell_size");
  }

  std::uint32_t vertex(const Key3& k) {
    bool inserted;
    std::uint32_t id = vertex_of_.insert(pack(k), static_cast<std::uint32_t>(key_.size()), inserted);
    if (inserted) {
      Vec3 p = lattice_point(k);
      double v = f(p);
      key_.push_back(k);
      pos_.push_back(p);
      value_.push_back(v);
      sign_.push_back(static_cast<std::int8_t>(v < 0 ? -1 : (v > 0 ? 1 : 0)));
    }
    return id;
  }

  void build_lattice_tets(const std::vector<Node>& leaves) {
    for (const Node& nd : leaves)
      for (int k = nd.lo[2]; k < nd.hi[2]; ++k)
        for (int j = nd.lo[1]; j < nd.hi[1]; ++j)
          for (int i = nd.lo[0]; i < nd.hi[0]; ++i) {
            const int c[3] = {i, j, k};
            std::uint32_t centre = vertex({2 * i + 1, 2 * j + 1, 2 * k + 1});
            for (int d = 0; d < 3; ++d) {
              if (c[d] + 1 >= n_[d]) continue;
              const int d1 = (d + 1) % 3, d2 = (d + 2) % 3;
              Key3 nk{2 * i + 1, 2 * j + 1, 2 * k + 1};
              nk[d] += 2;
              std::uint32_t other = vertex(nk);
              // Corners of the shared face: coordinate d fixed at c[d]+1.
              std::uint32_t q[2][2];
              for (int a = 0; a < 2; ++a)
                for (int b = 0; b < 2; ++b) {
                  Key3 ck{2 * i, 2 * j, 2 * k};
                  ck[d] = 2 * (c[d] + 1);
                  ck[d1] = 2 * (c[d1] + a);
                  ck[d2] = 2 * (c[d2] + b);
                  q[a][b] = vertex(ck);
                }
              const std::uint32_t face_edges[4][2] = {
                  {q[0][0], q[1][0]}, {q[0][1], q[1][1]}, {q[0][0], q[0][1]}, {q[1][0], q[1][1]}};
              for (const auto& e : face_edges) {
                std::array<std::uint32_t, 4> t{centre, other, e[0], e[1]};
                if (sign_[t[0]] < 0 || sign_[t[1]] < 0 || sign_[t[2]] < 0 || sign_[t[3]] < 0) {
                  lattice_tets_.push_back(t);
                  if (lattice_tets_.size() > opt_.max_tets) {
                    estimate_ = std::max(estimate_, double(lattice_tets_.size()));
                    refuse();
                  }
                }
              }
            }
          }
    if (lattice_tets_.empty())
      throw InvalidArgument("isosurface_stuffing: sdf >= 0 at every lattice point in the box: empty mesh");
  }

  // The sign-changing lattice edges. Only (centre, centre, corner, corner) tets have them, so
  // local edges (0,1) and (2,3) are the long ones.
  void collect_cuts() {
    static constexpr int kEdges[6][2] = {{0, 1}, {2, 3}, {0, 2}, {0, 3}, {1, 2}, {1, 3}};
    for (const auto& t : lattice_tets_)
      for (int e = 0; e < 6; ++e) {
        std::uint32_t a = t[kEdges[e][0]], b = t[kEdges[e][1]];
        if (sign_[a] * sign_[b] >= 0) continue;
        bool inserted;
        cut_of_.insert(edge_key(a, b), static_cast<std::uint32_t>(cuts_.size()), inserted);
        if (inserted) cuts_.push_back({std::min(a, b), std::max(a, b), e < 2, 0.0, Vec3::Zero()});
      }
  }

  // Graded lattice (isosurface_stuffing_graded.h). The cut, warp and stencil steps below are
  // the uniform ones; they stay exactly the uniform algorithm if every lattice tet that
  // touches a vertex they can move or cut (one with f = 0 or ending a sign-changing edge) is
  // a finest BCC tet: those vertices then have the uniform lattice's star. Coarse and
  // transition tets are then wholly inside or outside and keep their lattice shape. The
  // lattice builder arranges that for a 1-Lipschitz f; this checks it, and rebuilds finer
  // around every offending tet until it holds (an sdf that breaks the contract costs rounds,
  // never a wrong mesh).
  void build_graded_lattice() {
    stuffing_detail::GradedLatticeInput in;
    in.cells = n_;
    in.h = h_;
    in.max_tets = opt_.max_tets;
    in.value = [this](const Key3& k) { return value_[vertex(k)]; };
    in.refuse = [this](double estimate) {
      estimate_ = estimate;
      refuse();
    };
    for (int round = 0;; ++round) {
      lattice_tets_.clear();
      fine_.clear();
      cuts_.clear();
      cut_of_ = KeyMap(1 << 12);
      stuffing_detail::graded_bcc_lattice(in, [this](const std::array<Key3, 4>& k, bool fine) {
        std::array<std::uint32_t, 4> t{vertex(k[0]), vertex(k[1]), vertex(k[2]), vertex(k[3])};
        if (sign_[t[0]] < 0 || sign_[t[1]] < 0 || sign_[t[2]] < 0 || sign_[t[3]] < 0) {
          lattice_tets_.push_back(t);
          fine_.push_back(fine);
          if (lattice_tets_.size() > opt_.max_tets) {
            estimate_ = std::max(estimate_, double(lattice_tets_.size()));
            refuse();
          }
        }
      });
      if (lattice_tets_.empty())
        throw InvalidArgument("isosurface_stuffing: sdf >= 0 at every lattice point in the box: empty mesh");
      collect_cuts();
      std::vector<std::uint8_t> touched(key_.size(), 0);
      for (const CutEdge& c : cuts_) touched[c.u] = touched[c.w] = 1;
      const std::size_t before = in.forced.size();
      for (std::size_t i = 0; i < lattice_tets_.size(); ++i) {
        if (fine_[i]) continue;
        const auto& t = lattice_tets_[i];
        bool bad = false;
        for (std::uint32_t v : t) bad |= sign_[v] >= 0 || touched[v];
        if (bad)
          for (std::uint32_t v : t) in.forced.push_back(key_[v]);
      }
      if (in.forced.size() == before) return;
      if (round >= 40) throw Error("isosurface_stuffing: internal error: the graded lattice does not settle");
    }
  }

  void solve_cuts() {
    const double tol = 1e-12 * h_;
    for (CutEdge& c : cuts_) {
      const Vec3 xu = pos_[c.u], xw = pos_[c.w];
      c.t = find_root([&](double s) { return f(xu + s * (xw - xu)); }, value_[c.u], value_[c.w], tol);
      c.point = xu + c.t * (xw - xu);
    }
  }

  // A lattice vertex is violated by a cut point on one of its edges closer than alpha times
  // the edge length (alpha_long / alpha_short by edge type); it moves to the closest such cut
  // point and becomes a zero vertex, which removes the cut points on all its edges. Vertices
  // are visited in id order; a cut point whose edge lost its sign change no longer violates.
  void warp() {
    struct Candidate {
      std::uint32_t v;
      double dist;
      std::uint32_t cut;
    };
    std::vector<Candidate> cand;
    for (std::uint32_t i = 0; i < cuts_.size(); ++i) {
      const CutEdge& c = cuts_[i];
      double alpha = c.long_edge ? opt_.alpha_long : opt_.alpha_short;
      double len = (pos_[c.w] - pos_[c.u]).norm();
      if (c.t < alpha) cand.push_back({c.u, c.t * len, i});
      if (1 - c.t < alpha) cand.push_back({c.w, (1 - c.t) * len, i});
    }
    std::sort(cand.begin(), cand.end(), [](const Candidate& a, const Candidate& b) {
      return a.v != b.v ? a.v < b.v : (a.dist != b.dist ? a.dist < b.dist : a.cut < b.cut);
    });
    for (std::size_t i = 0; i < cand.size();) {
      std::size_t j = i;
      while (j < cand.size() && cand[j].v == cand[i].v) ++j;
      for (std::size_t k = i; k < j; ++k) {
        const CutEdge& c = cuts_[cand[k].cut];
        if (sign_[c.u] == 0 || sign_[c.w] == 0) continue;  // edge no longer crosses
        pos_[cand[k].v] = c.point;
        sign_[cand[k].v] = 0;
        break;
      }
      i = j;
    }
  }

  // Output point ids: lattice vertex v -> v, cut point i -> i | kCutBit.
  static constexpr std::uint32_t kCutBit = 0x80000000u;
  std::uint32_t cut(std::uint32_t a, std::uint32_t b) const {
    std::uint32_t i = cut_of_.find(edge_key(a, b));
    if (i == std::numeric_limits<std::uint32_t>::max()) throw Error("isosurface_stuffing: internal error: missing cut point");
    return i | kCutBit;
  }

  // The quadrilateral a stencil leaves in lattice face (p, q, o), p and q inside and o
  // outside, has corners p, q, cut(q,o), cut(p,o). Returns the inside vertex its diagonal
  // starts from (p: diagonal p-cut(q,o); q: diagonal q-cut(p,o)). Both tets sharing the face
  // compute the same answer, which keeps the mesh conforming.
  //  - pq short: one of po, qo is long; the diagonal joins the cut point on the long edge to
  //    the other inside vertex.
  //  - pq long: the paper's parity rule. The four faces around a long edge alternate (their
  //    o lie in the four quadrants around it), so in a tet whose two inside vertices span a
  //    long edge the two quadrilaterals take diagonals from different ends and the prism
  //    between them has a triangulation; the grid term and the edge direction make the rule a
  //    function of the face alone.
  std::uint32_t diagonal_start(std::uint32_t p, std::uint32_t q, std::uint32_t o, bool pq_long, bool po_long) const {
    if (!pq_long) return po_long ? q : p;
    const Key3 &kp = key_[p], &kq = key_[q], &ko = key_[o];
    int axis = kp[0] != kq[0] ? 0 : (kp[1] != kq[1] ? 1 : 2);
    int parity = (kp[0] & 1) == 0 ? 1 : 0;  // corner grid
    parity += kp[axis] > kq[axis] ? 1 : 0;
    for (int d = 0; d < 3; ++d)
      if (d != axis && ko[d] < kp[d]) ++parity;
    return (parity & 1) ? q : p;
  }

  void emit(std::uint32_t a, std::uint32_t b, std::uint32_t c, std::uint32_t d) { out_.push_back({a, b, c, d}); }

  // Triangular prism with columns (bottom[i], top[i]); before[i][j] = column i must come
  // before column j (-1 free). Staircase triangulation along an order consistent with it:
  // the quad between columns u (earlier) and v gets the diagonal bottom[v]-top[u].
  void prism(const std::array<std::uint32_t, 3>& bottom, const std::array<std::uint32_t, 3>& top,
             const std::array<std::array<int, 3>, 3>& before) {
    static constexpr int kPerms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    for (const auto& pm : kPerms) {
      bool ok = true;
      for (int x = 0; x < 3 && ok; ++x)
        for (int y = x + 1; y < 3 && ok; ++y)
          if (before[pm[y]][pm[x]] == 1) ok = false;
      if (!ok) continue;
      const int i = pm[0], j = pm[1], k = pm[2];
      emit(bottom[i], bottom[j], bottom[k], top[i]);
      emit(top[i], bottom[j], bottom[k], top[j]);
      emit(top[i], top[j], bottom[k], top[k]);
      return;
    }
    throw Error("isosurface_stuffing: internal error: cyclic prism diagonals");
  }

  void fill() {
    for (const auto& t : lattice_tets_) {
      int nin = 0, nout = 0;
      int in[4], out[4], zero[4], nz = 0;
      for (int i = 0; i < 4; ++i) {
        int s = sign_[t[i]];
        if (s < 0)
          in[nin++] = i;
        else if (s > 0)
          out[nout++] = i;
        else
          zero[nz++] = i;
      }
      if (nin == 0) continue;  // includes all-zero tets, which the stencils never output
      auto is_long = [](int a, int b) { return a / 2 == b / 2; };
      auto diag_from_first = [&](int p, int q, int o) {  // true: diagonal from p
        return diagonal_start(t[p], t[q], t[o], is_long(p, q), is_long(p, o)) == t[p];
      };
      if (nout == 0) {
        emit(t[0], t[1], t[2], t[3]);
      } else if (nin == 1) {
        // One inside vertex: the tet keeps it, its zero vertices and the cut points of its
        // edges to outside vertices.
        std::uint32_t v[4];
        int p = in[0];
        for (int i = 0; i < 4; ++i) v[i] = (i == p || sign_[t[i]] == 0) ? t[i] : cut(t[p], t[i]);
        emit(v[0], v[1], v[2], v[3]);
      } else if (nin == 2 && nout == 1) {
        // Pyramid: quadrilateral p, q, cut(q,o), cut(p,o) under the zero vertex z.
        int p = in[0], q = in[1], o = out[0], z = zero[0];
        std::uint32_t cp = cut(t[p], t[o]), cq = cut(t[q], t[o]);
        if (diag_from_first(p, q, o)) {
          emit(t[p], t[q], cq, t[z]);
          emit(t[p], cq, cp, t[z]);
        } else {
          emit(t[q], cp, t[p], t[z]);
          emit(t[q], cq, cp, t[z]);
        }
      } else if (nin == 2 && nout == 2) {
        // Prism: columns (p,q), (cut(p,o1), cut(q,o1)), (cut(p,o2), cut(q,o2)); the two lateral
        // quadrilaterals lie in lattice faces, the third is the isosurface patch.
        int p = in[0], q = in[1], o1 = out[0], o2 = out[1];
        std::array<std::uint32_t, 3> bottom{t[p], cut(t[p], t[o1]), cut(t[p], t[o2])};
        std::array<std::uint32_t, 3> top{t[q], cut(t[q], t[o1]), cut(t[q], t[o2])};
        std::array<std::array<int, 3>, 3> before{{{-1, -1, -1}, {-1, -1, -1}, {-1, -1, -1}}};
        for (int col = 1; col <= 2; ++col) {
          int o = col == 1 ? o1 : o2;
          // Diagonal from p (bottom of column 0) to top of column col: col comes first.
          bool from_p = diag_from_first(p, q, o);
          before[col][0] = from_p ? 1 : 0;
          before[0][col] = from_p ? 0 : 1;
        }
        prism(bottom, top, before);
      } else if (nin == 3) {
        // Tet minus a corner: prism with the inside vertices as bottom and the cut points
        // towards the outside vertex as top; all three quadrilaterals lie in lattice faces.
        int o = out[0];
        std::array<std::uint32_t, 3> bottom{t[in[0]], t[in[1]], t[in[2]]};
        std::array<std::uint32_t, 3> top{cut(t[in[0]], t[o]), cut(t[in[1]], t[o]), cut(t[in[2]], t[o])};
        std::array<std::array<int, 3>, 3> before{{{-1, -1, -1}, {-1, -1, -1}, {-1, -1, -1}}};
        for (int a = 0; a < 3; ++a)
          for (int b = a + 1; b < 3; ++b) {
            bool from_a = diag_from_first(in[a], in[b], o);  // diagonal bottom[a]-top[b]
            before[b][a] = from_a ? 1 : 0;
            before[a][b] = from_a ? 0 : 1;
          }
        prism(bottom, top, before);
      } else {
        throw Error("isosurface_stuffing: internal error: unhandled stencil");
      }
    }
    if (out_.size() > opt_.max_tets) {
      estimate_ = double(out_.size());
      refuse();
    }
    if (out_.empty())
      throw InvalidArgument("isosurface_stuffing: no tet left inside the surface (all inside lattice points lie "
                            "within alpha of it): empty mesh; decrease cell_size");
  }

  TetMesh make_mesh() const {
    std::vector<std::uint32_t> lat_id(key_.size(), kUnset), cut_id(cuts_.size(), kUnset);
    std::vector<Vec3> points;
    auto id = [&](std::uint32_t x) {
      std::uint32_t& slot = (x & kCutBit) ? cut_id[x & ~kCutBit] : lat_id[x];
      if (slot == kUnset) {
        slot = static_cast<std::uint32_t>(points.size());
        points.push_back((x & kCutBit) ? cuts_[x & ~kCutBit].point : pos_[x]);
      }
      return slot;
    };
    std::vector<std::array<std::uint32_t, 4>> tets;
    tets.reserve(out_.size());
    for (const auto& t : out_) tets.push_back({id(t[0]), id(t[1]), id(t[2]), id(t[3])});

    TetMesh m;
    m.reserve(points.size(), tets.size());
    for (const Vec3& p : points) m.add_vertex(p);
    for (auto t : tets) {
      // In units of h, so the sign survives scales where h^3 under- or overflows.
      const Vec3& a = points[t[0]];
      Vec3 b = (points[t[1]] - a) / h_, c = (points[t[2]] - a) / h_, d = (points[t[3]] - a) / h_;
      double det = b.cross(c).dot(d);
      if (!(det != 0)) throw Error("isosurface_stuffing: internal error: degenerate tet");
      if (det < 0) std::swap(t[2], t[3]);
      m.add_tet(VertexId(t[0]), VertexId(t[1]), VertexId(t[2]), VertexId(t[3]), opt_.label);
    }
    tag_boundary(m);
    m.discard_change();
    return m;
  }

  static constexpr std::uint32_t kUnset = std::numeric_limits<std::uint32_t>::max();

  const std::function<double(const Vec3&)>& sdf_;
  const Vec3 lo_, hi_;
  const StuffingOptions& opt_;
  const double h_;
  std::array<int, 3> n_{};
  Vec3 origin_;
  double estimate_ = 0;

  KeyMap vertex_of_;  // packed doubled coordinates -> lattice vertex
  std::vector<Key3> key_;
  std::vector<Vec3> pos_;  // warped positions
  std::vector<double> value_;
  std::vector<std::int8_t> sign_;  // -1 inside, 0 on the surface (or warped), +1 outside

  std::vector<std::array<std::uint32_t, 4>> lattice_tets_;  // tets with an inside vertex
  std::vector<std::uint8_t> fine_;                          // graded: lattice_tets_[i] is a finest BCC tet
  KeyMap cut_of_;                                           // edge -> cut point
  std::vector<CutEdge> cuts_;
  std::vector<std::array<std::uint32_t, 4>> out_;
};

}  // namespace

TetMesh isosurface_stuffing(const std::function<double(const Vec3&)>& sdf, const Vec3& lo, const Vec3& hi,
                            const StuffingOptions& options) {
  if (!sdf) throw InvalidArgument("isosurface_stuffing: no sdf given");
  if (!(options.cell_size > 0) || !std::isfinite(options.cell_size))
    throw InvalidArgument("isosurface_stuffing: cell_size must be positive and finite");
  if (!(options.alpha_long > 0 && options.alpha_long < 0.5) || !(options.alpha_short > 0 && options.alpha_short < 0.5))
    throw InvalidArgument("isosurface_stuffing: alpha_long and alpha_short must lie in (0, 0.5)");
  if (options.max_tets == 0) throw InvalidArgument("isosurface_stuffing: max_tets must be positive");
  for (int d = 0; d < 3; ++d) {
    if (!std::isfinite(lo[d]) || !std::isfinite(hi[d]))
      throw InvalidArgument("isosurface_stuffing: the domain box must be finite");
    if (!(hi[d] > lo[d])) throw InvalidArgument("isosurface_stuffing: the domain box is empty (hi <= lo)");
  }
  return Stuffer(sdf, lo, hi, options).run();
}

}  // namespace incise
