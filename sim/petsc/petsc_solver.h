#pragma once
// PetscSolver: the FEM system a M + c K (the same K FemModel assembles: elements() and its
// nodal_b(), so every displacement formulation) assembled into a distributed PETSc matrix
// (MATAIJ with 3x3 blocks) and solved by a KSP: CG with GAMG by default, the six rigid-body
// modes of the rest positions as GAMG's near-null space; options from the scene's
// `petsc_options` string and the PETSC_OPTIONS environment variable apply (KSPSetFromOptions).
//
// Held unknowns (free[i] == 0: fixed, prescribed, dead or without tets) are eliminated by
// zeroing their rows and columns (MatZeroRowsColumns) with a diagonal of the matrix's mean
// scale; solve() takes the right-hand side already lifted (b - A x_held on the free rows, the
// caller's matrix-free product) and x holding the held values.
//
// Ranks: in a distributed run (sim/petsc/petsc_session.h, `mpirun -np N incise simulate`) rank 0
// holds the model and calls compute()/solve(); each call sends the other ranks, which serve in
// petsc_serve(), the data of their rows: the vertex graph is cut into one part per rank
// (sim/petsc/vertex_partition.h, PT-Scotch through MatPartitioning; redone when the slot count
// grows), rank r gets the tets touching its vertices and assembles its own rows from them
// (element_block, the model's element math), and B's rows in an even split (K += B^T B by
// MatTransposeMatMult). The solution is gathered to rank 0. Anywhere else (one process, the library, Python) it runs on
// PETSC_COMM_SELF. docs/solver.md#petsc-more-than-one-machine.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace incise {

class FemModel;

struct PetscSolveStats {
  int iterations = 0;
  bool converged = false;
  std::string reason;  // KSPConvergedReason's name ("CONVERGED_RTOL", "DIVERGED_ITS", ...)
  double assemble_ms = 0;  // the last compute() (data sent, rows assembled, GAMG not yet set up)
};

// Whether this build has PETSc (INCISE_WITH_PETSC); without it PetscSolver's constructor throws.
bool petsc_built();

class PetscSolver {
public:
  // `options`: PETSc command-line options ("-ksp_type minres -pc_type jacobi"), added to the
  // options database before the KSP reads it. tolerance: relative residual on the free rows;
  // both may be overridden by -ksp_rtol / -ksp_max_it. Throws InvalidArgument without PETSc.
  PetscSolver(const std::string& options, double tolerance, int max_iterations);
  ~PetscSolver();
  PetscSolver(const PetscSolver&) = delete;
  PetscSolver& operator=(const PetscSolver&) = delete;

  // Assembles a diag(lumped mass) + c K from the model's current elements (rotations included)
  // with the held unknowns eliminated. O(mesh / ranks) per rank, O(mesh) on rank 0 to send.
  void compute(const FemModel& model, double a, double c, const std::vector<std::uint8_t>& free);
  // x: the initial guess on the free unknowns, the held values on the others; overwritten with
  // the solution. b: the lifted right-hand side (see above). Collective in a distributed run.
  PetscSolveStats solve(const Eigen::VectorXd& b, Eigen::VectorXd& x);
  int ranks() const;  // processes the matrix is spread over

private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  double assemble_ms_ = 0;
};

}  // namespace incise
