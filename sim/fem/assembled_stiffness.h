#pragma once
// The assembled baseline: K (or K_R) stored as an Eigen sparse matrix, with the same
// LinearOperator interface as the matrix-free FemModel, and a direct solver (Eigen
// SimplicialLDLT) on the free unknowns that serves as the exact reference.
// Both rebuild from scratch (O(mesh)); that is what the local updates are measured against.
#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/SparseCore>

#include "sim/fem/fem_model.h"

namespace incise {

class AssembledStiffness : public LinearOperator {
public:
  explicit AssembledStiffness(const FemModel& model) : model_(&model) { rebuild(); }
  // Reassembles K and its diagonal from the model (after apply() or update_rotations()).
  void rebuild();
  const Eigen::SparseMatrix<double>& matrix() const { return k_; }

  Eigen::Index rows() const override { return k_.rows(); }
  // Parallel CSR product (K is symmetric, so its column-major storage reads as CSR).
  void multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const override;
  const Eigen::VectorXd& diagonal() const override { return diag_; }
  const std::vector<Eigen::Matrix3d>& diagonal_blocks() const override { return model_->diagonal_blocks(); }

private:
  const FemModel* model_;
  Eigen::SparseMatrix<double> k_;
  Eigen::VectorXd diag_;
};

// Solves A x = b on free unknowns with kept unknowns at the values x holds (prescribed values
// enter the right-hand side), by sparse LDL^T. A is symmetric of size free.size().
class DirectSolver {
public:
  // `supernodal`: CHOLMOD's supernodal LL^T where the build has CHOLMOD (factors with much fill,
  // as quadratic tets': docs/solver.md#quadratic-tets), else the same LDL^T.
  explicit DirectSolver(bool supernodal = false);
  ~DirectSolver();
  // Factorizes the free-free block; throws Error naming the problem if A is singular there
  // (e.g. too few fixed nodes). O(fill-in).
  void compute(const Eigen::SparseMatrix<double>& a, const std::vector<std::uint8_t>& free);
  // x: kept unknowns hold their values on input; free unknowns are overwritten.
  void solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) const;
  double factorize_ms() const { return factorize_ms_; }

private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  double factorize_ms_ = 0;
};

}  // namespace incise
