#pragma once
// Preconditioners for ConjugateGradient: z = M^-1 r on the free unknowns, z = 0 on kept ones.
// M must be symmetric positive definite on the free unknowns and must not change during a
// solve; CG calls setup() at every fresh start (never when it resumes), and restarts when
// version() changes (an asynchronous factor was adopted).
//
// Jacobi and BlockJacobi read the operator's diagonal / 3x3 vertex blocks, which the FEM model
// keeps current locally from each TopologyChange, so they survive cuts at no extra cost.
// Cholesky is the asynchronous sparse factorization of sim/fem/async_cholesky.h and Amg the
// aggregation multigrid of sim/fem/aggregation_amg.h; both need the FEM model, so the FEM frame
// driver attaches them to CG (on its own, CG treats either as BlockJacobi).
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "sim/linalg/linear_operator.h"

namespace incise {

enum class Preconditioner { None, Jacobi, BlockJacobi, Cholesky, Amg };
const char* to_string(Preconditioner p);
// "none", "jacobi", "block-jacobi", "cholesky", "amg"; throws InvalidArgument on anything else.
Preconditioner parse_preconditioner(const std::string& name);

class CgPreconditioner {
public:
  virtual ~CgPreconditioner() = default;
  // Binds the operator and the free mask (nullptr: all free) for the solves that follow.
  virtual void setup(const LinearOperator& a, const std::vector<std::uint8_t>* free) = 0;
  virtual void apply(const Eigen::VectorXd& r, Eigen::VectorXd& z) const = 0;
  virtual std::uint64_t version() const { return 0; }
  // A cheaper preconditioner CG uses instead for a solve whose wall-clock budget cannot
  // afford one application of this one (nullptr: none). It must stay valid as long as this.
  virtual CgPreconditioner* cheaper() { return nullptr; }
  // What the next setup() is expected to cost (ms), when the preconditioner knows better than
  // CG's running average of past setups (a multigrid whose setup is a patch after a cut and
  // almost nothing otherwise); negative: no idea, CG uses its average.
  virtual double next_setup_ms() const { return -1; }
};

// None, Jacobi or BlockJacobi (Cholesky and Amg give BlockJacobi, see above).
std::unique_ptr<CgPreconditioner> make_preconditioner(Preconditioner kind);

// Inverse 3x3 vertex blocks with a per-unknown diagonal fallback (vertices with only some
// unknowns free, singular blocks, operators without blocks). Also the fallback of the
// Cholesky preconditioner for unknowns its factor does not cover.
class BlockJacobi : public CgPreconditioner {
public:
  void setup(const LinearOperator& a, const std::vector<std::uint8_t>* free) override;
  void apply(const Eigen::VectorXd& r, Eigen::VectorXd& z) const override;
  // z on the unknowns of vertex v only (v's block or diagonal fallback).
  void apply_vertex(std::size_t v, const Eigen::VectorXd& r, Eigen::VectorXd& z) const;

private:
  std::vector<Eigen::Matrix3d> inv_;  // per vertex; zero rows/columns for kept unknowns
};

}  // namespace incise
