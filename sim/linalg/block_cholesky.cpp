#include "sim/linalg/block_cholesky.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>

#include <Eigen/Cholesky>

namespace incise {

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

bool BlockCholesky6::compute(const Rows& rows, const std::vector<int>& dims) {
  ok_ = false;
  nonzeros_ = 0;
  order(rows, dims);
  const std::size_t m = perm_.size();
  diag_.assign(m, Block::Zero());
  below_.resize(m);
  for (std::size_t k = 0; k < m; ++k) below_[k].assign(pattern_[k].size(), Block::Zero());
  auto slot = [&](std::size_t col, std::int32_t row) {
    const auto& p = pattern_[col];
    return std::size_t(std::lower_bound(p.begin(), p.end(), row) - p.begin());
  };
  double dmax = 0;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const int di = dims[i];
    if (di <= 0) continue;
    const std::size_t pi = std::size_t(where_[i]);
    for (const auto& [j, blk] : rows[i]) {
      if (std::size_t(j) > i) continue;
      const int dj = dims[std::size_t(j)];
      if (dj <= 0) continue;
      Block a = Block::Zero();  // only the unknowns the nodes have
      a.topLeftCorner(di, dj) = blk.topLeftCorner(di, dj);
      const std::size_t pj = std::size_t(where_[std::size_t(j)]);
      if (pj == pi) {
        for (int p = 0; p < di; ++p)
          for (int q = 0; q <= p; ++q) diag_[pi](p, q) += a(p, q);
      } else if (pi > pj) {
        below_[pj][slot(pj, std::int32_t(pi))] += a;
      } else {
        below_[pi][slot(pi, std::int32_t(pj))] += a.transpose();
      }
    }
    for (int p = 0; p < di; ++p) dmax = std::max(dmax, diag_[pi](p, p));
  }
  for (std::size_t k = 0; k < m; ++k)
    for (int p = dims[std::size_t(perm_[k])]; p < 6; ++p) diag_[k](p, p) = 1;
  if (!(dmax > 0) || !std::isfinite(dmax)) return false;
  const double floor = 1e-12 * dmax;
  for (std::size_t k = 0; k < m; ++k) {
    const int dk = dims[std::size_t(perm_[k])];
    Eigen::LLT<Block> llt(diag_[k]);  // reads the lower triangle
    if (llt.info() != Eigen::Success) return false;
    Block l = llt.matrixL();
    for (int p = 0; p < dk; ++p)
      if (!(l(p, p) * l(p, p) > floor)) return false;
    diag_[k] = l;
    const auto& pk = pattern_[k];
    auto& bk = below_[k];
    for (Block& b : bk) l.triangularView<Eigen::Lower>().transpose().solveInPlace<Eigen::OnTheRight>(b);
    // The Schur complement update of the columns below: W_ij -= L_ik L_jk^T for i >= j in
    // pattern(k); pattern(j) holds every later row of pattern(k) (they formed a clique).
    for (std::size_t a = 0; a < pk.size(); ++a) {
      const std::size_t j = std::size_t(pk[a]);
      diag_[j].noalias() -= bk[a] * bk[a].transpose();
      const auto& pj = pattern_[j];
      std::size_t s = 0;
      for (std::size_t b = a + 1; b < pk.size(); ++b) {
        while (pj[s] != pk[b]) ++s;
        below_[j][s].noalias() -= bk[b] * bk[a].transpose();
      }
    }
    nonzeros_ += std::size_t(dk * (dk + 1) / 2);
    for (std::int32_t i : pk) nonzeros_ += std::size_t(dk * dims[std::size_t(perm_[std::size_t(i)])]);
  }
  ok_ = true;
  return true;
}

void BlockCholesky6::solve_in_place(std::vector<Vec>& x) const {
  for (std::size_t i = 0; i < x.size(); ++i)
    if (i >= where_.size() || where_[i] < 0) x[i].setZero();
  const std::size_t m = perm_.size();
  for (std::size_t k = 0; k < m; ++k) {  // L y = x
    Vec& xk = x[std::size_t(perm_[k])];
    diag_[k].triangularView<Eigen::Lower>().solveInPlace(xk);
    for (std::size_t s = 0; s < pattern_[k].size(); ++s)
      x[std::size_t(perm_[std::size_t(pattern_[k][s])])].noalias() -= below_[k][s] * xk;
  }
  for (std::size_t k = m; k-- > 0;) {  // L^T z = y
    Vec& xk = x[std::size_t(perm_[k])];
    for (std::size_t s = 0; s < pattern_[k].size(); ++s)
      xk.noalias() -= below_[k][s].transpose() * x[std::size_t(perm_[std::size_t(pattern_[k][s])])];
    diag_[k].triangularView<Eigen::Lower>().transpose().solveInPlace(xk);
  }
}

}  // namespace incise
