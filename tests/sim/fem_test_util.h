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

}  // namespace incise::testing
