// The per-tet spring fit (sim/springs/spring_fit.h) against a least-squares solve written independently
// on the 12x12 nodal stiffness matrices (Lloyd, Székely & Harders 2007): the FEM tet's
// V B^T C B, each edge spring's d d^T, the volume term's V g g^T, vectorized and solved by QR.
#include <Eigen/Dense>
#include <catch2/catch.hpp>
#include <map>
#include <random>

#include "mesh/generate.h"
#include "sim/springs/spring_fit.h"
#include "sim/springs/spring_model.h"

using namespace incise;

namespace {

using Mat12 = Eigen::Matrix<double, 12, 12>;
using Vec12 = Eigen::Matrix<double, 12, 1>;

struct Nodal {
  Mat12 fem;                 // V B^T C B
  std::array<Mat12, 6> edge;  // unit spring on each edge: d d^T
  Mat12 volume;              // V g g^T: kappa times it is the volume term's stiffness
};

Nodal nodal_matrices(const std::array<Vec3, 4>& x, double mu, double lambda) {
  Eigen::Matrix3d D;
  D << x[1] - x[0], x[2] - x[0], x[3] - x[0];
  const double V = std::abs(D.determinant()) / 6;
  const Eigen::Matrix3d Dinv = D.inverse();
  std::array<Vec3, 4> g;  // shape function gradients
  for (int a = 1; a < 4; ++a) g[a] = Dinv.row(a - 1).transpose();
  g[0] = -(g[1] + g[2] + g[3]);
  // Energy of a nodal displacement u: V (mu eps:eps + lambda/2 (tr eps)^2), eps = sym(sum_a u_a g_a^T).
  Nodal n;
  n.fem.setZero();
  Vec12 div;
  for (int a = 0; a < 4; ++a) div.segment<3>(3 * a) = g[a];
  for (int a = 0; a < 4; ++a)
    for (int b = 0; b < 4; ++b)
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
          // d2/du_ai du_bj of mu eps:eps = mu (delta_ij g_a.g_b + g_a[j] g_b[i])
          n.fem(3 * a + i, 3 * b + j) += V * mu * ((i == j ? g[a].dot(g[b]) : 0.0) + g[a][j] * g[b][i]);
        }
  n.fem += V * lambda * div * div.transpose();
  n.volume = V * div * div.transpose();
  for (int e = 0; e < 6; ++e) {
    const int i = kTetEdges[e][0], j = kTetEdges[e][1];
    const Vec3 t = (x[j] - x[i]).normalized();
    Vec12 d = Vec12::Zero();
    d.segment<3>(3 * i) = -t;
    d.segment<3>(3 * j) = t;
    n.edge[e] = d * d.transpose();
  }
  return n;
}

// Unconstrained least squares for (k_1..k_6, kappa) on the vectorized nodal matrices.
Eigen::Matrix<double, 7, 1> nodal_least_squares(const Nodal& n) {
  Eigen::Matrix<double, 144, 7> A;
  for (int e = 0; e < 6; ++e) A.col(e) = n.edge[e].reshaped();
  A.col(6) = n.volume.reshaped();
  return A.colPivHouseholderQr().solve(Eigen::Matrix<double, 144, 1>(n.fem.reshaped()));
}

}  // namespace

TEST_CASE("fitted springs: the per-tet fit is the least-squares fit of the nodal stiffness", "[springs][fit]") {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.25, 0.25);
  const double mu = 3.4e4, lambda = 3.1e5;  // E = 1e5, nu = 0.45
  int compared = 0;
  for (int trial = 0; trial < 200; ++trial) {
    // A regular tet with its corners moved by up to a quarter of the edge, scaled and placed anywhere.
    const double s = std::pow(10.0, u(rng) * 12);
    std::array<Vec3, 4> x = {Vec3(1, 0, -1 / std::sqrt(2.0)), Vec3(-1, 0, -1 / std::sqrt(2.0)),
                             Vec3(0, 1, 1 / std::sqrt(2.0)), Vec3(0, -1, 1 / std::sqrt(2.0))};
    const Vec3 shift(u(rng) * 100, u(rng) * 100, u(rng) * 100);
    for (Vec3& p : x) p = (p + Vec3(u(rng), u(rng), u(rng))) * s + shift * s;
    const TetSpringFit fit = fit_tet_springs(x, mu, lambda, true, 0);
    const auto ls = nodal_least_squares(nodal_matrices(x, mu, lambda));
    for (int e = 0; e < 6; ++e) REQUIRE(fit.k[e] >= 0);
    REQUIRE(fit.kappa >= 0);
    if (ls.minCoeff() <= 0) continue;  // the bounds are active: checked below
    ++compared;
    for (int e = 0; e < 6; ++e) REQUIRE(fit.k[e] == Approx(ls[e]).epsilon(1e-8));
    REQUIRE(fit.kappa == Approx(ls[6]).epsilon(1e-8));
  }
  CHECK(compared > 100);
}

TEST_CASE("fitted springs: bounds, symmetry and degenerate tets", "[springs][fit]") {
  const double mu = 1, lambda = 9;
  SECTION("a regular tet gets six equal springs") {
    const std::array<Vec3, 4> x = {Vec3(1, 1, 1), Vec3(1, -1, -1), Vec3(-1, 1, -1), Vec3(-1, -1, 1)};
    const TetSpringFit fit = fit_tet_springs(x, mu, lambda, true, 0);
    for (int e = 1; e < 6; ++e) CHECK(fit.k[e] == Approx(fit.k[0]).epsilon(1e-12));
    CHECK(fit.k[0] > 0);
    CHECK(fit.kappa > 0);
    CHECK(fit.kappa < lambda);  // the springs carry part of lambda (the Cauchy relation)
  }
  SECTION("the volume modulus never drops below its floor; without the term it is 0") {
    const std::array<Vec3, 4> x = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)};
    const double nu_low_lambda = 0.1;  // nu near 0.04: the unconstrained kappa would be negative
    const TetSpringFit floored = fit_tet_springs(x, mu, nu_low_lambda, true, 0.3 * mu);
    CHECK(floored.kappa >= 0.3 * mu);
    const TetSpringFit none = fit_tet_springs(x, mu, lambda, false, 0.3 * mu);
    CHECK(none.kappa == 0);
    for (double k : none.k) CHECK(k >= 0);
  }
  SECTION("a flat or collapsed tet gets zero constants, never NaN") {
    const std::array<Vec3, 4> flat = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(1, 1, 0)};
    const std::array<Vec3, 4> point = {Vec3(0, 0, 0), Vec3(0, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)};
    for (const auto& x : {flat, point}) {
      const TetSpringFit fit = fit_tet_springs(x, mu, lambda, true, 0);
      for (double k : fit.k) CHECK(k == 0);
      CHECK(fit.kappa == 0);
    }
  }
  SECTION("a needle: the bounds hold and the fit is no worse than the clamped least squares") {
    const std::array<Vec3, 4> x = {Vec3(0, 0, 0), Vec3(10, 0, 0), Vec3(5, 0.3, 0), Vec3(5, 0.1, 0.2)};
    const Nodal n = nodal_matrices(x, mu, lambda);
    const TetSpringFit fit = fit_tet_springs(x, mu, lambda, true, 0);
    auto misfit = [&](const std::array<double, 6>& k, double kappa) {
      Mat12 r = n.fem - kappa * n.volume;
      for (int e = 0; e < 6; ++e) r -= k[e] * n.edge[e];
      return r.norm();
    };
    const auto ls = nodal_least_squares(n);
    std::array<double, 6> clamped;
    for (int e = 0; e < 6; ++e) clamped[e] = std::max(ls[e], 0.0);
    for (double k : fit.k) CHECK(k >= 0);
    CHECK(misfit(fit.k, fit.kappa) <= misfit(clamped, std::max(ls[6], 0.0)) * (1 + 1e-9));
  }
}

TEST_CASE("fitted springs: a model's spring is the sum of its tets' fitted constants", "[springs][fit]") {
  TetMesh m = make_box(Vec3(1, 2, 1), {2, 3, 2});
  const Material mat{1e5, 0.45, 1000};
  SpringOptions o;
  o.stiffness = SpringStiffness::Fitted;
  o.across_faces = false;  // fitted constants are per edge
  SpringModel s(m, MaterialTable(mat), o);
  std::map<std::pair<std::uint32_t, std::uint32_t>, double> sum;
  for (TetId t : m.tets()) {
    const auto tv = m.tet_vertices(t);
    const TetSpringFit fit = fit_tet_springs({m.rest(tv[0]), m.rest(tv[1]), m.rest(tv[2]), m.rest(tv[3])}, mat.mu(),
                                             mat.lambda(), true, o.min_volume_ratio * mat.mu());
    for (int e = 0; e < 6; ++e) {
      auto a = tv[kTetEdges[e][0]].idx(), b = tv[kTetEdges[e][1]].idx();
      sum[{std::min(a, b), std::max(a, b)}] += fit.k[e];
    }
    REQUIRE(s.volume_term(t)->kappa == Approx(fit.kappa).epsilon(1e-12));
  }
  REQUIRE(s.num_springs() == sum.size());
  for (const auto& [e, k] : sum) REQUIRE(s.spring(VertexId(e.first), VertexId(e.second))->stiffness == Approx(k).epsilon(1e-12));
  REQUIRE(parse_spring_stiffness("fitted") == SpringStiffness::Fitted);
  REQUIRE(parse_spring_stiffness("van-gelder") == SpringStiffness::VanGelder);
  REQUIRE(!parse_spring_stiffness("Fitted"));
}
