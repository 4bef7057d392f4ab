#include "sim/linalg/cg_solver.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <vector>

#include <Eigen/Cholesky>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "mesh/clock.h"
#include "mesh/errors.h"

namespace incise {

namespace {

// The iteration's vector work, fused into four passes (it was eight: projections, dots, axpys
// and a norm, each a trip through vectors larger than a core's L2 on the organ), split over
// fixed blocks. Partial sums are kept per block and added in block order, so the results do not
// depend on the thread count or on the scheduling.
constexpr Eigen::Index kBlock = 4096;
constexpr Eigen::Index kParallelFrom = 3 * kBlock;

template <class F>
double blocked_sum(Eigen::Index n, F&& f) {
  const Eigen::Index nb = (n + kBlock - 1) / kBlock;
  auto part = [&](Eigen::Index b) { return f(b * kBlock, std::min(n, (b + 1) * kBlock)); };
  if (n < kParallelFrom) {
    double s = 0;
    for (Eigen::Index b = 0; b < nb; ++b) s += part(b);
    return s;
  }
  double sums[64];
  std::vector<double> more;
  double* out = sums;
  if (nb > 64) {
    more.resize(std::size_t(nb));
    out = more.data();
  }
  tbb::parallel_for(tbb::blocked_range<Eigen::Index>(0, nb, 1), [&](const tbb::blocked_range<Eigen::Index>& r) {
    for (Eigen::Index b = r.begin(); b != r.end(); ++b) out[b] = part(b);
  });
  double s = 0;
  for (Eigen::Index b = 0; b < nb; ++b) s += out[b];
  return s;
}

// v = 0 where mask is 0 (no mask: all free); returns w . v.
double project_dot(const std::vector<std::uint8_t>* mask, Eigen::VectorXd& v, const Eigen::VectorXd& w) {
  double* vp = v.data();
  const double* wp = w.data();
  const std::uint8_t* m = mask ? mask->data() : nullptr;
  return blocked_sum(v.size(), [&](Eigen::Index lo, Eigen::Index hi) {
    double s0 = 0, s1 = 0, s2 = 0, s3 = 0;
    Eigen::Index i = lo;
    if (m) {
      for (Eigen::Index j = lo; j < hi; ++j) vp[j] = m[j] ? vp[j] : 0.0;
    }
    for (; i + 4 <= hi; i += 4) {
      s0 += wp[i] * vp[i];
      s1 += wp[i + 1] * vp[i + 1];
      s2 += wp[i + 2] * vp[i + 2];
      s3 += wp[i + 3] * vp[i + 3];
    }
    for (; i < hi; ++i) s0 += wp[i] * vp[i];
    return (s0 + s1) + (s2 + s3);
  });
}

// x += a p, r -= a q; returns r . r.
double step_xr(Eigen::VectorXd& x, Eigen::VectorXd& r, const Eigen::VectorXd& p, const Eigen::VectorXd& q, double a) {
  double* xp = x.data();
  double* rp = r.data();
  const double* pp = p.data();
  const double* qp = q.data();
  return blocked_sum(r.size(), [&](Eigen::Index lo, Eigen::Index hi) {
    double s0 = 0, s1 = 0, s2 = 0, s3 = 0;
    Eigen::Index i = lo;
    for (; i + 4 <= hi; i += 4) {
      for (int j = 0; j < 4; ++j) {
        xp[i + j] += a * pp[i + j];
        rp[i + j] -= a * qp[i + j];
      }
      s0 += rp[i] * rp[i];
      s1 += rp[i + 1] * rp[i + 1];
      s2 += rp[i + 2] * rp[i + 2];
      s3 += rp[i + 3] * rp[i + 3];
    }
    for (; i < hi; ++i) {
      xp[i] += a * pp[i];
      rp[i] -= a * qp[i];
      s0 += rp[i] * rp[i];
    }
    return (s0 + s1) + (s2 + s3);
  });
}

// p = z + beta p.
void next_direction(Eigen::VectorXd& p, const Eigen::VectorXd& z, double beta) {
  double* pp = p.data();
  const double* zp = z.data();
  blocked_sum(p.size(), [&](Eigen::Index lo, Eigen::Index hi) {
    for (Eigen::Index i = lo; i < hi; ++i) pp[i] = zp[i] + beta * pp[i];
    return 0.0;
  });
}

}  // namespace

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

ConjugateGradient::ConjugateGradient(const CgOptions& o) : opt_(o) {
  set_tolerance(o.tolerance);
  set_max_iterations(o.max_iterations);
  set_budget_ms(o.budget_ms);
  set_preconditioner(o.preconditioner);
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
void ConjugateGradient::set_preconditioner(Preconditioner p) {
  const bool attached = pc_ && pc_ != builtin_.get();
  if (!builtin_ || p != opt_.preconditioner) builtin_ = make_preconditioner(p);
  opt_.preconditioner = p;
  if (!attached) {
    pc_ = builtin_.get();
    pc_apply_ms_ = pc_setup_ms_ = cheap_apply_ms_ = cheap_setup_ms_ = 0;
  }
  resumable_ = false;
}
void ConjugateGradient::set_preconditioner(CgPreconditioner* pc) {
  pc_ = pc ? pc : builtin_.get();
  resumable_ = false;
  pc_apply_ms_ = pc_setup_ms_ = cheap_apply_ms_ = cheap_setup_ms_ = 0;
}

namespace {
// Running average of a measured cost; the first measurement sets it.
void average_in(double& avg, double ms) { avg = avg > 0 ? 0.75 * avg + 0.25 * ms : ms; }
}  // namespace

void ConjugateGradient::multiply(const Eigen::VectorXd& v, Eigen::VectorXd& out) {
  const double t = now_ms();
  A_->multiply(v, out);
  average_in(kx_ms_, now_ms() - t);
}

void ConjugateGradient::precondition(const Eigen::VectorXd& r, Eigen::VectorXd& z) {
  const double t = now_ms();
  active_->apply(r, z);
  average_in(active_ == pc_ ? pc_apply_ms_ : cheap_apply_ms_, now_ms() - t);
}

void ConjugateGradient::compute(const LinearOperator& A, const std::vector<std::uint8_t>* free) {
  A_ = &A;
  free_ = (free && !free->empty()) ? free : nullptr;
  if (free_ && Eigen::Index(free_->size()) != A.rows())
    throw InvalidArgument("cg: free mask has " + std::to_string(free_->size()) + " entries, operator " +
                          std::to_string(A.rows()) + " rows");
  invalidate();
}

void ConjugateGradient::invalidate() {
  resumable_ = false;
  akept_valid_ = false;
}

void ConjugateGradient::project(Eigen::VectorXd& v) const {
  if (!free_) return;
  const auto& f = *free_;
  for (Eigen::Index i = 0; i < v.size(); ++i)
    if (!f[std::size_t(i)]) v[i] = 0;
}

Eigen::VectorXd ConjugateGradient::solve(const Eigen::VectorXd& b) {
  Eigen::VectorXd x = Eigen::VectorXd::Zero(b.size());
  solve_with_guess(b, x);
  return x;
}

bool ConjugateGradient::can_resume(const Eigen::VectorXd& b, const Eigen::VectorXd& x) const {
  return resumable_ && A_ && active_ && active_->version() == pc_version_ && b.size() == b_last_.size() &&
         x.size() == x_last_.size() && b == b_last_ && x == x_last_;
}

// Sets r_, bnorm_ and the start point; returns false when the solve is already finished.
// x += sum alpha_i d_i, r -= sum alpha_i P A d_i with the Galerkin alphas (least energy-norm
// error), or those of least ||r|| when the Galerkin ones do not lower ||r||.
void ConjugateGradient::predict(Eigen::VectorXd& x, std::span<const Eigen::VectorXd> d) {
  const Eigen::Index n = A_->rows();
  pd_.clear();
  qd_.clear();
  for (const Eigen::VectorXd& di : d) {
    if (di.size() != n) continue;
    pd_.push_back(di);
    project(pd_.back());
    if (pd_.back().isZero(0)) {
      pd_.pop_back();
      continue;
    }
    qd_.emplace_back();
    multiply(pd_.back(), qd_.back());
    ++stats_.products;
    project(qd_.back());
  }
  const Eigen::Index k = Eigen::Index(qd_.size());
  if (k == 0) return;
  // Galerkin: D^T A D a = D^T r (the start of least energy-norm error over the span, CG's
  // own criterion). Least residual: (A D)^T (A D) a = (A D)^T r. Same products, two 4x4 solves.
  Eigen::MatrixXd g(k, k), gr(k, k);
  Eigen::VectorXd h(k), hr(k);
  for (Eigen::Index i = 0; i < k; ++i) {
    h[i] = pd_[std::size_t(i)].dot(r_);
    hr[i] = qd_[std::size_t(i)].dot(r_);
    for (Eigen::Index j = 0; j < k; ++j) {
      g(i, j) = pd_[std::size_t(i)].dot(qd_[std::size_t(j)]);
      gr(i, j) = qd_[std::size_t(i)].dot(qd_[std::size_t(j)]);
    }
  }
  // Takes the weights of m a = rhs when they lower the residual. Near-parallel directions make
  // m singular: a tiny ridge keeps the solve finite, and the residual check keeps the start
  // point when the result is no better.
  auto take = [&](Eigen::MatrixXd& m, const Eigen::VectorXd& rhs) {
    m.diagonal() *= 1 + 1e-12;
    const Eigen::VectorXd alpha = m.ldlt().solve(rhs);
    if (!alpha.allFinite()) return false;
    z_ = r_;
    for (Eigen::Index i = 0; i < k; ++i) z_.noalias() -= alpha[i] * qd_[std::size_t(i)];
    if (!(z_.squaredNorm() < r_.squaredNorm())) return false;
    r_.swap(z_);
    for (Eigen::Index i = 0; i < k; ++i) x.noalias() += alpha[i] * pd_[std::size_t(i)];
    stats_.prediction_weight = alpha[0];
    return true;
  };
  if (!take(g, h)) take(gr, hr);
}

bool ConjugateGradient::start(const Eigen::VectorXd& b, Eigen::VectorXd& x, std::span<const Eigen::VectorXd> d,
                              double t0) {
  const bool budgeted = opt_.budget_ms > 0;
  auto left = [&] { return opt_.budget_ms - (now_ms() - t0); };
  const Eigen::Index n = A_->rows();
  // Split the guess: z_ = kept part, p_ = free part.
  z_ = x;
  p_ = x;
  project(p_);
  z_ -= p_;
  // Effective right-hand side P (b - A x_kept); A x_kept is cached while the kept values and
  // the operator stay the same (the common frame: fixed nodes, or a probe that stopped).
  if (z_.isZero(0)) {
    akept_.setZero(n);
    kept_last_.setZero(n);
    akept_valid_ = true;
  } else if (!(akept_valid_ && kept_last_.size() == n && z_ == kept_last_)) {
    multiply(z_, akept_);
    ++stats_.products;
    project(akept_);
    kept_last_ = z_;
    akept_valid_ = true;
  }
  r_ = b;
  project(r_);
  r_ -= akept_;
  bnorm_ = r_.norm();
  if (!std::isfinite(bnorm_)) {
    stats_.info = SolveInfo::NumericalIssue;
    stats_.relative_residual = std::numeric_limits<double>::quiet_NaN();
    stats_.message = "cg: the right-hand side or the initial guess contains NaN/Inf";
    return false;
  }
  if (bnorm_ == 0) {  // the solution is zero on free unknowns
    x -= p_;
    return false;
  }
  if (!p_.isZero(0)) {
    multiply(p_, q_);
    ++stats_.products;
    project(q_);
    r_ -= q_;
  }
  if (!std::isfinite(r_.squaredNorm())) {
    stats_.info = SolveInfo::NumericalIssue;
    stats_.relative_residual = std::numeric_limits<double>::quiet_NaN();
    stats_.message = "cg: the right-hand side or the initial guess contains NaN/Inf";
    return false;
  }
  stats_.guess_relative_residual = r_.norm() / bnorm_;
  // A prediction costs a product per direction: not worth half of what the budget leaves.
  if (budgeted && kx_ms_ > 0 && double(d.size()) * kx_ms_ > 0.5 * left()) d = {};
  predict(x, d);
  stats_.initial_relative_residual = r_.norm() / bnorm_;
  if (stats_.initial_relative_residual <= opt_.tolerance) {  // converged at the start point
    stats_.relative_residual = stats_.initial_relative_residual;
    return false;
  }
  if (log_) *log_ = {};
  // The preconditioner's setup and application must fit the budget with a product to spare;
  // otherwise this solve uses the cheaper one (unknown costs are measured by trying, unless the
  // preconditioner announces its setup cost).
  active_ = pc_;
  CgPreconditioner* cheap = pc_->cheaper();
  const double hint = pc_->next_setup_ms();
  const double pc_ms = (hint >= 0 ? hint : pc_setup_ms_) + pc_apply_ms_, cheap_ms = cheap_setup_ms_ + cheap_apply_ms_;
  if (budgeted && cheap && (pc_apply_ms_ > 0 || hint > 0) && pc_ms + kx_ms_ > left() &&
      (cheap_ms == 0 || pc_ms > 1.5 * cheap_ms)) {
    active_ = cheap;
    stats_.cheaper_preconditioner = true;
  }
  const double ts = now_ms();
  active_->setup(*A_, free_);
  stats_.preconditioner_setup_ms = now_ms() - ts;
  average_in(active_ == pc_ ? pc_setup_ms_ : cheap_setup_ms_, stats_.preconditioner_setup_ms);
  pc_version_ = active_->version();
  precondition(r_, z_);
  project(z_);
  p_ = z_;
  rz_ = r_.dot(z_);
  return true;
}

void ConjugateGradient::solve_with_guess(const Eigen::VectorXd& b, Eigen::VectorXd& x,
                                         std::span<const Eigen::VectorXd> d) {
  const double t0 = now_ms();
  if (!A_) throw Error("cg: solve before compute()");
  if (!pc_) set_preconditioner(opt_.preconditioner);
  const Eigen::Index n = A_->rows();
  if (b.size() != n || x.size() != n)
    throw InvalidArgument("cg: right-hand side / guess size does not match the operator");
  const bool resume = can_resume(b, x);
  stats_ = SolveStats{};
  stats_.resumed = resume;
  if (resume) {
    stats_.cheaper_preconditioner = active_ != pc_;
    stats_.guess_relative_residual = stats_.initial_relative_residual = r_.norm() / bnorm_;
  } else if (!start(b, x, d, t0)) {
    resumable_ = false;
    stats_.solve_ms = now_ms() - t0;
    return;
  }
  iterate(x, t0);
  // Keep what a resume needs only when there is something to resume.
  resumable_ = stats_.info == SolveInfo::BudgetExhausted || stats_.info == SolveInfo::NoConvergence;
  if (resumable_) {
    b_last_ = b;
    x_last_ = x;
  }
  stats_.solve_ms = now_ms() - t0;
}

void ConjugateGradient::iterate(Eigen::VectorXd& x, double t0) {
  const double target = opt_.tolerance * bnorm_;
  double rnorm = r_.norm();
  int k = 0;
  for (;;) {
    stats_.relative_residual = rnorm / bnorm_;
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
    // Stop before an iteration that would end past the budget (a product and an application
    // at their measured costs); the first one always runs, so budgeted solves progress.
    if (k > 0 && opt_.budget_ms > 0 &&
        now_ms() - t0 + kx_ms_ + (active_ == pc_ ? pc_apply_ms_ : cheap_apply_ms_) > opt_.budget_ms) {
      stats_.info = SolveInfo::BudgetExhausted;
      stats_.budget_exhausted = true;
      break;
    }
    multiply(p_, q_);
    const double pq = project_dot(free_, q_, p_);
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
    const double alpha = rz_ / pq;
    ++k;
    rnorm = std::sqrt(step_xr(x, r_, p_, q_, alpha));
    if (!std::isfinite(rnorm)) {
      stats_.info = SolveInfo::NumericalIssue;
      stats_.message = "cg: residual became NaN/Inf at iteration " + std::to_string(k);
      break;
    }
    // Converged: stop before the preconditioner, whose application would only serve a next
    // iteration (with a Cholesky factor, one application costs many block-Jacobi iterations).
    if (rnorm <= target) {
      stats_.relative_residual = rnorm / bnorm_;
      stats_.info = SolveInfo::Success;
      break;
    }
    precondition(r_, z_);
    const double rz_new = project_dot(free_, z_, r_);
    if (log_) {
      log_->alpha.push_back(alpha);
      log_->beta.push_back(rz_new / rz_);
    }
    next_direction(p_, z_, rz_new / rz_);
    rz_ = rz_new;
  }
  stats_.iterations = k;
  stats_.products += k;
}

}  // namespace incise
