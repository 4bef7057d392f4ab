// SpringModel: the explicit integrators' stable time step, from Gershgorin's bound at rest
// (kept per vertex, updated locally) or from an estimate of the current state's fastest mode.
#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>

#include "mesh/errors.h"
#include "sim/springs/spring_model.h"

namespace incise {

namespace {

// Symplectic Euler (and Verlet) on x'' = -w^2 x - c x' is stable iff w^2 dt^2 + 2 c dt < 4.
double symplectic_limit(double w2, double c) {
  if (!(w2 > 0)) return c > 0 ? 2 / c : std::numeric_limits<double>::infinity();
  return (-c + std::sqrt(c * c + 4 * w2)) / w2;
}

// Explicit Euler's step matrix [[1, dt], [-w^2 dt, 1 - c dt]]: det = 1 - c dt + w^2 dt^2 < 1
// needs dt < c / w^2 (worst at w_max), trace >= -(1 + det) needs c dt < 2.
double explicit_limit(double w2, double c) {
  if (!(c > 0)) return 0.0;
  return w2 > 0 ? std::min(c / w2, 2 / c) : 2 / c;
}

double limit_for(Integrator integrator, double w2, double c) {
  switch (integrator) {
    case Integrator::ImplicitEuler: return std::numeric_limits<double>::infinity();
    case Integrator::ExplicitEuler: return explicit_limit(w2, c);
    default: return symplectic_limit(w2, c);
  }
}

}  // namespace

double SpringModel::max_angular_frequency() const {
  return bound_leaves_ ? std::sqrt(bound_tree_[1]) : 0.0;
}

// Kelvin-Voigt damps a mode of frequency w at viscosity x w^2: the fastest mode's rate.
double SpringModel::stable_time_step() const { return stable_time_step(Integrator::SymplecticEuler); }

double SpringModel::stable_time_step(Integrator integrator) const {
  const double w2 = bound_leaves_ ? bound_tree_[1] : 0.0;
  return limit_for(integrator, w2, opt_.damping + max_tau_ * w2);
}

// Lanczos on A = M^-1/2 K M^-1/2 restricted to the free dofs (K: linearize()'s tangent at x_),
// without reorthogonalization (lost orthogonality makes copies of converged Ritz values, it does
// not move the largest). The largest Ritz value theta has an eigenvalue of A within the
// residual beta_k |s_k| of it; theta + that residual is returned, so the estimate errs high (the
// step it gives errs short) while theta is still converging.
double SpringModel::estimated_max_angular_frequency(int iterations) {
  if (iterations < 2) throw InvalidArgument("springs: the stable step's estimate needs at least 2 iterations");
  const std::size_t n = x_.size();
  std::vector<double> scale(n, 0.0);  // 1 / sqrt(m_i) on the free dofs, 0 elsewhere
  std::size_t free = 0;
  for (std::size_t i = 0; i < n; ++i)
    if (free_dof(static_cast<std::uint32_t>(i))) {
      scale[i] = 1 / std::sqrt(mass_[i]);
      ++free;
    }
  if (free == 0) return 0.0;
  if (opt_.nodal_volume) nodal_volumes(x_);
  linearize();
  auto dot = [&](const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
    double s = 0;
    for (std::size_t i = 0; i < n; ++i) s += a[i].dot(b[i]);
    return s;
  };
  // A deterministic start with every free dof in it (a fixed-seed hash, not a smooth field,
  // so the fast modes are present from the first product).
  std::vector<Vec3> q(n, Vec3::Zero()), q_prev(n, Vec3::Zero()), w(n), t(n);
  std::uint64_t h = 0x9e3779b97f4a7c15ull;
  auto next = [&] {
    h ^= h << 13, h ^= h >> 7, h ^= h << 17;
    return double(h >> 11) / double(1ull << 53) - 0.5;
  };
  for (std::size_t i = 0; i < n; ++i)
    if (scale[i] > 0) q[i] = Vec3(next(), next(), next());
  double norm = std::sqrt(dot(q, q));
  for (Vec3& v : q) v /= norm;
  std::vector<double> alpha, beta;  // T's diagonal and off-diagonal
  const int k_max = static_cast<int>(std::min<std::size_t>(iterations, 3 * free));
  for (int k = 0; k < k_max; ++k) {
    for (std::size_t i = 0; i < n; ++i) t[i] = scale[i] * q[i];
    apply_tangent(t, w, 0.0, 1.0, 0.0);
    for (std::size_t i = 0; i < n; ++i) w[i] *= scale[i];
    const double a = dot(q, w);
    alpha.push_back(a);
    const double b_prev = beta.empty() ? 0.0 : beta.back();
    for (std::size_t i = 0; i < n; ++i) w[i] -= a * q[i] + b_prev * q_prev[i];
    const double b = std::sqrt(dot(w, w));
    beta.push_back(b);
    if (!(b > 1e-14 * std::abs(a))) break;  // an invariant subspace: T's eigenvalues are A's
    q_prev.swap(q);
    for (std::size_t i = 0; i < n; ++i) q[i] = w[i] / b;
  }
  const int m = static_cast<int>(alpha.size());
  Eigen::MatrixXd tri = Eigen::MatrixXd::Zero(m, m);
  for (int i = 0; i < m; ++i) {
    tri(i, i) = alpha[i];
    if (i + 1 < m) tri(i, i + 1) = tri(i + 1, i) = beta[i];
  }
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(tri);
  const double theta = es.eigenvalues()(m - 1);
  const double residual = beta[m - 1] * std::abs(es.eigenvectors()(m - 1, m - 1));
  const double w2 = std::max(0.0, theta + residual);
  if (!std::isfinite(w2)) throw Error("springs: the stable step's estimate is not finite: the state is not finite");
  return std::sqrt(w2);
}

double SpringModel::estimated_stable_time_step(Integrator integrator, int iterations) {
  const double w = estimated_max_angular_frequency(iterations), w2 = w * w;
  return limit_for(integrator, w2, opt_.damping + max_tau_ * w2);
}

}  // namespace incise
