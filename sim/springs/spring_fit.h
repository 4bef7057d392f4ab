#pragma once
// Per-tet spring constants fitted to the tet's own FEM stiffness (SpringStiffness::Fitted),
// after Lloyd, Székely & Harders 2007 ("Identification of spring parameters for deformable
// object simulation", IEEE TVCG): the six edge springs' constants k_e >= 0 and the volume
// term's modulus kappa >= kappa_min that bring the tet's 12x12 stiffness matrix
//   sum_e k_e d_e d_e^T + kappa V g g^T   (d_e: the edge's unit direction at its two corners,
//                                          g: the divergence of the corner displacements)
// closest, in the Frobenius norm, to the linear FEM tet's V B^T C B. Every term is B^T X B for
// a form X on the strain (Mandel vectors), so the fit is a 7-unknown least-squares problem on
// forms with the metric H = B B^T: O(1) per tet, solved with the bounds by Lawson & Hanson's
// active set. It depends only on the tet's shape (not its size, place or orientation).
// docs/solver.md#spring-stiffness measures it against Van Gelder's isotropic rule.
#include <array>

#include "mesh/tet_mesh.h"

namespace incise {

struct TetSpringFit {
  std::array<double, 6> k{};  // [N/m] per edge in kTetEdges order
  double kappa = 0;           // [Pa] the volume term's modulus (0 without one)
};

// Edge e of a tet joins corners kTetEdges[e][0] and kTetEdges[e][1].
inline constexpr std::array<std::array<int, 2>, 6> kTetEdges = {{{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}}};

// x: the tet's rest corners; mu, lambda: its material's Lame parameters; volume_term false:
// kappa is 0 and the springs alone are fitted; else kappa >= kappa_min. A degenerate tet
// (zero volume or a zero edge) gets zero constants.
TetSpringFit fit_tet_springs(const std::array<Vec3, 4>& x, double mu, double lambda, bool volume_term,
                             double kappa_min);

}  // namespace incise
