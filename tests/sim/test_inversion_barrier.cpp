// The inversion barrier (sim/fem/inversion_barrier.h): its terms against finite differences of its
// energy, the matrix-free product against the assembled matrix, and a frame that keeps a tet
// from inverting where the plain corotational element lets it.
#include <catch2/catch.hpp>

#include <random>

#include <tbb/global_control.h>

#include "mesh/generate.h"
#include "sim/fem/fem_model.h"
#include "sim/fem/fem_simulation.h"
#include "tests/sim/fem_test_util.h"

using namespace incise;
using namespace incise::testing;

namespace {

double volume_ratio(const TetMesh& m, TetId t, const Eigen::VectorXd& u) {
  const auto& v = m.tet_vertices(t);
  auto x = [&](int k) { return Vec3(m.rest(v[k]) + u.segment<3>(3 * v[k].idx())); };
  Eigen::Matrix3d d, dr;
  for (int k = 1; k < 4; ++k) {
    d.col(k - 1) = x(k) - x(0);
    dr.col(k - 1) = m.rest(v[k]) - m.rest(v[0]);
  }
  return d.determinant() / dr.determinant();
}

}  // namespace

TEST_CASE("inversion barrier: terms, product and assembly agree with its energy", "[sim][barrier]") {
  TetMesh mesh = make_box(Vec3(2, 2, 2), {2, 2, 2});
  const MaterialTable mat = table(1000, 0.3);
  const InversionBarrierOptions opt{.j_min = 0.4, .stiffness = 50};
  FemModel held(mesh, mat, FemKind::Corotational), plain(mesh, mat, FemKind::Corotational);
  held.set_inversion_barrier(opt);
  // The centre vertex pushed down through the tets below it, and a little noise.
  Eigen::VectorXd u = Eigen::VectorXd::Zero(held.rows());
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> noise(-0.02, 0.02);
  for (VertexId v : mesh.vertices()) {
    for (int a = 0; a < 3; ++a) u[3 * v.idx() + a] = noise(rng);
    if ((mesh.rest(v) - Vec3(1, 1, 1)).norm() < 1e-9) u[3 * v.idx() + 2] = -1.2;
  }
  held.update_rotations(u);
  plain.update_rotations(u);
  std::vector<TetId> below;
  for (TetId t : mesh.tets())
    if (volume_ratio(mesh, t, u) < opt.j_min) below.push_back(t);
  REQUIRE(!below.empty());
  CHECK(held.inversion_barrier().held() == below.size());

  // The barrier's force at u is -dE/du of E = sum k V (j_min - J)^2 over the held tets.
  auto energy = [&](const Eigen::VectorXd& w) {
    double e = 0;
    for (TetId t : below) {
      const double k = opt.stiffness * (mat.get(mesh.label(t)).lambda() + 2 * mat.get(mesh.label(t)).mu()) * mesh.volume(t);
      e += k * std::pow(opt.j_min - volume_ratio(mesh, t, w), 2);
    }
    return e;
  };
  Eigen::VectorXd fh, fp;
  held.internal_forces(u, fh);
  plain.internal_forces(u, fp);
  const Eigen::VectorXd barrier_force = fh - fp;
  double worst = 0, scale = barrier_force.cwiseAbs().maxCoeff();
  REQUIRE(scale > 0);
  const double h = 1e-6;
  for (Eigen::Index i = 0; i < u.size(); ++i) {
    Eigen::VectorXd a = u, b = u;
    a[i] += h;
    b[i] -= h;
    worst = std::max(worst, std::abs(-(energy(a) - energy(b)) / (2 * h) - barrier_force[i]));
  }
  CHECK(worst < 1e-5 * scale);

  // f_int(u) = b - K u with the barrier in both, the product equals the assembled matrix, and K
  // stays symmetric.
  Eigen::VectorXd b = Eigen::VectorXd::Zero(held.rows()), ku;
  held.add_rotation_rhs(b);
  held.multiply(u, ku);
  CHECK((fh - (b - ku)).norm() <= 1e-9 * fh.norm());
  const Eigen::SparseMatrix<double> k = held.assemble(), kp = plain.assemble();
  Eigen::VectorXd x = Eigen::VectorXd::Random(held.rows()), y;
  held.multiply(x, y);
  CHECK((y - k * x).norm() <= 1e-10 * y.norm());
  CHECK((k - Eigen::SparseMatrix<double>(k.transpose())).norm() <= 1e-12 * k.norm());
  CHECK((k - kp).norm() > 0);
}

TEST_CASE("inversion barrier: a pressed tet stays the right way out", "[sim][barrier]") {
  // A box fixed at its base, its top's middle vertex pushed down by a point force: the tets
  // under it invert at the plain corotational equilibrium (docs/solver.md#inversion-barrier-inversion_barrier-in-scenes);
  // held, none does, and the smallest volume ratio is near j_min.
  TetMesh mesh = make_box(Vec3(2, 2, 2), {2, 2, 2});
  const double force = 2000;  // twice E on cells of 1: far past what the plain tets resist
  double smallest = 1;
  auto run = [&](double j_min) {
    FemSimulationOptions o;
    o.kind = FemKind::Corotational;
    o.nonlinear_iterations = 2;
    o.cg.tolerance = 1e-10;
    o.inversion_barrier.j_min = j_min;
    FemSimulation sim(mesh, table(1000, 0.3), o);
    for (VertexId v : mesh.vertices()) {
      if (mesh.rest(v).z() < 1e-9) sim.fix(v);
      if ((mesh.rest(v) - Vec3(1, 1, 2)).norm() < 1e-9) sim.set_force(v, Vec3(0, 0, -force));
    }
    for (int f = 0; f < 6; ++f) sim.step();
    int inverted = 0;
    double jmin = 1;
    for (TetId t : mesh.tets()) {
      inverted += volume_ratio(mesh, t, sim.displacement()) <= 0;
      jmin = std::min(jmin, volume_ratio(mesh, t, sim.displacement()));
    }
    smallest = jmin;
    return inverted;
  };
  CHECK(run(0) > 0);
  CHECK(run(0.2) == 0);
  CHECK(smallest > 0.1);
  FemSimulationOptions linear;
  linear.inversion_barrier.j_min = 0.2;
  CHECK_THROWS_AS(FemSimulation(mesh, table(1000, 0.3), linear), InvalidArgument);  // linear elements: refused
}

TEST_CASE("inversion barrier: the product is the same on every run", "[sim][barrier]") {
  // Thousands of held tets across the threads' chunks (a box squashed to a fifth of its height,
  // with noise), on a fresh model each run (rotations are warm-started from the last call): the
  // held tets' terms are summed in tet order, not in the order the threads happened to find
  // them, so a scene gives the same frames however busy the machine (the README's first scene
  // once kept a tet inverted for ten frames on one run, for one on another).
  const TetMesh mesh = make_box(Vec3(2, 2, 2), {12, 12, 12});
  Eigen::VectorXd u = Eigen::VectorXd::Zero(3 * Eigen::Index(mesh.vertex_capacity()));
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> noise(-0.01, 0.01);
  for (VertexId v : mesh.vertices()) {
    for (int a = 0; a < 3; ++a) u[3 * v.idx() + a] = noise(rng);
    u[3 * v.idx() + 2] -= 0.8 * mesh.rest(v).z();
  }
  const Eigen::VectorXd x = Eigen::VectorXd::Random(u.size());
  std::size_t held_tets = 0;
  auto product = [&] {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 4);
    FemModel held(mesh, table(1000, 0.3), FemKind::Corotational);
    held.set_inversion_barrier(InversionBarrierOptions{.j_min = 0.4, .stiffness = 50});
    held.update_rotations(u);
    Eigen::VectorXd y;
    held.multiply(x, y);
    held_tets = held.inversion_barrier().held();
    return y;
  };
  const Eigen::VectorXd first = product();
  REQUIRE(held_tets > 2000);
  for (int run = 0; run < 8; ++run) {
    const Eigen::VectorXd again = product();
    INFO("run " << run << ": largest difference " << (again - first).cwiseAbs().maxCoeff() << " of "
                << first.cwiseAbs().maxCoeff());
    CHECK(again == first);
  }
}
