#pragma once
// Sparse Cholesky factorization L L^T of a symmetric positive definite matrix made of 6x6
// blocks: the multigrid's coarse matrix (sim/fem/aggregation_amg.h), one block row per aggregate
// (its rigid-body modes), a few hundred blocks, refactored at every cut step.
//
// Why not CHOLMOD: on the organ's coarse matrix its simplicial LL^T with the AMD ordering and
// the triplet assembly took a sixth of a cut frame (docs/solver.md, "The coarse factor"); this
// one works on the block graph (a node per aggregate, not one per unknown), orders it by exact
// minimum degree (the graph is small enough for dense bit rows) and gets L's pattern from that
// same elimination (bench_fem_precond --only amg-build prints both).
//
// The numeric work is supernodal and right-looking: up to four consecutive positions whose
// columns of L share one pattern below (the cliques minimum degree eliminates) form a dense
// panel; its update to the later columns, B B^T for its rows below, is one dense product
// (register-tiled, AVX2 where the CPU has it) scattered into their panels. Most of the flops
// are there (docs/solver.md, "The coarse factor in panels").
//
// Blocks with fewer than 6 unknowns (an aggregate whose modes were dropped) carry zeros in
// their unused rows and columns; their unused diagonal entries are taken as 1, so those
// unknowns decouple and solve to 0.
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include <Eigen/Core>

namespace incise {

class BlockCholesky6 {
public:
  using Block = Eigen::Matrix<double, 6, 6>;
  using Vec = Eigen::Matrix<double, 6, 1>;
  // One block row per node: (column node, block). Only blocks with column <= row are read
  // (the lower triangle; the diagonal block's upper triangle is ignored); dims[i] in 0..6 is
  // the number of unknowns of node i, and a node with 0 has no row or column.
  using Rows = std::vector<std::vector<std::pair<std::int32_t, Block>>>;

  // False when a pivot is not positive, or below 1e-12 of the largest diagonal entry (the
  // matrix is not SPD, or numerically singular); the factor is unusable then.
  bool compute(const Rows& rows, const std::vector<int>& dims);
  bool ok() const { return ok_; }
  // x: one 6-vector per node, overwritten with A^-1 x (entries beyond a node's dims are 0).
  void solve_in_place(std::vector<Vec>& x) const;
  std::size_t nonzeros() const { return nonzeros_; }  // scalar entries of L, lower triangle
  std::size_t supernodes() const { return first_.empty() ? 0 : first_.size() - 1; }

private:
  void order(const Rows& rows, const std::vector<int>& dims);  // perm_, pattern_
  void supernodes_from_pattern();                               // first_, of_, below_, panel offsets

  bool ok_ = false;
  std::size_t nonzeros_ = 0;
  std::vector<std::int32_t> perm_;                  // elimination position -> node
  std::vector<std::int32_t> where_;                 // node -> position (-1: no unknowns)
  std::vector<std::vector<std::int32_t>> pattern_;  // per position: rows below (positions, ascending)
  // Supernode s holds the positions first_[s] .. first_[s + 1) - 1; of_[k] is k's supernode.
  // Its panel is column-major, 6 x (its positions + below) rows by 6 x (its positions)
  // columns: L's diagonal block (lower triangle) over the rows below_[s] (positions, ascending).
  std::vector<std::int32_t> first_, of_;
  std::vector<std::vector<std::int32_t>> below_;
  std::vector<std::size_t> offset_;  // per supernode: its panel's first entry in panels_
  std::vector<double> panels_;
  std::vector<double> update_;  // scratch: a panel's update before its scatter
  // L again for the solve: per position k, L_kk then L_ik for i in pattern_[k], from start_[k].
  std::vector<Block> blocks_;
  std::vector<std::size_t> start_;
};

}  // namespace incise
