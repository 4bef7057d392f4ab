#include "sim/linalg/block_cholesky.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>

#include <Eigen/Cholesky>

#if defined(__GNUC__) && defined(__x86_64__)
#include <immintrin.h>
#define INCISE_GRAM_AVX2 1
#endif

#include "sim/linalg/simd_clones.h"

namespace incise {

namespace {

// Supernodes hold at most this many positions (6 x this columns): the update of a wider
// clique goes through the same kernel, a block of columns at a time, and each panel's
// diagonal block stays small enough for a fixed-size LL^T. Wider was no faster
// (docs/solver.md#behind-the-constants).
constexpr std::int32_t kPanelNodes = 4;
constexpr int kPanelCols = 6 * kPanelNodes;

using Panel = Eigen::Map<Eigen::MatrixXd, 0, Eigen::OuterStride<>>;

// C := B B^T, the lower triangle (and some entries above it) of the h x h column-major C,
// for the h x w column-major B (leading dimension ld): a supernode's update, most of the
// factorization's flops. Register tiles of 12 x 4 with AVX2 and FMA where the CPU has them
// (the build targets the baseline instruction set, and the BLAS at hand may not know the
// CPU: docs/solver.md, "The coarse factor in panels").
void gram_scalar(int h, int w, const double* b, std::size_t ld, double* c, int i0, int j0, int ni, int nj) {
  for (int q = 0; q < nj; ++q)
    for (int r = 0; r < ni; ++r) {
      double s = 0;
      for (int k = 0; k < w; ++k)
        s += b[std::size_t(i0 + r) + std::size_t(k) * ld] * b[std::size_t(j0 + q) + std::size_t(k) * ld];
      c[std::size_t(j0 + q) * std::size_t(h) + std::size_t(i0 + r)] = s;
    }
}

#ifdef INCISE_GRAM_AVX2
__attribute__((target("avx2,fma"))) inline void gram_tile_avx2(int w, const double* b, std::size_t ld, double* c,
                                                              std::size_t h, int i0, int j0) {
  __m256d a00 = _mm256_setzero_pd(), a01 = a00, a02 = a00, a10 = a00, a11 = a00, a12 = a00, a20 = a00, a21 = a00,
          a22 = a00, a30 = a00, a31 = a00, a32 = a00;
  const double* p = b + i0;
  const double* q = b + j0;
  for (int k = 0; k < w; ++k, p += ld, q += ld) {
    const __m256d r0 = _mm256_loadu_pd(p), r1 = _mm256_loadu_pd(p + 4), r2 = _mm256_loadu_pd(p + 8);
    __m256d s = _mm256_broadcast_sd(q);
    a00 = _mm256_fmadd_pd(r0, s, a00), a01 = _mm256_fmadd_pd(r1, s, a01), a02 = _mm256_fmadd_pd(r2, s, a02);
    s = _mm256_broadcast_sd(q + 1);
    a10 = _mm256_fmadd_pd(r0, s, a10), a11 = _mm256_fmadd_pd(r1, s, a11), a12 = _mm256_fmadd_pd(r2, s, a12);
    s = _mm256_broadcast_sd(q + 2);
    a20 = _mm256_fmadd_pd(r0, s, a20), a21 = _mm256_fmadd_pd(r1, s, a21), a22 = _mm256_fmadd_pd(r2, s, a22);
    s = _mm256_broadcast_sd(q + 3);
    a30 = _mm256_fmadd_pd(r0, s, a30), a31 = _mm256_fmadd_pd(r1, s, a31), a32 = _mm256_fmadd_pd(r2, s, a32);
  }
  double* o = c + std::size_t(j0) * h + std::size_t(i0);
  _mm256_storeu_pd(o, a00), _mm256_storeu_pd(o + 4, a01), _mm256_storeu_pd(o + 8, a02), o += h;
  _mm256_storeu_pd(o, a10), _mm256_storeu_pd(o + 4, a11), _mm256_storeu_pd(o + 8, a12), o += h;
  _mm256_storeu_pd(o, a20), _mm256_storeu_pd(o + 4, a21), _mm256_storeu_pd(o + 8, a22), o += h;
  _mm256_storeu_pd(o, a30), _mm256_storeu_pd(o + 4, a31), _mm256_storeu_pd(o + 8, a32);
}

__attribute__((target("avx2,fma"))) void gram_avx2(int h, int w, const double* b, std::size_t ld, double* c) {
  for (int j0 = 0; j0 < h; j0 += 4) {
    const int nj = std::min(4, h - j0);
    int i0 = j0;
    if (nj == 4)
      for (; i0 + 12 <= h; i0 += 12) gram_tile_avx2(w, b, ld, c, std::size_t(h), i0, j0);
    if (i0 < h) gram_scalar(h, w, b, ld, c, i0, j0, h - i0, nj);
  }
}
#endif

void lower_gram(int h, int w, const double* b, std::size_t ld, double* c) {
#ifdef INCISE_GRAM_AVX2
  static const bool avx2 = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  if (avx2) return gram_avx2(h, w, b, ld, c);
#endif
  for (int j0 = 0; j0 < h; j0 += 4) gram_scalar(h, w, b, ld, c, j0, j0, h - j0, std::min(4, h - j0));
}

// B := B L^-T for the h x w column-major B and the w x w lower L (both leading dimension
// ld): column c of B minus its earlier columns times L(c, k), over L(c, c).
INCISE_SIMD_CLONES void solve_right_lt(int h, int w, const double* __restrict l, std::size_t ld,
                                       double* __restrict b) {
  for (int c = 0; c < w; ++c) {
    double* __restrict bc = b + std::size_t(c) * ld;
    for (int k = 0; k < c; ++k) {
      const double f = l[std::size_t(k) * ld + std::size_t(c)];
      const double* __restrict bk = b + std::size_t(k) * ld;
      for (int r = 0; r < h; ++r) bc[r] -= f * bk[r];
    }
    const double inv = 1 / l[std::size_t(c) * ld + std::size_t(c)];
    for (int r = 0; r < h; ++r) bc[r] *= inv;
  }
}

// The panel's diagonal block (w <= kPanelCols, lower triangle) overwritten by its LL^T factor.
bool panel_llt(int w, double* a, std::size_t ld) {
  using Small = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kPanelCols, kPanelCols>;
  Panel m(a, w, w, Eigen::OuterStride<>(Eigen::Index(ld)));
  const Small d = m;
  const Eigen::LLT<Small> llt(d);
  if (llt.info() != Eigen::Success) return false;
  m.triangularView<Eigen::Lower>() = llt.matrixL();
  return true;
}

inline void subtract6(double* __restrict d, const double* __restrict u) {
  for (int r = 0; r < 6; ++r) d[r] -= u[r];
}

}  // namespace

// Exact minimum degree on the block graph, with dense bit rows: eliminating a node joins its
// remaining neighbours into a clique, and those neighbours are the rows of its column of L.
// Ties go to the lowest node, so the order (and the factor) is the same every run.
void BlockCholesky6::order(const Rows& rows, const std::vector<int>& dims) {
  const std::size_t n = rows.size();
  std::vector<std::int32_t> compact(n, -1), node;
  for (std::size_t i = 0; i < n; ++i)
    if (dims[i] > 0) {
      compact[i] = std::int32_t(node.size());
      node.push_back(std::int32_t(i));
    }
  const std::size_t m = node.size(), words = (m + 63) / 64;
  std::vector<std::uint64_t> adj(m * words, 0);
  auto row_of = [&](std::size_t c) { return adj.data() + c * words; };
  for (std::size_t i = 0; i < n; ++i) {
    if (compact[i] < 0) continue;
    for (const auto& [j, blk] : rows[i]) {
      if (std::size_t(j) >= i || compact[std::size_t(j)] < 0) continue;
      const std::size_t a = std::size_t(compact[i]), b = std::size_t(compact[std::size_t(j)]);
      row_of(a)[b / 64] |= std::uint64_t(1) << (b % 64);
      row_of(b)[a / 64] |= std::uint64_t(1) << (a % 64);
    }
  }
  std::vector<int> degree(m, 0);
  auto count = [&](std::size_t c) {
    int d = 0;
    for (std::size_t w = 0; w < words; ++w) d += std::popcount(row_of(c)[w]);
    return d;
  };
  for (std::size_t c = 0; c < m; ++c) degree[c] = count(c);
  std::vector<std::uint8_t> done(m, 0);
  std::vector<std::int32_t> position(m, -1);
  std::vector<std::vector<std::int32_t>> neighbours(m);  // per position, compact ids for now
  perm_.assign(m, -1);
  std::vector<std::int32_t> nb;
  for (std::size_t k = 0; k < m; ++k) {
    std::size_t best = m;
    for (std::size_t c = 0; c < m; ++c)
      if (!done[c] && (best == m || degree[c] < degree[best])) best = c;
    done[best] = 1;
    position[best] = std::int32_t(k);
    perm_[k] = node[best];
    nb.clear();
    const std::uint64_t* rb = row_of(best);
    for (std::size_t w = 0; w < words; ++w)
      for (std::uint64_t bits = rb[w]; bits; bits &= bits - 1)
        nb.push_back(std::int32_t(w * 64 + std::size_t(std::countr_zero(bits))));
    for (std::int32_t u : nb) {
      std::uint64_t* ru = row_of(std::size_t(u));
      for (std::size_t w = 0; w < words; ++w) ru[w] |= rb[w];
      ru[std::size_t(u) / 64] &= ~(std::uint64_t(1) << (std::size_t(u) % 64));
      ru[best / 64] &= ~(std::uint64_t(1) << (best % 64));
      degree[std::size_t(u)] = count(std::size_t(u));
    }
    neighbours[k] = nb;
  }
  where_.assign(n, -1);
  for (std::size_t k = 0; k < m; ++k) where_[std::size_t(perm_[k])] = std::int32_t(k);
  pattern_.assign(m, {});
  for (std::size_t k = 0; k < m; ++k) {
    for (std::int32_t c : neighbours[k]) pattern_[k].push_back(position[std::size_t(c)]);
    std::sort(pattern_[k].begin(), pattern_[k].end());
  }
}

// Fundamental supernodes of at most kPanelNodes positions: position k + 1 joins k's
// supernode when k's pattern below is k + 1 and then exactly k + 1's (a clique's columns).
void BlockCholesky6::supernodes_from_pattern() {
  const std::size_t m = perm_.size();
  first_.clear();
  of_.assign(m, -1);
  below_.clear();
  offset_.clear();
  std::size_t total = 0;
  for (std::size_t k = 0; k < m;) {
    std::size_t end = k + 1;
    while (end < m && end - k < std::size_t(kPanelNodes)) {
      const auto& a = pattern_[end - 1];
      const auto& b = pattern_[end];
      if (a.size() != b.size() + 1 || std::size_t(a[0]) != end || !std::equal(b.begin(), b.end(), a.begin() + 1)) break;
      ++end;
    }
    const auto s = std::int32_t(first_.size());
    first_.push_back(std::int32_t(k));
    for (std::size_t j = k; j < end; ++j) of_[j] = s;
    below_.push_back(pattern_[end - 1]);
    offset_.push_back(total);
    const std::size_t cols = 6 * (end - k), rows = cols + 6 * below_.back().size();
    total += rows * cols;
    k = end;
  }
  first_.push_back(std::int32_t(m));
  offset_.push_back(total);
  panels_.assign(total, 0.0);
}

bool BlockCholesky6::compute(const Rows& rows, const std::vector<int>& dims) {
  ok_ = false;
  nonzeros_ = 0;
  order(rows, dims);
  const std::size_t m = perm_.size();
  std::size_t nonzeros = 0;
  for (std::size_t k = 0; k < m; ++k) {
    const int dk = dims[std::size_t(perm_[k])];
    nonzeros += std::size_t(dk * (dk + 1) / 2);
    for (std::int32_t i : pattern_[k]) nonzeros += std::size_t(dk * dims[std::size_t(perm_[std::size_t(i)])]);
  }
  supernodes_from_pattern();
  const std::size_t ns = first_.size() - 1;
  auto cols_of = [&](std::size_t s) { return 6 * std::size_t(first_[s + 1] - first_[s]); };
  auto ld_of = [&](std::size_t s) { return cols_of(s) + 6 * below_[s].size(); };
  // The row (in blocks) of position p in supernode s's panel; p is in s or below it.
  auto row_in = [&](std::size_t s, std::int32_t p) {
    if (p < first_[s + 1]) return std::size_t(p - first_[s]);
    const auto& b = below_[s];
    return std::size_t(first_[s + 1] - first_[s]) + std::size_t(std::lower_bound(b.begin(), b.end(), p) - b.begin());
  };
  auto block_at = [&](std::size_t s, std::size_t row_block, std::size_t col_block) {
    return Panel(panels_.data() + offset_[s] + 6 * col_block * ld_of(s) + 6 * row_block, 6, 6,
                 Eigen::OuterStride<>(Eigen::Index(ld_of(s))));
  };
  double dmax = 0;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const int di = dims[i];
    if (di <= 0) continue;
    const auto pi = where_[i];
    for (const auto& [j, blk] : rows[i]) {
      if (std::size_t(j) > i) continue;
      const int dj = dims[std::size_t(j)];
      if (dj <= 0) continue;
      Block a = Block::Zero();  // only the unknowns the nodes have
      a.topLeftCorner(di, dj) = blk.topLeftCorner(di, dj);
      const auto pj = where_[std::size_t(j)];
      if (pj == pi) {
        auto d = block_at(std::size_t(of_[std::size_t(pi)]), std::size_t(pi - first_[std::size_t(of_[std::size_t(pi)])]),
                          std::size_t(pi - first_[std::size_t(of_[std::size_t(pi)])]));
        for (int p = 0; p < di; ++p)
          for (int q = 0; q <= p; ++q) d(p, q) += a(p, q);
      } else {
        const auto lo = std::min(pi, pj), hi = std::max(pi, pj);
        const auto s = std::size_t(of_[std::size_t(lo)]);
        auto d = block_at(s, row_in(s, hi), std::size_t(lo - first_[s]));
        if (pi > pj) d += a;
        else d += a.transpose();
      }
    }
  }
  for (std::size_t k = 0; k < m; ++k) {
    const auto s = std::size_t(of_[k]);
    auto d = block_at(s, k - std::size_t(first_[s]), k - std::size_t(first_[s]));
    const int dk = dims[std::size_t(perm_[k])];
    for (int p = 0; p < dk; ++p) dmax = std::max(dmax, d(p, p));
    for (int p = dk; p < 6; ++p) d(p, p) = 1;
  }
  if (!(dmax > 0) || !std::isfinite(dmax)) return false;
  const double floor = 1e-12 * dmax;
  std::vector<double>& update = update_;
  std::vector<std::size_t> to;  // per row block below the panel: its row block in the target panel
  for (std::size_t s = 0; s < ns; ++s) {
    const int w = int(cols_of(s)), ld = int(ld_of(s)), h = ld - w;
    double* panel = panels_.data() + offset_[s];
    if (!panel_llt(w, panel, std::size_t(ld))) return false;
    for (std::int32_t k = first_[s]; k < first_[s + 1]; ++k) {
      const int dk = dims[std::size_t(perm_[std::size_t(k)])], c = 6 * (k - first_[s]);
      for (int p = 0; p < dk; ++p) {
        const double l = panel[std::size_t(c + p) * std::size_t(ld) + std::size_t(c + p)];
        if (!(l * l > floor)) return false;
      }
    }
    if (h == 0) continue;
    solve_right_lt(h, w, panel, std::size_t(ld), panel + w);
    update.resize(std::size_t(h) * std::size_t(h));
    lower_gram(h, w, panel + w, std::size_t(ld), update.data());
    // Scatter: the update's block (a, b), a >= b, goes to the panel holding below_[s][b]'s
    // column, at the row of below_[s][a] there (to[a]; only a node diagonal block's lower
    // triangle).
    const auto& bl = below_[s];
    const std::size_t nb = bl.size();
    to.resize(nb);
    std::int32_t target = -1;
    for (std::size_t b = 0; b < nb; ++b) {
      const auto t = of_[std::size_t(bl[b])];
      const auto ts = std::size_t(t);
      if (t != target) {
        target = t;
        const std::size_t own = std::size_t(first_[ts + 1] - first_[ts]);
        for (std::size_t a = b; a < nb; ++a) {
          const std::int32_t p = bl[a];
          to[a] = p < first_[ts + 1] ? std::size_t(p - first_[ts])
                                     : own + std::size_t(std::lower_bound(below_[ts].begin(), below_[ts].end(), p) -
                                                         below_[ts].begin());
        }
      }
      const std::size_t ldt = ld_of(ts), col = std::size_t(bl[b] - first_[ts]);
      for (std::size_t c = 0; c < 6; ++c) {
        double* dst = panels_.data() + offset_[ts] + (6 * col + c) * ldt;
        const double* src = update.data() + (6 * b + c) * std::size_t(h);
        for (std::size_t r = c; r < 6; ++r) dst[6 * to[b] + r] -= src[6 * b + r];
        for (std::size_t a = b + 1; a < nb; ++a) subtract6(dst + 6 * to[a], src + 6 * a);
      }
    }
  }
  // The solve reads L by columns of contiguous 6x6 blocks (the panels' strided blocks made
  // every solve, one per CG iteration, slower than the copy costs once).
  start_.assign(m + 1, 0);
  for (std::size_t k = 0; k < m; ++k) start_[k + 1] = start_[k] + 1 + pattern_[k].size();
  blocks_.resize(start_[m]);
  for (std::size_t k = 0; k < m; ++k) {
    const auto s = std::size_t(of_[k]);
    const std::size_t c = k - std::size_t(first_[s]), own = std::size_t(first_[s + 1] - first_[s]);
    Block* l = blocks_.data() + start_[k];
    l[0] = block_at(s, c, c);
    l[0].triangularView<Eigen::StrictlyUpper>().setZero();
    for (std::size_t r = c + 1; r < own; ++r) l[r - c] = block_at(s, r, c);
    for (std::size_t r = 0; r < below_[s].size(); ++r) l[own - c + r] = block_at(s, own + r, c);
  }
  nonzeros_ = nonzeros;
  ok_ = true;
  return true;
}

void BlockCholesky6::solve_in_place(std::vector<Vec>& x) const {
  for (std::size_t i = 0; i < x.size(); ++i)
    if (i >= where_.size() || where_[i] < 0) x[i].setZero();
  const std::size_t m = perm_.size();
  for (std::size_t k = 0; k < m; ++k) {  // L y = x
    Vec& xk = x[std::size_t(perm_[k])];
    const Block* l = blocks_.data() + start_[k];
    l[0].triangularView<Eigen::Lower>().solveInPlace(xk);
    for (std::size_t s = 0; s < pattern_[k].size(); ++s)
      x[std::size_t(perm_[std::size_t(pattern_[k][s])])].noalias() -= l[s + 1] * xk;
  }
  for (std::size_t k = m; k-- > 0;) {  // L^T z = y
    Vec& xk = x[std::size_t(perm_[k])];
    const Block* l = blocks_.data() + start_[k];
    for (std::size_t s = 0; s < pattern_[k].size(); ++s)
      xk.noalias() -= l[s + 1].transpose() * x[std::size_t(perm_[std::size_t(pattern_[k][s])])];
    l[0].triangularView<Eigen::Lower>().transpose().solveInPlace(xk);
  }
}

}  // namespace incise
