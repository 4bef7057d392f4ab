#pragma once
// A MEASURED estimate of what a mesh costs the static CG solver: a short CG solve on the mesh's
// actual elastic stiffness, whose coefficients give the extreme eigenvalues (Lanczos), hence
// the condition number and a predicted iteration count. quality/conditioning.h has the
// formula (mesh only, O(mesh) and instant); this costs a short solve but sees the real K.
//
// Lanczos from CG: with alpha_j, beta_j of the (preconditioned) CG iterations j = 0..k-1, the
// k x k tridiagonal matrix
//   T_jj = 1/alpha_j + beta_{j-1}/alpha_{j-1}  (no second term for j = 0)
//   T_{j,j+1} = sqrt(beta_j) / alpha_j
// is the Lanczos matrix of M^-1 A (A restricted to the free unknowns) for the start vector
// M^-1 r_0. Its extreme eigenvalues (Ritz values) lie inside [lambda_min, lambda_max] and
// approach them as k grows: lambda_max within a few tens of iterations, lambda_min slowly
// and from above. So kappa_k = theta_max / theta_min is a LOWER bound on kappa that grows with k
// (and with a smooth load that hardly excites the lowest mode it may stay well below).
//
// Predicted iterations: the classical CG bound 0.5 sqrt(kappa) ln(2/tol) with the measured
// Ritz values, where isolated large eigenvalues (bad elements' stiff modes) cost one iteration
// each instead of entering kappa (cg_iterations_with_outliers). With the true spectrum that
// bound overshoots a real solve (CG converges superlinearly as it resolves the extreme
// modes); with Ritz values it is an upper-bound formula fed a lower-bound kappa, and the two
// errors partly cancel. The tests and `bench_fem_solver --only spectrum` measure how far it
// lands from a full solve (docs/quality-report.md). A solve that converges within the k
// iterations reports its own iteration count instead.
//
// The problem is the set-up the formula assumes and the quality report documents: linear
// elasticity (E = 1: kappa does not depend on E), one material of Poisson ratio nu, the body
// clamped on one side (the vertices within clamp_fraction of the extent from the minimum of
// the longest bounding-box axis) under a gravity-like load (lumped mass times a unit
// acceleration along the shortest axis, which bends the body).
#include <cstddef>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mesh/tet_mesh.h"
#include "sim/linalg/cg_solver.h"
#include "sim/fem/fem_model.h"

namespace incise {

// Extreme Ritz values of the Lanczos matrix built from CG coefficients (all of them).
struct LanczosExtremes {
  int steps = 0;  // k: the matrix's size
  double lambda_min = 0, lambda_max = 0;
  std::vector<double> ritz;  // all k Ritz values, ascending
  double kappa() const { return lambda_max / lambda_min; }
};
// O(k^2). k = 0 (no iteration) gives steps 0 and zeros. Throws InvalidArgument when the
// coefficients are not positive and finite or the arrays are shorter than each other allows.
LanczosExtremes lanczos_extremes(const CgCoefficients& c);

// 0.5 sqrt(kappa) ln(2/tol): the classical CG bound on iterations to reduce the error by tol.
double cg_iterations_for(double kappa, double tolerance);
// The same bound with isolated large eigenvalues paid one iteration each:
//   min over m <= min(max_outliers, k / 10) of  m + cg_iterations_for(theta_(m) / theta_min, tol)
// with theta_(m) the (m+1)-th largest DISTINCT Ritz value (values within a relative 1e-6 are
// one: finite-precision Lanczos repeats converged ones, and CG needs one iteration for a
// multiple eigenvalue anyway). The bound holds for the true eigenvalues (a polynomial with
// roots at the m outliers times the Chebyshev one on the rest); a few slivers make exactly
// such outliers, which the plain bound charges in sqrt(kappa). Only the top tenth of the k
// Ritz values may count as outliers: the rest stand for the bulk of the spectrum, and the
// small end converges too slowly to tell isolated soft modes (a slender body's first bending
// mode) from the bulk, so they are never removed. Ritz values ascending.
double cg_iterations_with_outliers(const std::vector<double>& ritz, double tolerance, int max_outliers = 10);

// The clamped, loaded problem above on a model of the mesh.
struct ClampedProblem {
  int clamp_axis = 0, load_axis = 2;   // 0 = x, 1 = y, 2 = z
  std::size_t fixed_vertices = 0;
  std::vector<std::uint8_t> free;      // 3 per vertex slot, 1 = free
  Eigen::VectorXd load;                // 3 per vertex slot
};
ClampedProblem clamped_problem(const FemModel& model, double clamp_fraction = 0.1);

// One CG run on the clamped problem: the Lanczos extremes of its iterations and the prediction.
struct CgSpectrumRun {
  Preconditioner preconditioner = Preconditioner::None;
  int iterations = 0;       // CG iterations run (<= the cap)
  bool converged = false;   // reached the tolerance within the cap
  LanczosExtremes ritz;     // from all `iterations`
  double kappa = 0;         // ritz.kappa(): a lower bound on kappa(M^-1 K)
  double classic_iterations = 0;    // cg_iterations_for(kappa, tol)
  double predicted_iterations = 0;  // iterations if converged, else cg_iterations_with_outliers
  double ms = 0;            // wall time of the CG run (not of building the model)
};
// Runs CG (None or Jacobi; BlockJacobi works too) from zero for at most max_iterations.
CgSpectrumRun run_cg_spectrum(const FemModel& model, const ClampedProblem& problem, Preconditioner pc,
                              int max_iterations, double tolerance);

struct MeasuredSolverOptions {
  double tolerance = 1e-6;       // relative residual the iteration count is for
  double poisson_ratio = 0.45;   // in [0, 0.5) (in (-1, 0): unavailable, the FEM model refuses it)
  int lanczos_iterations = 100;  // CG iterations per estimate; see docs/quality-report.md
  double clamp_fraction = 0.1;   // of the longest extent, from its minimum
};

struct MeasuredSolverEstimate {
  bool available = false;
  std::string reason;     // why not available
  std::string source;     // "measured: Lanczos from N CG iterations"
  ClampedProblem problem; // which vertices were clamped, which way the load pulls (load kept)
  CgSpectrumRun none, jacobi;
  double model_ms = 0;    // building the FEM model and the problem
  double total_ms = 0;    // everything
};

// Builds the model and the problem and runs the two short solves (unpreconditioned and
// Jacobi). O(mesh * iterations), a small share of a full solve (docs/quality-report.md).
// Unavailable (with the reason) for a mesh without tets, degenerate tets, no vertex to clamp,
// a negative Poisson ratio, or a solve that breaks down. Throws InvalidArgument for
// out-of-range options (tolerance outside (0, 1), nu outside (-1, 0.5), iterations < 1).
MeasuredSolverEstimate measure_solver(const TetMesh& mesh, const MeasuredSolverOptions& options = {});

}  // namespace incise
