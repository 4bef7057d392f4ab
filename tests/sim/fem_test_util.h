#pragma once
// Helpers shared by the FEM tests: loads on box faces, fixed ends, a run checked against the
// direct solution (random edits and jitter come from
// tests/support/mesh_edits.h).
#include <catch2/catch.hpp>

#include <cmath>
#include <random>
#include <vector>

#include "mesh/generate.h"
#include "mesh/tet_mesh.h"
#include "sim/fem_simulation.h"
#include "tests/support/mesh_edits.h"

namespace incise::testing {

using incise::testing::boundary_vertices;
using incise::testing::jitter;
using incise::testing::random_edit;

// A random residual on the free unknowns, zero on kept ones (for checking M^-1 as CG uses it).
inline Eigen::VectorXd random_free_residual(const std::vector<std::uint8_t>& free, std::mt19937& rng) {
  std::normal_distribution<double> g;
  Eigen::VectorXd r(Eigen::Index(free.size()));
  for (Eigen::Index i = 0; i < r.size(); ++i) r[i] = free[std::size_t(i)] ? g(rng) : 0.0;
  return r;
}
using incise::testing::random_tet;

// One material for every label (E, nu, density).
inline MaterialTable table(double e, double nu, double rho = 1000) { return MaterialTable(Material{e, nu, rho}); }

// Consistent nodal forces of a uniform traction on the boundary faces lying in the plane
// x[axis] == value: each triangle gives traction * area / 3 to each of its corners.
inline void add_face_traction(const TetMesh& m, FemSimulation& sim, int axis, double value, const Vec3& traction,
                              double tol) {
  for (const auto& f : m.boundary_faces()) {
    bool in = true;
    for (VertexId v : f.vertices) in = in && std::abs(m.rest(v)[axis] - value) <= tol;
    if (!in) continue;
    const Vec3 a = m.rest(f.vertices[0]), b = m.rest(f.vertices[1]), c = m.rest(f.vertices[2]);
    const double area = 0.5 * (b - a).cross(c - a).norm();
    for (VertexId v : f.vertices) sim.add_force(v, traction * area / 3);
  }
}

// Both x ends (x = 0 and x = 4) of a 4-long box fixed.
inline void fix_ends(const TetMesh& m, FemSimulation& sim) {
  for (VertexId v : m.vertices())
    if (m.rest(v).x() < 1e-9 || m.rest(v).x() > 4 - 1e-9) sim.fix(v);
}

// After 8 more frames, `sim` (ends fixed, -2 z on `top`) equals the direct solution on m.
inline void check_equals_direct(const TetMesh& m, const FemSimulationOptions& opt, const std::vector<VertexId>& top,
                         FemSimulation& sim) {
  FemSimulationOptions dopt = opt;
  dopt.method = SolverMethod::Direct;
  FemSimulation direct(m, table(1e5, 0.45), dopt);
  fix_ends(m, direct);
  for (VertexId v : top) direct.set_force(v, Vec3(0, 0, -2));
  for (int f = 0; f < 8; ++f) {
    CHECK(sim.step().info == SolveInfo::Success);
    direct.step();
  }
  CHECK((sim.displacement() - direct.displacement()).norm() <= 1e-6 * direct.displacement().norm());
}

inline double max_abs(const Eigen::VectorXd& v) { return v.size() ? v.cwiseAbs().maxCoeff() : 0.0; }

// Shared by the nodal-averaged and edge-smoothed tests (their own namespace: other FEM tests
// have helpers of these names).
namespace smoothed {
inline MaterialTable two_materials() {
  Material soft{2e4, 0.49, 900};
  Material hard{5e7, 0.2, 1900};
  MaterialTable t(soft);
  t.set(2, hard);
  return t;
}

inline Eigen::VectorXd random_vector(Eigen::Index n, std::mt19937& rng, double scale = 1) {
  std::normal_distribution<double> nd;
  Eigen::VectorXd x(n);
  for (Eigen::Index i = 0; i < n; ++i) x[i] = scale * nd(rng);
  return x;
}

// Relative difference of K x, diagonal, diagonal blocks and mass of two models on the mesh's
// vertex range, and (corotational) of b_R.
inline double model_difference(const FemModel& a, const FemModel& b, const TetMesh& m, std::mt19937& rng) {
  const Eigen::Index n = Eigen::Index(3 * m.vertex_capacity());
  Eigen::VectorXd xa = Eigen::VectorXd::Zero(a.rows()), xb = Eigen::VectorXd::Zero(b.rows()), ya, yb;
  xa.head(n) = xb.head(n) = random_vector(n, rng);
  a.multiply(xa, ya);
  b.multiply(xb, yb);
  double d = (ya.head(n) - yb.head(n)).norm() / yb.head(n).norm();
  d = std::max(d, (a.diagonal().head(n) - b.diagonal().head(n)).norm() / b.diagonal().head(n).norm());
  d = std::max(d, (a.lumped_mass().head(n) - b.lumped_mass().head(n)).norm() / b.lumped_mass().head(n).norm());
  double blocks = 0, scale = 0;
  for (std::size_t v = 0; v < m.vertex_capacity(); ++v) {
    blocks += (a.diagonal_blocks()[v] - b.diagonal_blocks()[v]).squaredNorm();
    scale += b.diagonal_blocks()[v].squaredNorm();
  }
  d = std::max(d, std::sqrt(blocks / scale));
  if (a.kind() == FemKind::Corotational) {
    Eigen::VectorXd ra = Eigen::VectorXd::Zero(a.rows()), rb = Eigen::VectorXd::Zero(b.rows());
    a.add_rotation_rhs(ra);
    b.add_rotation_rhs(rb);
    d = std::max(d, (ra.head(n) - rb.head(n)).norm() / std::max(rb.head(n).norm(), 1e-300));
  }
  if (a.rows() > n) d = std::max(d, ya.tail(a.rows() - n).norm() + a.diagonal().tail(a.rows() - n).norm());
  return d;
}

// Cantilever L x h x h (L = 10 h), clamped at x = 0, a total shear load P (z) spread over the
// tip face; returns the mean tip deflection and Timoshenko's (Cowper's shear coefficient).
struct Cantilever {
  double fem = 0, theory = 0;
  double error() const { return fem / theory - 1; }  // negative: too stiff
};
// Solved by CG with the exact (CHOLMOD) Cholesky preconditioner to 1e-12: the direct solver's
// SimplicialLDLT takes ~25 s on the nodal-averaged 80x8x8 (2-ring pattern), CG ~2.5 s, and CG
// equals the direct solve (test above).
inline Cantilever cantilever(int nx, double nu, Formulation f) {
  const double len = 10, h = 1, e = 1e6, p = -1;
  const double inertia = h * h * h * h / 12, area = h * h, g = e / (2 * (1 + nu));
  const double shear = 10 * (1 + nu) / (12 + 11 * nu);
  Cantilever c;
  c.theory = p * len * len * len / (3 * e * inertia) + p * len / (shear * g * area);
  TetMesh m = make_box(Vec3(len, h, h), {nx, nx / 10, nx / 10});
  FemSimulationOptions opt;
  opt.formulation = f;
  opt.cg.tolerance = 1e-12;
  opt.cg.preconditioner = Preconditioner::Cholesky;
  opt.cholesky.background = false;
  opt.warm_start = false;
  FemSimulation sim(m, table(e, nu), opt);
  for (VertexId v : m.vertices())
    if (m.rest(v).x() < 1e-9) sim.fix(v);
  add_face_traction(m, sim, 0, len, Vec3(0, 0, p / area), 1e-9);
  REQUIRE(sim.step().info == SolveInfo::Success);
  int count = 0;
  for (VertexId v : m.vertices())
    if (m.rest(v).x() > len - 1e-9) {
      c.fem += sim.displacement()[3 * v.idx() + 2];
      ++count;
    }
  c.fem /= count;
  return c;
}


}  // namespace smoothed

}  // namespace incise::testing
