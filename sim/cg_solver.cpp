#include "sim/cg_solver.h"

#include <chrono>
#include <cmath>
#include <sstream>

#include "mesh/errors.h"

namespace incise {

const char* to_string(SolveInfo info) {
  switch (info) {
    case SolveInfo::Success: return "converged";
    case SolveInfo::NoConvergence: return "iteration cap reached";
    case SolveInfo::BudgetExhausted: return "budget exhausted";
    case SolveInfo::NotPositiveDefinite: return "not positive definite";
    case SolveInfo::NumericalIssue: return "numerical issue (NaN/Inf)";
  }
  return "?";
}

void ConjugateGradient::set_tolerance(double t) {
  if (!(t > 0) || !std::isfinite(t)) throw InvalidArgument("cg tolerance: expected a positive number");
  opt_.tolerance = t;
}
void ConjugateGradient::set_max_iterations(int n) {
  if (n < 1) throw InvalidArgument("cg max_iterations: expected an integer >= 1");
  opt_.max_iterations = n;
}
void ConjugateGradient::set_budget_ms(double ms) {
  if (!(ms >= 0) || !std::isfinite(ms)) throw InvalidArgument("cg budget_ms: expected a number >= 0");
  opt_.budget_ms = ms;
}

void ConjugateGradient::compute(const LinearOperator& A, const std::vector<std::uint8_t>* free) {
  A_ = &A;
  free_ = (free && !free->empty()) ? free : nullptr;
  if (free_ && Eigen::Index(free_->size()) != A.rows())
    throw InvalidArgument("cg: free mask has " + std::to_string(free_->size()) + " entries, operator " +
                          std::to_string(A.rows()) + " rows");
}

void ConjugateGradient::project(Eigen::VectorXd& v) const {
  if (!free_) return;
  const auto& f = *free_;
  for (Eigen::Index i = 0; i < v.size(); ++i)
    if (!f[i]) v[i] = 0;
}

Eigen::VectorXd ConjugateGradient::solve(const Eigen::VectorXd& b) {
  Eigen::VectorXd x = Eigen::VectorXd::Zero(b.size());
  solve_with_guess(b, x);
  return x;
}

void ConjugateGradient::solve_with_guess(const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  using clock = std::chrono::steady_clock;
  const auto t0 = clock::now();
  auto elapsed_ms = [&] { return std::chrono::duration<double, std::milli>(clock::now() - t0).count(); };
  if (!A_) throw Error("cg: solve before compute()");
  const Eigen::Index n = A_->rows();
  if (b.size() != n || x.size() != n)
    throw InvalidArgument("cg: right-hand side / guess size does not match the operator");
  stats_ = SolveStats{};

  // Effective right-hand side norm: P (b - A x_kept). When the guess is zero on free unknowns
  // it equals the initial residual and costs nothing extra.
  bool guess_free_zero = true;
  if (free_) {
    for (Eigen::Index i = 0; i < n && guess_free_zero; ++i)
      if ((*free_)[i] && x[i] != 0) guess_free_zero = false;
  } else {
    guess_free_zero = x.isZero(0);
  }
  A_->multiply(x, q_);
  r_ = b - q_;
  project(r_);
  double bnorm;
  if (guess_free_zero) {
    bnorm = r_.norm();
  } else {
    z_ = x;
    if (free_) {
      for (Eigen::Index i = 0; i < n; ++i)
        if ((*free_)[i]) z_[i] = 0;
    } else {
      z_.setZero();
    }
    A_->multiply(z_, q_);
    q_ = b - q_;
    project(q_);
    bnorm = q_.norm();
  }
  if (!std::isfinite(bnorm) || !std::isfinite(r_.squaredNorm())) {
    stats_.info = SolveInfo::NumericalIssue;
    stats_.relative_residual = std::numeric_limits<double>::quiet_NaN();
    stats_.message = "cg: the right-hand side or the initial guess contains NaN/Inf";
    stats_.solve_ms = elapsed_ms();
    return;
  }
  if (bnorm == 0) {  // the solution is zero on free unknowns
    if (free_) {
      for (Eigen::Index i = 0; i < n; ++i)
        if ((*free_)[i]) x[i] = 0;
    } else {
      x.setZero();
    }
    stats_.solve_ms = elapsed_ms();
    return;
  }

  const bool jacobi = opt_.preconditioner == Preconditioner::Jacobi;
  if (jacobi) {
    const Eigen::VectorXd& d = A_->diagonal();
    inv_diag_.resize(n);
    for (Eigen::Index i = 0; i < n; ++i) {
      const bool f = !free_ || (*free_)[i];
      inv_diag_[i] = (f && d[i] > 0) ? 1.0 / d[i] : (f ? 1.0 : 0.0);
    }
  }
  auto precondition = [&] {
    if (jacobi) z_ = inv_diag_.cwiseProduct(r_);
    else z_ = r_;
  };

  const double target = opt_.tolerance * bnorm;
  double rnorm = r_.norm();
  precondition();
  p_ = z_;
  double rz = r_.dot(z_);
  int k = 0;
  for (;;) {
    stats_.relative_residual = rnorm / bnorm;
    if (rnorm <= target) {
      stats_.info = SolveInfo::Success;
      break;
    }
    if (k >= opt_.max_iterations) {
      stats_.info = SolveInfo::NoConvergence;
      std::ostringstream m;
      m << "cg: not converged after " << k << " iterations (relative residual " << stats_.relative_residual
        << ", tolerance " << opt_.tolerance << ")";
      stats_.message = m.str();
      break;
    }
    if (k > 0 && opt_.budget_ms > 0 && elapsed_ms() >= opt_.budget_ms) {
      stats_.info = SolveInfo::BudgetExhausted;
      stats_.budget_exhausted = true;
      break;
    }
    A_->multiply(p_, q_);
    project(q_);
    const double pq = p_.dot(q_);
    if (!std::isfinite(pq)) {
      stats_.info = SolveInfo::NumericalIssue;
      stats_.message = "cg: NaN/Inf in K*p at iteration " + std::to_string(k) +
                       " (non-finite material parameters or positions?)";
      break;
    }
    if (pq <= 0) {
      stats_.info = SolveInfo::NotPositiveDefinite;
      std::ostringstream m;
      m << "cg: operator is not positive definite (p^T K p = " << pq << " at iteration " << k
        << "): too few fixed nodes for a static solve, or inverted elements";
      stats_.message = m.str();
      break;
    }
    const double alpha = rz / pq;
    x.noalias() += alpha * p_;
    r_.noalias() -= alpha * q_;
    ++k;
    rnorm = r_.norm();
    if (!std::isfinite(rnorm)) {
      stats_.info = SolveInfo::NumericalIssue;
      stats_.message = "cg: residual became NaN/Inf at iteration " + std::to_string(k);
      break;
    }
    precondition();
    const double rz_new = r_.dot(z_);
    p_ = z_ + (rz_new / rz) * p_;
    rz = rz_new;
  }
  stats_.iterations = k;
  stats_.solve_ms = elapsed_ms();
}

}  // namespace incise
