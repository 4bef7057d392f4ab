#pragma once
// What a mesh's shape means for the static solver: an ESTIMATE of the condition number of
// the stiffness matrix K and of the Conjugate Gradient iterations it costs. Not a bound.
//
//  lambda_max(K) <= max_i sum_{t at i} lambda_max(K_t)        (rigorous, element by element)
//      with lambda_max(K_t) <= trace(K_t) = sum_f A_f^2 / (9 |V_t|) for the P1 Laplacian:
//      a flat element (small V, finite face areas) makes it blow up.
//  lambda_min(K) ~ lambda_1 * V_total / N                     (smooth lowest mode)
//      with lambda_1 = (pi / 2L)^2, L the largest bounding-box extent: the body clamped on
//      one side, the usual set-up of a surgical scene.
//  kappa_laplace = lambda_max / lambda_min   ~ C (L/h)^2 / quality ~ C N^(2/3) / quality
//  kappa = kappa_laplace * 2(1-nu)/(1-2nu)   (elasticity: (lambda+2mu)/mu, the ratio of the
//                                             stiffest to the softest wave modulus)
//  CG iterations ~ 0.5 sqrt(kappa) ln(2/tol) (the classical CG error bound, unpreconditioned)
// On quasi-uniform meshes kappa_laplace lies within a small factor (about 1-4x, above) of
// the true value; the tests compare it with eigenvalues of the assembled Laplacian.
// A Jacobi preconditioner removes most of the effect of mesh grading, not of bad shapes.
// Against full solves it overshoots (docs/quality-report.md has the figures); sim/fem/cg_spectrum.h has a
// measured estimate (Lanczos from a short CG solve), which `incise quality` shows beside this.
#include <span>
#include <string>

#include "mesh/tet_mesh.h"

namespace incise {

struct SolverEstimateOptions {
  double tolerance = 1e-6;           // relative residual the CG iteration count is for
  double poisson_ratio = 0.45;       // in (-1, 0.5); soft tissue is nearly incompressible
  double degenerate_volume = 1e-12;  // |V| <= this * l_max^3 makes K singular: no estimate
};

struct SolverEstimate {
  bool available = false;        // false for an empty mesh or degenerate tets; see reason
  std::string reason;            // why not available
  double domain_size = 0;        // L
  double lambda_max_bound = 0;   // upper bound on lambda_max of the Laplacian K
  VertexId lambda_max_vertex;    // where that bound is attained (look there for bad tets)
  double lambda_min_estimate = 0;
  double kappa_laplace = 0;
  double elasticity_factor = 0;  // 2(1-nu)/(1-2nu)
  double kappa = 0;              // estimated condition number of the elastic K
  double cg_iterations = 0;      // estimated unpreconditioned CG iterations to `tolerance`
  double tolerance = 0;          // echo of the options used
  double poisson_ratio = 0;
};

// O(mesh). Positions: rest when empty, else indexed by VertexId. Throws InvalidArgument for
// a Poisson ratio outside (-1, 0.5) or a tolerance outside (0, 1).
SolverEstimate estimate_solver(const TetMesh& mesh, const SolverEstimateOptions& options = {},
                               std::span<const Vec3> positions = {});

}  // namespace incise
