#pragma once
// The one interface the iterative solver sees: y = A x and diag(A), for a symmetric operator
// over 3 * vertex_capacity() unknowns. The matrix-free FEM model, the assembled matrix and the
// dynamic system (a M + c K) all implement it, so every solver runs on every backend.
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
};

}  // namespace incise
