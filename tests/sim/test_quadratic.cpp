// Quadratic tets (10 nodes, sim/fem/quadratic_solver.h) and Taylor-Hood against answers computed
// another way: the exact integrals of the element, the patch test (P2 reproduces a quadratic
// displacement field exactly), beam theory, and the linear path's own solvers.
#include <catch2/catch.hpp>

#include <cmath>

#include "mesh/generate.h"
#include "sim/fem/fem_simulation.h"
#include "sim/fem/p2_element.h"
#include "sim/fem/quadratic_solver.h"
#include "testing/mesh_edits.h"

using namespace incise;

namespace {

// u(x) = s (x^2 + y, y z, x y + z^2 / 2): quadratic; div u = s (2 x + z + z), grad div = s (2, 0, 2),
// laplacian u = s (2, 0, 1); body force b = -div sigma = -((lambda + mu) grad div u + mu laplacian u).
constexpr double kScale = 1e-3;
Vec3 quadratic_field(const Vec3& p) {
  const double x = p.x(), y = p.y(), z = p.z();
  return kScale * Vec3(x * x + y, y * z, x * y + z * z / 2);
}
Vec3 quadratic_body_force(double mu, double lambda) {
  return -kScale * ((lambda + mu) * Vec3(2, 0, 2) + mu * Vec3(2, 0, 1));
}
Vec3 linear_field(const Vec3& p) { return 1e-3 * Vec3(p.x() + 2 * p.y(), -p.z(), 0.5 * p.x() + p.z()); }

// Holds every boundary node (corner and mid-edge) at field(x); returns the max error over all nodes.
template <class Field>
double patch_error(const TetMesh& m, QuadraticSolver& qs, Field field, const Vec3& g) {
  const P2Mesh& p2 = qs.p2();
  const auto on = incise::testing::boundary_vertices(m);
  const auto dofs = Eigen::Index(qs.num_dofs());
  std::vector<std::uint8_t> free(std::size_t(dofs), 1);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(dofs);
  auto hold = [&](std::size_t n) {
    for (int k = 0; k < 3; ++k) free[3 * n + std::size_t(k)] = 0;
    x.segment<3>(3 * Eigen::Index(n)) = field(p2.rest(m, n));
  };
  for (std::size_t v = 0; v < p2.corner_slots; ++v)
    if (on[v]) hold(v);
  for (std::size_t e = 0; e < p2.edges.size(); ++e)
    if (on[p2.edges[e][0]] && on[p2.edges[e][1]]) hold(p2.corner_slots + e);  // boundary edges (and chords, held exactly too)
  const QuadraticStats st = qs.solve(0, 1, qs.body_force(g), free, x);
  REQUIRE(st.converged);
  double err = 0;
  for (std::size_t n = 0; n < p2.num_nodes(); ++n) err = std::max(err, (x.segment<3>(3 * Eigen::Index(n)) - field(p2.rest(m, n))).norm());
  return err;
}

TetMesh jittered_box() {
  TetMesh m = make_box(Vec3(2, 1, 1.5), {4, 3, 3});
  incise::testing::jitter(m, 0.25, 7);
  return m;
}

}  // namespace

TEST_CASE("p2 element: the consistent mass and loads integrate the shape functions exactly", "[quadratic]") {
  const auto& m = p2_unit_mass();
  CHECK(m.sum() == Approx(1.0).epsilon(1e-14));  // int 1 = V
  double w = 0;
  for (int a = 0; a < 10; ++a) {
    CHECK(m.row(a).sum() == Approx(p2_load_weight(a)).epsilon(1e-13));  // int N_a = sum_b int N_a N_b
    w += p2_load_weight(a);
  }
  CHECK(w == Approx(1.0));
  // Known entries (e.g. Zienkiewicz): corner-corner 6/420, corner-own-edge -4/420, mid-mid diagonal 32/420.
  CHECK(m(0, 0) == Approx(6.0 / 420));
  CHECK(m(0, 4) == Approx(-4.0 / 420));
  CHECK(m(4, 4) == Approx(32.0 / 420));
  CHECK(m.isApprox(m.transpose()));
  // Rigid motions are in the stiffness' kernel, and the stiffness is symmetric.
  const P2Tet t = make_p2_tet({Vec3(0, 0, 0), Vec3(1.2, 0.1, 0), Vec3(0.2, 0.9, 0.1), Vec3(0.1, 0.3, 1.1)});
  const P2Matrix k = p2_stiffness(t, 3.0, 5.0);
  CHECK((k - k.transpose()).norm() <= 1e-12 * k.norm());
  Eigen::Matrix<double, 30, 1> rot;
  const std::array<Vec3, 10> x{Vec3(0, 0, 0), Vec3(1.2, 0.1, 0), Vec3(0.2, 0.9, 0.1), Vec3(0.1, 0.3, 1.1),
                               Vec3(0.6, 0.05, 0), Vec3(0.7, 0.5, 0.05), Vec3(0.1, 0.45, 0.05), Vec3(0.05, 0.15, 0.55),
                               Vec3(0.65, 0.2, 0.55), Vec3(0.15, 0.6, 0.6)};
  for (int a = 0; a < 10; ++a) rot.segment<3>(3 * a) = Vec3(0.3, -0.2, 1).cross(x[std::size_t(a)]);
  CHECK((k * rot).norm() <= 1e-12 * k.norm());
}

TEST_CASE("quadratic patch test: a quadratic field with its body force is reproduced exactly", "[quadratic]") {
  const TetMesh m = jittered_box();
  const Material mat{1e4, 0.3, 1};  // density 1: body_force(g) is the force density itself
  for (const bool th : {false, true})
    for (const bool direct : {true, false}) {
      QuadraticOptions o;
      o.taylor_hood = th;
      o.direct = direct;
      o.tolerance = 1e-13;
      o.preconditioner = Preconditioner::Cholesky;
      QuadraticSolver qs(m, MixedMaterials(mat), FemKind::Linear, o);
      INFO("taylor-hood " << th << ", direct " << direct);
      CHECK(patch_error(m, qs, quadratic_field, quadratic_body_force(mat.mu(), mat.lambda())) <= 1e-10 * kScale);
      CHECK(patch_error(m, qs, linear_field, Vec3::Zero()) <= 1e-12);
      if (th) {
        // Taylor-Hood's pressure is lambda div u, linear here: exact at the vertices too.
        for (VertexId v : m.vertices()) CHECK(qs.pressure()[v.idx()] == Approx(mat.lambda() * 1e-3 * (1 + 1)).epsilon(1e-9));
      }
    }
  // CG with each preconditioner that applies.
  for (const Preconditioner pc : {Preconditioner::Jacobi, Preconditioner::BlockJacobi, Preconditioner::None}) {
    QuadraticOptions o;
    o.direct = false;
    o.preconditioner = pc;
    o.tolerance = 1e-13;
    QuadraticSolver qs(m, MixedMaterials(mat), FemKind::Linear, o);
    CHECK(patch_error(m, qs, quadratic_field, quadratic_body_force(mat.mu(), mat.lambda())) <= 1e-9 * kScale);
  }
}
