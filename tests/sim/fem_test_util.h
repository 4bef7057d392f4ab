#pragma once
// Helpers shared by the FEM tests: loads on box faces (random edits and jitter come from
// tests/support/mesh_edits.h).
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

inline double max_abs(const Eigen::VectorXd& v) { return v.size() ? v.cwiseAbs().maxCoeff() : 0.0; }

}  // namespace incise::testing
