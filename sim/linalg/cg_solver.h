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
//
// Cost of a fresh start: one product A x_free (none when the guess is zero on free unknowns),
// plus A x_kept only when the kept values changed since the last solve on this operator, plus
// A d_i per prediction direction d_i given. Resume: a solve stopped by the budget or the
// iteration cap continues its own iteration (no product, same iterates as one uninterrupted
// solve) when called again with the same right-hand side and the x it returned, on the same
// operator (no compute()/invalidate() since) and the same preconditioner version.
//
// Budget: a solve with budget_ms > 0 plans with the measured cost of a product and of a
// preconditioner application (running averages; the preconditioner's next_setup_ms() when it
// gives one). It skips the prediction when its products
// would take more than half of the budget, preconditions with pc->cheaper() when one setup and
// application of the preconditioner plus a product do not fit and the cheaper one is cheaper by
// half again (stats: cheaper_preconditioner),
// and stops before an iteration that would end past the budget. At least one iteration runs,
// so a budgeted solve ends within about one cheap iteration of its budget and still progresses.
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "sim/linalg/linear_operator.h"
#include "sim/linalg/preconditioner.h"

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
  int products = 0;                // all K x of the solve: iterations + start (guess, kept, prediction)
  double relative_residual = 0;    // ||r|| / ||b_eff|| at exit
  double initial_relative_residual = 0;  // at the start point actually used (after prediction)
  double guess_relative_residual = 0;    // at the guess as given (before prediction)
  double prediction_weight = 0;    // alpha_1 of x = guess + sum alpha_i d_i (0: prediction not used)
  double solve_ms = 0;             // wall time of the solve
  double preconditioner_setup_ms = 0;  // of it, the preconditioner's setup (a multigrid rebuild shows here)
  bool budget_exhausted = false;   // the budget stopped it
  bool resumed = false;            // continued the previous interrupted solve
  // The budget left could not afford one application of the preconditioner: the solve used
  // its cheaper() one (a resumed solve keeps the one it started with).
  bool cheaper_preconditioner = false;
  SolveInfo info = SolveInfo::Success;
  std::string message;             // empty on success; one line otherwise
  bool converged() const { return info == SolveInfo::Success; }
};

// alpha_j = r_j.z_j / p_j.A p_j and beta_j = r_{j+1}.z_{j+1} / r_j.z_j of each iteration j.
struct CgCoefficients {
  std::vector<double> alpha, beta;
};

struct CgOptions {
  double tolerance = 1e-8;                          // relative residual target
  int max_iterations = 10000;                       // cap per solve
  double budget_ms = 0;                             // wall-clock budget per solve; 0 = none
  Preconditioner preconditioner = Preconditioner::Jacobi;  // see sim/linalg/preconditioner.h; FemSimulation: Cholesky
};

class ConjugateGradient {
public:
  ConjugateGradient() : ConjugateGradient(CgOptions{}) {}
  explicit ConjugateGradient(const CgOptions& o);

  void set_tolerance(double t);
  void set_max_iterations(int n);
  void set_budget_ms(double ms);
  void set_preconditioner(Preconditioner p);
  // Uses `pc` (not owned, must outlive the solves) instead of the built-in one; nullptr
  // returns to the built-in one.
  void set_preconditioner(CgPreconditioner* pc);
  const CgOptions& options() const { return opt_; }

  // Binds the operator and the free mask (3 * vertex entries, 1 = free). Both must outlive
  // the solves. The preconditioner reads the operator at each fresh start, so local updates of
  // the operator need no new compute(), but they need invalidate() (or compute()) to stop a
  // resume. An empty mask means every unknown is free.
  void compute(const LinearOperator& A, const std::vector<std::uint8_t>* free = nullptr);
  // The operator or the mask changed in place: no resume, no cached A x_kept.
  void invalidate();

  // x = 0 on free unknowns (kept unknowns are 0 too).
  Eigen::VectorXd solve(const Eigen::VectorXd& b);
  // Starts from x (kept unknowns hold their prescribed values) and overwrites it. With
  // prediction directions d_i (their kept entries are ignored), starts from x + sum alpha_i d_i
  // with the alphas of the Galerkin projection onto their span (least A-norm error, CG's own
  // criterion), or of least initial residual when the Galerkin start's residual is not below
  // x's; a prediction never starts with a larger residual than x itself. One product per d_i.
  void solve_with_guess(const Eigen::VectorXd& b, Eigen::VectorXd& x, std::span<const Eigen::VectorXd> d = {});
  // Whether solve_with_guess(b, x) would resume the previous solve.
  bool can_resume(const Eigen::VectorXd& b, const Eigen::VectorXd& x) const;

  // Records each iteration's alpha and beta into `log` (not owned; nullptr stops recording):
  // the Lanczos tridiagonal matrix of the solve, hence estimates of the extreme eigenvalues
  // of M^-1 A, come from them (sim/fem/cg_spectrum.h). A fresh start clears the log, a resume
  // appends to it. Two pushes per iteration, nothing else.
  void set_coefficient_log(CgCoefficients* log) { log_ = log; }

  SolveInfo info() const { return stats_.info; }
  int iterations() const { return stats_.iterations; }
  double error() const { return stats_.relative_residual; }
  const SolveStats& stats() const { return stats_; }

private:
  void project(Eigen::VectorXd& v) const;
  bool start(const Eigen::VectorXd& b, Eigen::VectorXd& x, std::span<const Eigen::VectorXd> d, double t0_ms);  // false: done
  void predict(Eigen::VectorXd& x, std::span<const Eigen::VectorXd> d);
  void iterate(Eigen::VectorXd& x, double t0_ms);
  void multiply(const Eigen::VectorXd& v, Eigen::VectorXd& out);    // A v, timed
  void precondition(const Eigen::VectorXd& r, Eigen::VectorXd& z);  // z = M^-1 r with active_, timed

  CgOptions opt_;
  const LinearOperator* A_ = nullptr;
  const std::vector<std::uint8_t>* free_ = nullptr;
  std::unique_ptr<CgPreconditioner> builtin_;
  CgPreconditioner* pc_ = nullptr;  // builtin_ or the attached one
  CgPreconditioner* active_ = nullptr;  // of the current solve: pc_ or pc_->cheaper()
  // Measured costs (running averages, ms) that let a budgeted solve plan its next step: one
  // product, one setup and one application of pc_ and of its cheaper one.
  double kx_ms_ = 0, pc_apply_ms_ = 0, pc_setup_ms_ = 0, cheap_apply_ms_ = 0, cheap_setup_ms_ = 0;
  CgCoefficients* log_ = nullptr;
  SolveStats stats_;
  Eigen::VectorXd r_, z_, p_, q_;  // kept between solves: resume state and no reallocation
  std::vector<Eigen::VectorXd> pd_, qd_;  // projected prediction directions and A times them
  double rz_ = 0, bnorm_ = 0;
  // Resume: the problem the interrupted solve was on.
  bool resumable_ = false;
  std::uint64_t pc_version_ = 0;
  Eigen::VectorXd b_last_, x_last_;
  // P A x_kept for the kept values of the last fresh start on this operator.
  bool akept_valid_ = false;
  Eigen::VectorXd kept_last_, akept_;
};

}  // namespace incise
