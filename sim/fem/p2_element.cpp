#include "sim/fem/p2_element.h"

#include <cmath>

#include "mesh/errors.h"
#include "sim/fem/p2_mesh.h"

namespace incise {

P2Tet make_p2_tet(const std::array<Vec3, 4>& x) {
  Eigen::Matrix3d e;
  e.col(0) = x[1] - x[0];
  e.col(1) = x[2] - x[0];
  e.col(2) = x[3] - x[0];
  const double det = e.determinant();
  if (!(det > 0)) throw InvalidMesh("p2: a tet has zero or negative volume");
  P2Tet t;
  t.volume = det / 6;
  const Eigen::Matrix3d inv = e.inverse();  // row j: grad L_{j+1}
  t.grad_l.bottomRows<3>() = inv;
  t.grad_l.row(0) = -inv.colwise().sum();
  return t;
}

Eigen::Matrix<double, 10, 3> p2_gradients(const P2Tet& t, const Eigen::Vector4d& l) {
  Eigen::Matrix<double, 10, 3> g;
  for (int i = 0; i < 4; ++i) g.row(i) = (4 * l[i] - 1) * t.grad_l.row(i);
  for (int k = 0; k < 6; ++k) {
    const int i = kP2Edges[std::size_t(k)][0], j = kP2Edges[std::size_t(k)][1];
    g.row(4 + k) = 4 * (l[j] * t.grad_l.row(i) + l[i] * t.grad_l.row(j));
  }
  return g;
}

const std::array<Eigen::Vector4d, 4>& p2_quadrature_points() {
  static const std::array<Eigen::Vector4d, 4> pts = [] {
    const double a = (5 + 3 * std::sqrt(5.0)) / 20, b = (5 - std::sqrt(5.0)) / 20;
    std::array<Eigen::Vector4d, 4> p;
    for (int q = 0; q < 4; ++q) {
      p[std::size_t(q)].setConstant(b);
      p[std::size_t(q)][q] = a;
    }
    return p;
  }();
  return pts;
}

P2Matrix p2_stiffness(const P2Tet& t, double mu, double lambda) {
  P2Matrix k = P2Matrix::Zero();
  const double w = t.volume / 4;
  for (const Eigen::Vector4d& l : p2_quadrature_points()) {
    const Eigen::Matrix<double, 10, 3> g = p2_gradients(t, l);
    for (int a = 0; a < 10; ++a)
      for (int b = a; b < 10; ++b) {
        const Eigen::Vector3d ga = g.row(a).transpose(), gb = g.row(b).transpose();
        const Eigen::Matrix3d blk =
            w * (lambda * ga * gb.transpose() + mu * gb * ga.transpose() + mu * ga.dot(gb) * Eigen::Matrix3d::Identity());
        k.block<3, 3>(3 * a, 3 * b) += blk;
        if (b != a) k.block<3, 3>(3 * b, 3 * a) += blk.transpose();
      }
  }
  return k;
}

Eigen::Matrix<double, 4, 30> p2_divergence(const P2Tet& t) {
  Eigen::Matrix<double, 4, 30> d = Eigen::Matrix<double, 4, 30>::Zero();
  const double w = t.volume / 4;
  for (const Eigen::Vector4d& l : p2_quadrature_points()) {
    const Eigen::Matrix<double, 10, 3> g = p2_gradients(t, l);
    for (int i = 0; i < 4; ++i)
      for (int a = 0; a < 10; ++a) d.block<1, 3>(i, 3 * a) += w * l[i] * g.row(a);
  }
  return d;
}

namespace {

// N_a = L^T Q_a L (sum L = 1 turns the linear terms into quadratic ones).
std::array<Eigen::Matrix4d, 10> shape_quadratic_forms() {
  std::array<Eigen::Matrix4d, 10> q;
  for (int i = 0; i < 4; ++i) {
    q[std::size_t(i)].setConstant(0);
    for (int j = 0; j < 4; ++j) q[std::size_t(i)](i, j) = q[std::size_t(i)](j, i) = j == i ? 1.0 : -0.5;
  }
  for (int k = 0; k < 6; ++k) {
    Eigen::Matrix4d& m = q[std::size_t(4 + k)];
    m.setZero();
    const int i = kP2Edges[std::size_t(k)][0], j = kP2Edges[std::size_t(k)][1];
    m(i, j) = m(j, i) = 2;
  }
  return q;
}

double factorial(int n) { return n <= 1 ? 1.0 : n * factorial(n - 1); }

}  // namespace

const Eigen::Matrix<double, 10, 10>& p2_unit_mass() {
  static const Eigen::Matrix<double, 10, 10> m = [] {
    const auto q = shape_quadratic_forms();
    // int_T L_i L_j L_k L_l / V = 6 prod(multiplicities!) / 7!
    double mono[4][4][4][4];
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j)
        for (int k = 0; k < 4; ++k)
          for (int l = 0; l < 4; ++l) {
            int c[4] = {0, 0, 0, 0};
            ++c[i], ++c[j], ++c[k], ++c[l];
            mono[i][j][k][l] = 6 * factorial(c[0]) * factorial(c[1]) * factorial(c[2]) * factorial(c[3]) / factorial(7);
          }
    Eigen::Matrix<double, 10, 10> out;
    for (int a = 0; a < 10; ++a)
      for (int b = 0; b < 10; ++b) {
        double s = 0;
        for (int i = 0; i < 4; ++i)
          for (int j = 0; j < 4; ++j)
            for (int k = 0; k < 4; ++k)
              for (int l = 0; l < 4; ++l) s += q[std::size_t(a)](i, j) * q[std::size_t(b)](k, l) * mono[i][j][k][l];
        out(a, b) = s;
      }
    return out;
  }();
  return m;
}

double p2_load_weight(int a) { return a < 4 ? -1.0 / 20 : 1.0 / 5; }

Eigen::Matrix3d p2_displacement_gradient(const P2Tet& t, const Eigen::Matrix<double, 30, 1>& ue,
                                         const Eigen::Vector4d& l) {
  const Eigen::Matrix<double, 10, 3> g = p2_gradients(t, l);
  Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
  for (int a = 0; a < 10; ++a) h += ue.segment<3>(3 * a) * g.row(a);
  return h;
}

}  // namespace incise
