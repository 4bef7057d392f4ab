#pragma once
// The straight-sided 10-node tetrahedron (P2) and its P1 pressure partner (Taylor-Hood):
// element matrices in the node order of sim/fem/p2_mesh.h. Shape functions in barycentric
// coordinates L: corner i: L_i (2 L_i - 1), mid-edge (i, j): 4 L_i L_j.
// The stiffness and the divergence coupling integrate polynomials of degree 2 on an affine tet:
// the 4-point degree-2 rule is exact for them. The consistent mass (degree 4) is exact: the
// reference matrix comes from the monomial formula int L^a = 6 V a! / (|a| + 3)!.
#include <array>

#include <Eigen/Core>

#include "mesh/tet_mesh.h"

namespace incise {

using P2Matrix = Eigen::Matrix<double, 30, 30>;

struct P2Tet {
  Eigen::Matrix<double, 4, 3> grad_l;  // row i: grad L_i
  double volume = 0;
};

// Throws InvalidMesh for a tet of zero or negative volume.
P2Tet make_p2_tet(const std::array<Vec3, 4>& corners);

// Row a: grad N_a at barycentric point l.
Eigen::Matrix<double, 10, 3> p2_gradients(const P2Tet& t, const Eigen::Vector4d& l);
// The 4-point degree-2 rule's barycentric points (each weighs V / 4).
const std::array<Eigen::Vector4d, 4>& p2_quadrature_points();

// Linear elasticity (unknowns 3a..3a+2 of node a): lambda g_a g_b^T + mu g_b g_a^T + mu g_a.g_b I.
P2Matrix p2_stiffness(const P2Tet& t, double mu, double lambda);
// Taylor-Hood coupling D_ij = int L_i div N_j (4 pressure corners x 30 unknowns).
Eigen::Matrix<double, 4, 30> p2_divergence(const P2Tet& t);
// The consistent mass of a unit-volume tet per unit density (scalar, 10 x 10): M_e = rho V m.
const Eigen::Matrix<double, 10, 10>& p2_unit_mass();
// int N_a / V: -1/20 at corners, 1/5 at mid-edge nodes (a body force's consistent load).
double p2_load_weight(int a);
// The 6-node triangle's int N / area for a uniform traction: 0 at its corners, 1/3 at its
// mid-edge nodes.
inline constexpr double kP2FaceCornerWeight = 0.0, kP2FaceMidWeight = 1.0 / 3.0;
// Displacement gradient (du_i / dx_j) at barycentric point l from the 10 nodal displacements.
Eigen::Matrix3d p2_displacement_gradient(const P2Tet& t, const Eigen::Matrix<double, 30, 1>& ue,
                                         const Eigen::Vector4d& l);

}  // namespace incise
