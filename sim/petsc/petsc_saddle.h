#pragma once
// The mixed formulations' saddle-point system on PETSc (sim/fem/mixed_solver.h with
// MixedOptions::petsc): the free block [A_uu A_up; A_pu A_pp] x = b, unknowns u first, solved by
// MINRES with a block-diagonal field split, the SPD preconditioner MixedSolver's own MINRES
// uses: GAMG on A_uu, Jacobi on the pressure diagonal `p_diagonal` (lumped mass x
// (1/mu + 1/lambda), spectrally like the Schur complement). In this process alone, or on rank 0
// of a distributed run (sim/petsc/petsc_session.h) over every rank: each takes a contiguous
// range of the rows, sent by rank 0. Options ("-fieldsplit_u_pc_type hypre", "-ksp_rtol 1e-10")
// as for PetscSolver. docs/solver.md#petsc-more-than-one-machine.
#include <string>

#include <Eigen/Core>
#include <Eigen/SparseCore>

namespace incise {

struct PetscSaddleStats {
  int iterations = 0;
  bool converged = false;
  std::string reason;  // KSPConvergedReason's name
};

// a: symmetric, n x n with the first u_rows rows displacements; x: the guess in, the solution
// out. Throws InvalidArgument without PETSc, Error on a PETSc failure.
PetscSaddleStats petsc_solve_saddle(const Eigen::SparseMatrix<double>& a, Eigen::Index u_rows,
                                    const Eigen::VectorXd& p_diagonal, const Eigen::VectorXd& b, Eigen::VectorXd& x,
                                    double tolerance, int max_iterations, const std::string& options);

}  // namespace incise
