#pragma once
// Preconditioned Conjugate Gradient with its own loop, so that it can stop on a wall-clock
// budget and resume next frame from where it stopped (warm start).
//
// Constraints by projection: `free` marks the unknowns CG may change (1) and those it must
// keep (0: fixed or prescribed). The value of a kept unknown is whatever the guess holds there,
// so prescribed values enter through the right-hand side: CG solves
//   P A P x_f = P (b - A x_kept)   with P the projection onto free unknowns.
// Convergence: ||P (b - A x)|| <= tolerance * ||P (b - A x_kept)||  (relative to the effective
// right-hand side, so it does not depend on the guess).
// Breakdown: p^T A p <= 0 (not positive definite) and NaN/Inf stop the loop with a message.
// Vocabulary after Eigen: compute, solve, solve_with_guess, info, iterations, error.
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "sim/linear_operator.h"

namespace incise {

enum class SolveInfo {
  Success,              // relative residual <= tolerance
  NoConvergence,        // iteration cap reached first
  BudgetExhausted,      // wall-clock budget reached first; x is the best iterate so far
  NotPositiveDefinite,  // p^T A p <= 0: missing constraints, inverted material, bad operator
  NumericalIssue,       // NaN or Inf in the iterates
};
const char* to_string(SolveInfo info);

struct SolveStats {
  int iterations = 0;              // CG iterations (one K x each)
  double relative_residual = 0;    // ||r|| / ||b_eff|| at exit
  double solve_ms = 0;             // wall time of the solve
  bool budget_exhausted = false;   // the budget stopped it
  SolveInfo info = SolveInfo::Success;
  std::string message;             // empty on success; one line otherwise
  bool converged() const { return info == SolveInfo::Success; }
};

enum class Preconditioner { None, Jacobi };

struct CgOptions {
  double tolerance = 1e-8;                          // relative residual target
  int max_iterations = 10000;                       // cap per solve
  double budget_ms = 0;                             // wall-clock budget per solve; 0 = none
  Preconditioner preconditioner = Preconditioner::Jacobi;  // Jacobi: diag(A) of free unknowns
};

class ConjugateGradient {
public:
  ConjugateGradient() = default;
  explicit ConjugateGradient(const CgOptions& o) : opt_(o) {}

  void set_tolerance(double t);
  void set_max_iterations(int n);
  void set_budget_ms(double ms);
  void set_preconditioner(Preconditioner p) { opt_.preconditioner = p; }
  const CgOptions& options() const { return opt_; }

  // Binds the operator and the free mask (3 * vertex entries, 1 = free). Both must outlive
  // the solves; the operator's diagonal is read at each solve, so local updates of the
  // operator need no new compute(). An empty mask means every unknown is free.
  void compute(const LinearOperator& A, const std::vector<std::uint8_t>* free = nullptr);

  // x = 0 on free unknowns (kept unknowns are 0 too).
  Eigen::VectorXd solve(const Eigen::VectorXd& b);
  // Starts from x (kept unknowns hold their prescribed values) and overwrites it.
  void solve_with_guess(const Eigen::VectorXd& b, Eigen::VectorXd& x);

  SolveInfo info() const { return stats_.info; }
  int iterations() const { return stats_.iterations; }
  double error() const { return stats_.relative_residual; }
  const SolveStats& stats() const { return stats_; }

private:
  void project(Eigen::VectorXd& v) const;

  CgOptions opt_;
  const LinearOperator* A_ = nullptr;
  const std::vector<std::uint8_t>* free_ = nullptr;
  SolveStats stats_;
  Eigen::VectorXd r_, z_, p_, q_, inv_diag_;  // kept between solves to avoid reallocation
};

}  // namespace incise
