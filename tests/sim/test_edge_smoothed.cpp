// Edge-smoothed tets (Formulation::EdgeSmoothed: deviatoric strain smoothed over the tets around
// each edge, volumetric strain averaged at the vertices): the matrix-free passes and the factored
// snapshot against the assembled matrix and its rigid modes, the energy below the per-tet
// element's, the patch test, CG with every preconditioner against the direct solve, local
// updates after edits and cuts against a fresh model and their locality, and the cantilever
// against Timoshenko beam theory.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "mesh/generate.h"
#include "sim/fem/edge_tet_lists.h"
#include "sim/fem/fem_model.h"
#include "sim/fem/fem_simulation.h"
#include "tests/sim/fem_test_util.h"

using namespace incise;
using namespace incise::testing;
using namespace incise::testing::smoothed;

namespace {
constexpr Formulation kEdge = Formulation::EdgeSmoothed;
}  // namespace

TEST_CASE("edge-smoothed: K x, b_R and f_int match the assembled matrix, which has the rigid modes as kernel",
          "[fem][edge]") {
  TetMesh m = two_label_box();
  std::mt19937 rng(3);
  for (FemKind kind : {FemKind::Linear, FemKind::Corotational}) {
    INFO("kind " << int(kind));
    FemModel model(m, two_materials(), kind, kEdge);
    FemModel nodal(m, two_materials(), kind, Formulation::NodalAveraged);
    CHECK(model.edge_smoothed());
    CHECK(model.nodal_averaged());
    CHECK_FALSE(nodal.edge_smoothed());
    CHECK(nodal.num_edges() == 0);
    // Edges of the box: each tet has 6; Euler's formula for a ball: V - E + F - T = 1.
    std::size_t faces = 0;
    for (TetId t : m.tets())
      for (int f = 0; f < 4; ++f) faces += !m.neighbor(t, f).is_valid() ? 2 : 1;
    CHECK(std::int64_t(m.num_vertices()) - std::int64_t(model.num_edges()) + std::int64_t(faces / 2) -
              std::int64_t(m.num_tets()) ==
          1);
    const Eigen::VectorXd u = random_vector(model.rows(), rng, 0.2);  // large rotations
    model.update_rotations(u);
    nodal.update_rotations(u);
    const Eigen::SparseMatrix<double> k = model.assemble();
    CHECK((Eigen::SparseMatrix<double>(k.transpose()) - k).norm() <= 1e-12 * k.norm());
    const Eigen::VectorXd x = random_vector(model.rows(), rng);
    Eigen::VectorXd y, yn;
    model.multiply(x, y);
    CHECK((y - k * x).norm() <= 1e-12 * y.norm());
    // The snapshot the background Cholesky factors (per-tet blocks + B^T B) is all of K, the
    // smoothed rows in B: the factor is exact.
    const FemElements e = model.elements();
    Eigen::MatrixXd ke =
        Eigen::MatrixXd(Eigen::SparseMatrix<double>(e.nodal_b.transpose()) * Eigen::SparseMatrix<double>(e.nodal_b));
    for (std::size_t t = 0; t < e.alive.size(); ++t)
      if (e.alive[t])
        for (int i = 0; i < 4; ++i)
          for (int j = 0; j < 4; ++j) ke.block<3, 3>(3 * e.verts[t][i], 3 * e.verts[t][j]) += e.block(t, i, j);
    CHECK((ke - Eigen::MatrixXd(k)).norm() <= 1e-12 * k.norm());
    // f_int(u) = -(K_R u - b_R) with the rotations of u.
    Eigen::VectorXd f, b = Eigen::VectorXd::Zero(model.rows());
    model.internal_forces(u, f);
    model.add_rotation_rhs(b);
    CHECK((f + k * u - b).norm() <= 1e-11 * f.norm());
    // Averaging strains over a domain lowers the quadratic energy (Jensen): below the per-tet
    // element's, which is what the preconditioners are built from.
    nodal.multiply(x, yn);
    CHECK(x.dot(y) < x.dot(yn));
    CHECK(x.dot(y) > 0.3 * x.dot(yn));
    if (kind == FemKind::Linear) {
      // Rigid motions store no energy: three translations and three infinitesimal rotations.
      for (int mode = 0; mode < 6; ++mode) {
        Eigen::VectorXd r = Eigen::VectorXd::Zero(model.rows());
        for (VertexId v : m.vertices()) {
          const Vec3 p = m.rest(v);
          r.segment<3>(3 * v.idx()) = mode < 3 ? Vec3(Vec3::Unit(mode)) : Vec3(Vec3::Unit(mode - 3).cross(p));
        }
        Eigen::VectorXd kr;
        model.multiply(r, kr);
        CHECK(kr.norm() <= 1e-10 * y.norm() * r.norm() / x.norm());
      }
    }
  }
}

TEST_CASE("edge-smoothed: the diagonal blocks the smoothers read are K's, exactly where each edge's tets share a rotation",
          "[fem][edge][preconditioner]") {
  TetMesh m = two_label_box();
  for (FemKind kind : {FemKind::Linear, FemKind::Corotational}) {
    INFO("kind " << int(kind));
    FemModel model(m, two_materials(), kind, kEdge);
    // Linear: no rotation. Corotational: the whole body turned by 70 degrees (every tet the
    // same R), so K = R K0 R^T blockwise and its diagonal blocks are the smoothed ones rotated.
    Eigen::VectorXd u = Eigen::VectorXd::Zero(model.rows());
    const Eigen::Matrix3d r = Eigen::AngleAxisd(1.2, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    for (VertexId v : m.vertices()) u.segment<3>(3 * v.idx()) = r * m.rest(v) - m.rest(v);
    model.update_rotations(u);
    const Eigen::MatrixXd k = Eigen::MatrixXd(model.assemble());
    double worst = 0, scale = 0;
    for (VertexId v : m.vertices()) {
      const Eigen::Matrix3d kb = k.block<3, 3>(3 * v.idx(), 3 * v.idx());
      worst = std::max(worst, (model.diagonal_blocks()[v.idx()] - kb).norm());
      scale = std::max(scale, kb.norm());
      REQUIRE(model.diagonal()(3 * v.idx()) == Approx(kb(0, 0)).epsilon(1e-12));
    }
    CHECK(worst <= 1e-12 * scale);
  }
}

TEST_CASE("edge-smoothed: patch test, an affine field is reproduced exactly, with its stress", "[fem][edge][verification]") {
  for (FemKind kind : {FemKind::Linear, FemKind::Corotational})
    for (double nu : {0.3, 0.49}) {
      INFO("kind " << int(kind) << ", nu " << nu);
      check_affine_patch(kEdge, kind, nu, true, [&](FemModel& model, const Eigen::VectorXd& u, const Eigen::Matrix3d& a) {
        if (kind != FemKind::Linear) return;
        // Every tet carries the field's stress: von Mises of 2 mu dev(eps) (the pressure adds none).
        const Material mat{1e5, nu, 1000};
        const Eigen::Matrix3d eps = 0.5 * (a + a.transpose());
        const Eigen::Matrix3d dev = eps - eps.trace() / 3 * Eigen::Matrix3d::Identity();
        const double expected = von_mises_of(2 * mat.mu() * dev);
        const std::vector<double> vm = model.von_mises(u);
        for (TetId t : model.mesh().tets()) REQUIRE(vm[t.idx()] == Approx(expected).epsilon(1e-9));
      });
    }
}

TEST_CASE("edge-smoothed: CG with every preconditioner equals the direct solution", "[fem][edge][preconditioner][long]") {
  // A coarser box than nodal-averaged's (12 x 3 x 3): the smoothed product is the dearest, and
  // this runs instrumented in CI too (224 s there on 16 x 4 x 4 with a busy machine).
  check_cg_equals_direct(kEdge, false, 12);
}

TEST_CASE("edge-smoothed: through cuts, CG with the stale factor and the patched multigrid equals the direct solution",
          "[fem][edge][preconditioner][cut]") {
  check_cuts_equal_direct(kEdge);
}

TEST_CASE("edge-smoothed: the locally updated model equals a fresh one after edits and cuts", "[fem][edge][local]") {
  check_local_updates(kEdge);
}

TEST_CASE("edge-smoothed: work per local update does not grow with mesh size", "[fem][edge][local][locality]") {
  const WorkPerUpdate w6 = work_per_local_update(kEdge, 6), w30 = work_per_local_update(kEdge, 30);  // 1.3k, 162k tets
  const std::array<double, 2> small{w6.tets, w6.edges}, large{w30.tets, w30.edges};
  WARN("per update (1.3k vs 162k tets): tets " << small[0] << " vs " << large[0] << ", edges " << small[1] << " vs "
                                               << large[1]);
  for (int i = 0; i < 2; ++i) CHECK(large[std::size_t(i)] < 1.5 * small[std::size_t(i)]);
  CHECK(large[1] > 0);
  CHECK(large[1] < 100);  // the edited tets' edges, not the mesh's
}

TEST_CASE("edge-smoothed: the cantilever within 5% of Timoshenko at 80x8x8 for every nu, converging with h",
          "[fem][edge][verification][long][scale]") {
  // Measured (bench_fem_locking), error against Timoshenko at nu = 0.3 / 0.45 / 0.49 / 0.4999:
  //   nodal-averaged 40x4x4 -12.3 / -15.1 / -16.9 / -20.9 %   80x8x8 -4.0 / -5.6 / -6.4 / -7.0 %
  //   edge-smoothed  40x4x4  +1.4 /  -1.5 /  -3.1 /  -7.7 %   80x8x8 -0.03 / -1.5 / -2.2 / -2.7 %
  // Smoothing the deviatoric strain over edges removes most of linear tets' bending stiffness;
  // the volumetric averaging removes the locking.
  for (double nu : {0.3, 0.45, 0.49, 0.4999}) {
    const Cantilever e40 = cantilever(40, nu, kEdge), n40 = cantilever(40, nu, Formulation::NodalAveraged);
    WARN("nu " << nu << ": 40x4x4 edge-smoothed " << 100 * e40.error() << "%, nodal-averaged " << 100 * n40.error() << "%");
    CHECK(std::abs(e40.error()) < std::abs(n40.error()));
    CHECK(std::abs(e40.error()) <= 0.08);
  }
  const Cantilever e80 = cantilever(80, 0.4999, kEdge);
  WARN("80x8x8, nu 0.4999: edge-smoothed " << 100 * e80.error() << "%");
  CHECK(std::abs(e80.error()) <= 0.05);
  CHECK(std::abs(e80.error()) < 0.5 * std::abs(cantilever(40, 0.4999, kEdge).error()));  // converging
}

TEST_CASE("nodal-averaged and edge-smoothed: the fused products equal the assembled matrix in parallel, both kernel paths",
          "[fem][edge][nodal]") {
  // Above the kernel's serial threshold (coloured sweeps on several threads), with the AVX2 and
  // the portable sweeps; standard tets with smoothed edges are the displacement block of the
  // mixed edge-smoothed variant (no nodal pressure in its product).
  TetMesh m = make_box(Vec3(4, 2, 2), {20, 10, 8});
  jitter(m, 0.25, 9);
  for (TetId t : m.tets())
    if (t.idx() % 5 == 0) m.set_label(t, 2);
  std::mt19937 rng(4);
  const std::pair<Formulation, bool> variants[] = {
      {Formulation::NodalAveraged, false}, {kEdge, false}, {Formulation::Standard, true}};
  for (const auto& [f, smooth] : variants)
    for (FemKind kind : {FemKind::Linear, FemKind::Corotational}) {
      FemModel model(m, two_materials(), kind, f, smooth);
      model.update_rotations(random_vector(model.rows(), rng, 0.2));
      const Eigen::SparseMatrix<double> k = model.assemble();
      const Eigen::VectorXd x = random_vector(model.rows(), rng);
      for (bool simd : {true, false}) {
        INFO(formulation_name(f) << (smooth ? " smoothed" : "") << " kind " << int(kind) << " simd " << simd);
        model.set_kernel_simd(simd);
        Eigen::VectorXd y;
        model.multiply(x, y);
        CHECK((y - k * x).norm() <= 1e-12 * y.norm());
      }
    }
}

// The per-edge tet lists: short lists in their records, long ones spilled to a list of their own
// and back, the same tets in the same order as a plain vector with the same edits (push at the
// back, removal by swapping the last in).
TEST_CASE("edge tet lists keep a vector's order through spills and removals", "[edge-smoothed]") {
  EdgeTetLists lists;
  std::vector<std::vector<std::uint32_t>> plain;
  std::mt19937 rng(3);
  const std::size_t edges = 40;
  for (std::size_t e = 0; e < edges; ++e) {
    lists.add_edge();
    plain.emplace_back();
  }
  std::uint32_t next = 0;
  for (int round = 0; round < 4000; ++round) {
    const std::size_t e = rng() % edges;
    // Grow up to twice the inline size, then shrink: every edge crosses the spill both ways.
    const bool add = plain[e].empty() || (plain[e].size() < 2 * EdgeTetLists::kInline && rng() % 5 < 3);
    if (add) {
      lists.push(e, next);
      plain[e].push_back(next++);
    } else {
      const std::uint32_t t = plain[e][rng() % plain[e].size()];
      lists.remove(e, t);
      auto it = std::find(plain[e].begin(), plain[e].end(), t);
      *it = plain[e].back();
      plain[e].pop_back();
    }
    const auto got = lists[e];
    REQUIRE(std::vector<std::uint32_t>(got.begin(), got.end()) == plain[e]);
    REQUIRE(lists.empty(e) == plain[e].empty());
  }
  std::size_t spilled = 0;
  for (std::size_t e = 0; e < edges; ++e) {
    const auto got = lists[e];
    CHECK(std::vector<std::uint32_t>(got.begin(), got.end()) == plain[e]);
    spilled += plain[e].size() > EdgeTetLists::kInline;
  }
  CHECK(spilled > 0);
  lists.remove(0, 0xffffffffu);  // not there: nothing
  const auto got = lists[0];
  CHECK(std::vector<std::uint32_t>(got.begin(), got.end()) == plain[0]);
}
