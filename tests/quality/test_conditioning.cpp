// The solver estimate against the eigenvalues of the assembled P1 Laplacian (body clamped
// on its x = min face, as the estimate assumes).
#include <catch2/catch.hpp>

#include <cmath>

#include <Eigen/Dense>

#include "mesh/errors.h"
#include "mesh/generate.h"
#include "quality/conditioning.h"

using namespace incise;

namespace {

// Condition number of the Laplacian stiffness matrix with the vertices at x = x_min fixed,
// and its largest eigenvalue.
struct Spectrum {
  double kappa, lambda_max, lambda_min;
};
Spectrum laplacian_spectrum(const TetMesh& m) {
  const std::size_t n = m.vertex_capacity();
  double xmin = 1e300;
  for (VertexId v : m.vertices()) xmin = std::min(xmin, m.rest(v).x());
  std::vector<int> dof(n, -1);
  int nd = 0;
  for (VertexId v : m.vertices())
    if (m.rest(v).x() > xmin + 1e-12 && !m.incident_tets(v).empty()) dof[v.idx()] = nd++;
  Eigen::MatrixXd K = Eigen::MatrixXd::Zero(nd, nd);
  for (TetId t : m.tets()) {
    const auto& v = m.tet_vertices(t);
    Eigen::Matrix3d J;
    for (int k = 0; k < 3; ++k) J.col(k) = m.rest(v[k + 1]) - m.rest(v[0]);
    double vol = J.determinant() / 6.0;
    Eigen::Matrix3d Jit = J.inverse().transpose();
    Eigen::Matrix<double, 3, 4> G;  // barycentric gradients
    G.col(1) = Jit.col(0);
    G.col(2) = Jit.col(1);
    G.col(3) = Jit.col(2);
    G.col(0) = -(G.col(1) + G.col(2) + G.col(3));
    Eigen::Matrix4d Ke = std::abs(vol) * G.transpose() * G;
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b)
        if (dof[v[a].idx()] >= 0 && dof[v[b].idx()] >= 0) K(dof[v[a].idx()], dof[v[b].idx()]) += Ke(a, b);
  }
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(K, Eigen::EigenvaluesOnly);
  const auto& ev = es.eigenvalues();
  return {ev(nd - 1) / ev(0), ev(nd - 1), ev(0)};
}

}  // namespace

TEST_CASE("condition estimate tracks the assembled Laplacian", "[quality][conditioning]") {
  struct Case {
    const char* name;
    TetMesh mesh;
  };
  std::vector<Case> cases;
  cases.push_back({"cube 3", make_box(Vec3(1, 1, 1), {3, 3, 3})});
  cases.push_back({"cube 6", make_box(Vec3(1, 1, 1), {6, 6, 6})});
  cases.push_back({"bar 4x1x1", make_box(Vec3(4, 1, 1), {12, 3, 3})});
  cases.push_back({"small cube 1e-6", make_box(Vec3(1e-6, 1e-6, 1e-6), {5, 5, 5})});
  cases.push_back({"ellipsoid", make_ellipsoid(Vec3(2, 1, 1), 3)});
  for (const Case& c : cases) {
    SolverEstimate est = estimate_solver(c.mesh);
    Spectrum sp = laplacian_spectrum(c.mesh);
    INFO(c.name << ": estimate " << est.kappa_laplace << ", true " << sp.kappa << ", lambda_max bound "
                << est.lambda_max_bound << " vs " << sp.lambda_max);
    REQUIRE(est.available);
    // lambda_max is a rigorous bound (within the factor 3 of trace vs max eigenvalue and
    // the vertex valence sum).
    CHECK(est.lambda_max_bound >= sp.lambda_max * (1 - 1e-12));
    CHECK(est.lambda_max_bound <= 10 * sp.lambda_max);
    const double ratio = est.kappa_laplace / sp.kappa;
    CHECK(ratio > 0.5);
    CHECK(ratio < 8);
    CHECK(est.kappa == Approx(est.kappa_laplace * 2 * 0.55 / 0.1));
    CHECK(est.cg_iterations == Approx(0.5 * std::sqrt(est.kappa) * std::log(2e6)));
  }
}

TEST_CASE("condition estimate follows refinement and a bad element", "[quality][conditioning]") {
  TetMesh coarse = make_box(Vec3(1, 1, 1), {3, 3, 3}), fine = make_box(Vec3(1, 1, 1), {7, 7, 7});
  const double est_growth = estimate_solver(fine).kappa_laplace / estimate_solver(coarse).kappa_laplace;
  const double true_growth = laplacian_spectrum(fine).kappa / laplacian_spectrum(coarse).kappa;
  INFO("growth estimate " << est_growth << " true " << true_growth);
  CHECK(est_growth / true_growth > 0.67);
  CHECK(est_growth / true_growth < 1.5);

  // Push an interior vertex towards the centre of a face of one of its tets: its tets
  // flatten and both kappas grow by orders of magnitude, together.
  TetMesh bad = make_box(Vec3(1, 1, 1), {3, 3, 3});
  VertexId v;
  for (VertexId u : bad.vertices())
    if ((bad.rest(u) - Vec3(1.0 / 3, 1.0 / 3, 1.0 / 3)).norm() < 1e-9) v = u;
  REQUIRE(v.is_valid());
  const double k0 = laplacian_spectrum(bad).kappa, e0 = estimate_solver(bad).kappa_laplace;
  TetId t = bad.incident_tets(v)[0];
  int lv = bad.local_index(t, v);
  Vec3 centroid = Vec3::Zero();
  for (int k = 0; k < 4; ++k)
    if (k != lv) centroid += bad.rest(bad.tet_vertices(t)[k]) / 3;
  bad.set_rest(v, bad.rest(v) + 0.999 * (centroid - bad.rest(v)));
  bool any_inverted = false;
  for (TetId u : bad.incident_tets(v)) any_inverted |= bad.volume(u) <= 0;
  if (!any_inverted) {
    const double k1 = laplacian_spectrum(bad).kappa, e1 = estimate_solver(bad).kappa_laplace;
    INFO("true " << k0 << " -> " << k1 << ", estimate " << e0 << " -> " << e1);
    CHECK(k1 > 10 * k0);
    CHECK(e1 / e0 > 0.2 * (k1 / k0));
    CHECK(e1 / e0 < 20 * (k1 / k0));
    CHECK(estimate_solver(bad).lambda_max_vertex.is_valid());
  } else {
    SUCCEED("moving the vertex inverted a tet; covered by the degenerate case below");
  }
}

TEST_CASE("condition estimate refuses degenerate meshes and bad options", "[quality][conditioning]") {
  TetMesh empty;
  CHECK_FALSE(estimate_solver(empty).available);
  TetMesh m;
  VertexId a = m.add_vertex(Vec3(0, 0, 0)), b = m.add_vertex(Vec3(1, 0, 0)), c = m.add_vertex(Vec3(0, 1, 0)),
           d = m.add_vertex(Vec3(0.3, 0.3, 0));
  m.add_tet(a, b, c, d);
  SolverEstimate e = estimate_solver(m);
  CHECK_FALSE(e.available);
  CHECK_THAT(e.reason, Catch::Contains("degenerate"));
  SolverEstimateOptions o;
  o.poisson_ratio = 0.5;
  CHECK_THROWS_AS(estimate_solver(m, o), InvalidArgument);
  o.poisson_ratio = 0.3;
  o.tolerance = 0;
  CHECK_THROWS_AS(estimate_solver(m, o), InvalidArgument);
}
