#pragma once
// The one interface the iterative solver sees: y = A x and diag(A), for a symmetric operator
// over 3 * vertex_capacity() unknowns. The matrix-free FEM model, the assembled matrix and the
// dynamic system (a M + c K) all implement it, so every solver runs on every backend.
#include <vector>

#include <Eigen/Core>

namespace incise {

class LinearOperator {
public:
  virtual ~LinearOperator() = default;
  virtual Eigen::Index rows() const = 0;
  // y = A x; y is resized to rows().
  virtual void multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const = 0;
  // diag(A), rows() entries; used by the Jacobi preconditioner. Kept current by the operator.
  virtual const Eigen::VectorXd& diagonal() const = 0;
  // The 3x3 diagonal block of each vertex (rows 3v..3v+2), for block-Jacobi; empty when the
  // operator has no vertex structure (block-Jacobi then falls back to the diagonal).
  virtual const std::vector<Eigen::Matrix3d>& diagonal_blocks() const {
    static const std::vector<Eigen::Matrix3d> none;
    return none;
  }
};

}  // namespace incise
