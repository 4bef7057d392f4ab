// Nodal-averaged (average nodal pressure) tets, Formulation::NodalAveraged: patch test, the
// matrix-free product and the per-vertex blocks against the assembled matrix, CG with every
// preconditioner against the direct solve, local updates after edits and cuts against a fresh
// model (and their locality), the cantilever against Timoshenko beam theory as Poisson's ratio
// nears 0.5, and the volume change of a compressed block going to zero.
#include <catch2/catch.hpp>

#include <cmath>
#include <random>

#include "mesh/errors.h"
#include "mesh/generate.h"
#include "sim/fem/fem_model.h"
#include "sim/fem/fem_simulation.h"
#include "tests/sim/fem_test_util.h"

using namespace incise;
using namespace incise::testing;
using namespace incise::testing::smoothed;

namespace {

constexpr Formulation kNodal = Formulation::NodalAveraged;

}  // namespace

TEST_CASE("nodal-averaged: the mixed formulation is refused, the standard one unchanged", "[fem][nodal]") {
  TetMesh m = make_box(Vec3(1, 1, 1), {2, 2, 2});
  CHECK_THROWS_AS(FemModel(m, table(1e5, 0.3), FemKind::Linear, Formulation::Mixed), InvalidArgument);
  const FemModel s(m, table(1e5, 0.3)), n(m, table(1e5, 0.3), FemKind::Linear, kNodal);
  CHECK(s.formulation() == Formulation::Standard);
  CHECK(n.nodal_averaged());
  CHECK(s.nodal_b().rows() == 0);
  std::mt19937 rng(1);
  const Eigen::VectorXd x = random_vector(s.rows(), rng);
  Eigen::VectorXd ys, yn;
  s.multiply(x, ys);
  n.multiply(x, yn);
  CHECK((ys - yn).norm() > 1e-3 * ys.norm());  // a different operator
}

TEST_CASE("nodal-averaged: patch test, an affine field is reproduced exactly", "[fem][nodal][verification]") {
  for (FemKind kind : {FemKind::Linear, FemKind::Corotational})
    for (double nu : {0.3, 0.49, 0.4999}) {
      INFO("kind " << int(kind) << ", nu " << nu);
      // The corotational frames re-linearize without geometric stiffness: the fixed-point
      // iteration contracts only while the pressure is small against mu (at nu = 0.4999 this
      // field's pressure is ~25 mu, and the iterates stall near 4e-4). There the discrete
      // equilibrium (no internal force at interior vertices) is the patch test.
      const bool solve = kind == FemKind::Linear || nu <= 0.49;
      check_affine_patch(kNodal, kind, nu, solve, [&](FemModel& model, const Eigen::VectorXd& u, const Eigen::Matrix3d& a) {
        if (kind != FemKind::Linear) return;
        // Every tet carries the same pressure, kappa tr(eps).
        const Material mat{1e5, nu, 1000};
        const double expected = (mat.lambda() + 2 * mat.mu() / 3) * a.trace();
        const std::vector<double> p = model.pressure(u);
        for (TetId t : model.mesh().tets()) REQUIRE(p[t.idx()] == Approx(expected).epsilon(1e-9));
      });
    }
}

TEST_CASE("nodal-averaged: K x, diagonal, blocks, b_R and f_int match the assembled matrix", "[fem][nodal]") {
  TetMesh m = two_label_box();
  std::mt19937 rng(3);
  for (FemKind kind : {FemKind::Linear, FemKind::Corotational}) {
    INFO("kind " << int(kind));
    FemModel model(m, two_materials(), kind, kNodal);
    const Eigen::VectorXd u = random_vector(model.rows(), rng, 0.2);  // large rotations
    model.update_rotations(u);
    const Eigen::SparseMatrix<double> k = model.assemble();
    CHECK((Eigen::SparseMatrix<double>(k.transpose()) - k).norm() <= 1e-12 * k.norm());
    const Eigen::VectorXd x = random_vector(model.rows(), rng);
    Eigen::VectorXd y;
    model.multiply(x, y);
    CHECK((y - k * x).norm() <= 1e-12 * y.norm());
    CHECK((model.diagonal() - Eigen::VectorXd(k.diagonal())).norm() <= 1e-12 * model.diagonal().norm());
    const Eigen::MatrixXd dense(k);
    for (VertexId v : m.vertices())
      REQUIRE((model.diagonal_blocks()[v.idx()] - dense.block<3, 3>(3 * v.idx(), 3 * v.idx())).norm() <=
              1e-12 * dense.block<3, 3>(3 * v.idx(), 3 * v.idx()).norm());
    // The element snapshot the Cholesky factors: deviatoric blocks + B^T B is K.
    const FemElements e = model.elements();
    Eigen::MatrixXd ke = Eigen::MatrixXd(Eigen::SparseMatrix<double>(e.nodal_b.transpose()) * Eigen::SparseMatrix<double>(e.nodal_b));
    for (std::size_t t = 0; t < e.alive.size(); ++t)
      if (e.alive[t])
        for (int i = 0; i < 4; ++i)
          for (int j = 0; j < 4; ++j) ke.block<3, 3>(3 * e.verts[t][i], 3 * e.verts[t][j]) += e.block(t, i, j);
    CHECK((ke - dense).norm() <= 1e-12 * dense.norm());
    // f_int(u) = -(K_R u - b_R) with the rotations of u.
    Eigen::VectorXd f, b = Eigen::VectorXd::Zero(model.rows());
    model.internal_forces(u, f);
    model.add_rotation_rhs(b);
    CHECK((f + k * u - b).norm() <= 1e-11 * f.norm());
    // The pattern reaches the 2-ring: wider than the standard element's.
    const FemModel standard(m, two_materials(), kind);
    CHECK(k.nonZeros() > standard.assemble().nonZeros());
  }
}

TEST_CASE("nodal-averaged: CG with every preconditioner equals the direct solution", "[fem][nodal][preconditioner][long]") {
  check_cg_equals_direct(kNodal, true);
}

TEST_CASE("nodal-averaged: through cuts, CG with the stale factor and the patched multigrid equals the direct solution",
          "[fem][nodal][preconditioner][cut]") {
  check_cuts_equal_direct(kNodal);
}

TEST_CASE("nodal-averaged: the locally updated model equals a fresh one after edits and cuts", "[fem][nodal][local]") {
  check_local_updates(kNodal);
}

TEST_CASE("nodal-averaged: work per local update does not grow with mesh size", "[fem][nodal][local][locality]") {
  const WorkPerUpdate w6 = work_per_local_update(kNodal, 6), w30 = work_per_local_update(kNodal, 30);  // 1.3k, 162k tets
  const std::array<double, 3> small{w6.tets, w6.vertices, w6.blocks}, large{w30.tets, w30.vertices, w30.blocks};
  WARN("per update (1.3k vs 162k tets): tets " << small[0] << " vs " << large[0] << ", vertices " << small[1]
                                               << " vs " << large[1] << ", 1-ring blocks " << small[2] << " vs "
                                               << large[2]);
  for (int i = 0; i < 3; ++i) CHECK(large[std::size_t(i)] < 1.5 * small[std::size_t(i)]);
  CHECK(large[2] > 0);
  CHECK(large[2] < 200);  // a 1-ring, not the mesh
}

TEST_CASE("nodal-averaged: no volumetric locking in the cantilever, and the bending error left converges with h",
          "[fem][nodal][verification][long][scale]") {
  // Measured (bench_fem_locking), error against Timoshenko at nu = 0.3 / 0.45 / 0.49 / 0.4999:
  //   standard        40x4x4  -21.3 / -40.2 / -71.2 / -98.6 %   80x8x8  -7.0 / -16.4 / -41.9 / -97.2 %
  //   nodal-averaged  40x4x4  -12.3 / -15.1 / -16.9 / -20.9 %   80x8x8  -4.0 /  -5.6 /  -6.4 /  -7.0 %
  //                                                           120x12x12 -2.2 / -3.5 / -4.1 / -4.4 %
  // The 5% target is met from 120x12x12 (17 s a solve: the hidden test below), not at 80x8x8
  // above nu = 0.3: linear tets are also too stiff in bending (their constant strain cannot
  // bend; standard tets at nu = 0.3 are 7.0% too stiff at 80x8x8), which no volumetric
  // treatment removes. The nodal-averaged error at nu = 0.4999 equals the standard one at 0.3,
  // and it falls ~3x per halving of h at every nu (the standard one at 0.4999 does not move).
  double coarse_std = 0;
  for (double nu : {0.3, 0.45, 0.49, 0.4999}) {
    const Cantilever s40 = cantilever(40, nu, Formulation::Standard);
    const Cantilever n40 = cantilever(40, nu, kNodal);
    const Cantilever n80 = cantilever(80, nu, kNodal);
    WARN("nu " << nu << ": standard 40x4x4 " << 100 * s40.error() << "%, nodal-averaged 40x4x4 " << 100 * n40.error()
               << "%, 80x8x8 " << 100 * n80.error() << "%");
    CHECK(n80.error() < 0);                      // still on the stiff side (bending)
    CHECK(std::abs(n80.error()) <= 0.075);       // measured 4.0 - 7.0%
    CHECK(std::abs(n40.error()) >= 2.5 * std::abs(n80.error()));  // converging with h (measured 2.6 - 3.1x)
    CHECK(std::abs(n40.error()) < 0.6 * std::abs(s40.error()));
    if (nu == 0.3) {
      CHECK(std::abs(n80.error()) <= 0.05);
      coarse_std = std::abs(s40.error());
    }
    // No locking: at nu -> 0.5 no stiffer than the standard element at nu = 0.3.
    CHECK(std::abs(n40.error()) <= coarse_std);
  }
}

TEST_CASE("nodal-averaged: 120x12x12 cantilever within 5% of Timoshenko at nu = 0.4999", "[long][fem][nodal][scale]") {
  const Cantilever n = cantilever(120, 0.4999, kNodal);
  WARN("120x12x12, nu 0.4999: nodal-averaged " << 100 * n.error() << "%");
  CHECK(std::abs(n.error()) <= 0.05);
}

TEST_CASE("nodal-averaged: a compressed block's volume change goes to zero as nu -> 0.5", "[fem][nodal][verification]") {
  // Unit cube, bottom face clamped, uniform pressure on the top face. The volume change is
  // sum_t V_t div_t(u) = sum_a V_a theta_a, exact for the piecewise-linear field.
  TetMesh m = make_box(Vec3(1, 1, 1), {6, 6, 6});
  auto run = [&](double nu) {
    FemSimulationOptions opt;
    opt.formulation = kNodal;
    opt.method = SolverMethod::Direct;
    FemSimulation sim(m, table(1e5, nu), opt);
    for (VertexId v : m.vertices())
      if (m.rest(v).z() < 1e-9) sim.fix(v);
    add_face_traction(m, sim, 2, 1.0, Vec3(0, 0, -1e3), 1e-9);
    REQUIRE(sim.step().info == SolveInfo::Success);
    const Eigen::VectorXd& u = sim.displacement();
    double dv = 0, top = 0;
    int count = 0;
    for (TetId t : m.tets()) {
      const auto& v = m.tet_vertices(t);
      Eigen::Matrix3d d0, d;
      for (int j = 0; j < 3; ++j) {
        d0.col(j) = m.rest(v[j + 1]) - m.rest(v[0]);
        d.col(j) = u.segment<3>(3 * v[j + 1].idx()) - u.segment<3>(3 * v[0].idx());
      }
      dv += (d * d0.inverse()).trace() * d0.determinant() / 6;
    }
    for (VertexId v : m.vertices())
      if (m.rest(v).z() > 1 - 1e-9) {
        top += u[3 * v.idx() + 2];
        ++count;
      }
    return std::pair<double, double>(dv, top / count);
  };
  const auto [dv3, top3] = run(0.3);
  double prev = std::abs(dv3);
  for (double nu : {0.45, 0.49, 0.499, 0.4999}) {
    const auto [dv, top] = run(nu);
    WARN("nu " << nu << ": volume change " << dv << " (nu 0.3: " << dv3 << "), top " << top << " (nu 0.3: " << top3
               << ")");
    CHECK(std::abs(dv) < prev);
    prev = std::abs(dv);
    // The compliance itself does not lock: the block still shortens (bulging sideways).
    CHECK(top < 0.3 * top3);  // both negative: at least 30% of the nu = 0.3 shortening
  }
  CHECK(prev <= 2e-3 * std::abs(dv3));
}
