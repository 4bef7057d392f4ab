#include "sim/springs/spring_fit.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

namespace incise {

namespace {

using Small = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 7, 7>;
using SmallVec = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 7, 1>;
using Mandel = Eigen::Matrix<double, 6, 1>;

// min 1/2 x^T G x - b^T x subject to x >= 0 (G symmetric positive definite, n <= 7):
// Lawson & Hanson's active set, on the normal equations.
SmallVec nonnegative_least_squares(const Small& G, const SmallVec& b) {
  const int n = int(b.size());
  SmallVec x = SmallVec::Zero(n);
  std::array<bool, 7> passive{};
  const double tol = 1e-13 * std::max(1.0, b.cwiseAbs().maxCoeff());
  auto solve_passive = [&]() {
    std::array<int, 7> idx{};
    int m = 0;
    for (int i = 0; i < n; ++i)
      if (passive[i]) idx[m++] = i;
    Small A(m, m);
    SmallVec r(m);
    for (int i = 0; i < m; ++i) {
      r[i] = b[idx[i]];
      for (int j = 0; j < m; ++j) A(i, j) = G(idx[i], idx[j]);
    }
    const SmallVec s = A.ldlt().solve(r);
    SmallVec z = SmallVec::Zero(n);
    for (int i = 0; i < m; ++i) z[idx[i]] = s[i];
    return z;
  };
  for (int outer = 0; outer < 4 * n; ++outer) {
    const SmallVec w = b - G * x;
    int best = -1;
    for (int i = 0; i < n; ++i)
      if (!passive[i] && w[i] > tol && (best < 0 || w[i] > w[best])) best = i;
    if (best < 0) break;
    passive[best] = true;
    for (int inner = 0; inner < 2 * n; ++inner) {
      const SmallVec z = solve_passive();
      bool feasible = true;
      double alpha = 1;
      for (int i = 0; i < n; ++i)
        if (passive[i] && z[i] <= 0) {
          feasible = false;
          alpha = std::min(alpha, x[i] / (x[i] - z[i]));
        }
      if (feasible) {
        x = z;
        break;
      }
      x += alpha * (z - x);
      for (int i = 0; i < n; ++i)
        if (passive[i] && x[i] <= tol) {
          passive[i] = false;
          x[i] = 0;
        }
    }
  }
  return x;
}

}  // namespace

TetSpringFit fit_tet_springs(const std::array<Vec3, 4>& x, double mu, double lambda, bool volume_term,
                             double kappa_min) {
  TetSpringFit fit;
  Eigen::Matrix3d D;
  D << x[1] - x[0], x[2] - x[0], x[3] - x[0];
  const double volume = std::abs(D.determinant()) / 6;
  std::array<Vec3, 6> t;
  std::array<double, 6> len{};
  for (int e = 0; e < 6; ++e) {
    const Vec3 d = x[kTetEdges[e][1]] - x[kTetEdges[e][0]];
    len[e] = d.norm();
    if (!(len[e] > 0) || !(volume > 1e-14 * len[0] * len[0] * len[0])) return fit;
    t[e] = d / len[e];
  }
  // The metric H = B B^T of the strain-displacement map B (nodal u -> Mandel strain): the
  // nodal matrices B^T X B have Frobenius inner products tr(X H Y H).
  const Eigen::Matrix3d Dinv = D.inverse();  // rows: gradients of the shape functions 1..3
  std::array<Vec3, 4> g;
  for (int a = 1; a < 4; ++a) g[a] = Dinv.row(a - 1).transpose();
  g[0] = -(g[1] + g[2] + g[3]);
  const double r2 = std::sqrt(2.0);
  auto mandel = [&](const Eigen::Matrix3d& e) {
    Mandel m;
    m << e(0, 0), e(1, 1), e(2, 2), r2 * e(1, 2), r2 * e(0, 2), r2 * e(0, 1);
    return m;
  };
  Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
  for (int a = 0; a < 4; ++a)
    for (int k = 0; k < 3; ++k) {
      Eigen::Matrix3d e = Eigen::Matrix3d::Zero();
      e.col(k) = g[a];
      const Mandel m = mandel(0.5 * (e + e.transpose()));
      H += m * m.transpose();
    }
  H /= H.trace();  // the fit does not depend on H's scale; this keeps the numbers near 1
  // The unknowns: w_e = k_e l_e^2 / V (forms m_e m_e^T) and kappa - k0 (form 1 1^T).
  const int n = volume_term ? 7 : 6;
  const double k0 = volume_term ? kappa_min : 0;
  Mandel one;
  one << 1, 1, 1, 0, 0, 0;
  std::array<Mandel, 7> form;
  for (int e = 0; e < 6; ++e) form[e] = mandel(t[e] * t[e].transpose());
  form[6] = one;
  // Without a volume term the springs fit the isotropic material they can be (nu = 1/4, same
  // E: lambda = mu = 0.4 E), as Van Gelder's rule does; fitting a larger lambda with springs
  // alone makes them stiff in every direction.
  const double young = mu * (3 * lambda + 2 * mu) / (lambda + mu);
  const double m_fit = volume_term ? mu : 0.4 * young, l_fit = volume_term ? lambda - k0 : 0.4 * young;
  const Eigen::Matrix<double, 6, 6> C = 2 * m_fit * Eigen::Matrix<double, 6, 6>::Identity() + l_fit * one * one.transpose();
  const Eigen::Matrix<double, 6, 6> HCH = H * C * H;
  Small G(n, n);
  SmallVec b(n);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const double c = form[i].dot(H * form[j]);
      G(i, j) = c * c;
    }
    b[i] = form[i].dot(HCH * form[i]);
  }
  for (int i = 0; i < n; ++i) G(i, i) *= 1 + 1e-12;  // a flat tet's forms are dependent
  const SmallVec w = nonnegative_least_squares(G, b);
  for (int e = 0; e < 6; ++e) fit.k[e] = w[e] * volume / (len[e] * len[e]);
  if (volume_term) fit.kappa = k0 + w[6];
  return fit;
}

}  // namespace incise
