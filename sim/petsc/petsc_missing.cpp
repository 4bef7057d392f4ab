// The PETSc backend in a build without PETSc (INCISE_WITH_PETSC off): asking for it is an error
// of one line; a plain run never notices.
#include "mesh/errors.h"
#include "sim/petsc/petsc_saddle.h"
#include "sim/petsc/petsc_session.h"
#include "sim/petsc/petsc_solver.h"

namespace incise {

namespace {
const char* const kMissing =
    "this incise was built without PETSc (install petsc-dev and openmpi-bin, then reconfigure: docs/solver.md#petsc-more-than-one-machine)";
}

bool petsc_built() { return false; }

struct PetscSolver::Impl {};
PetscSolver::PetscSolver(const std::string&, double, int) { throw InvalidArgument(std::string("solver backend petsc: ") + kMissing); }
PetscSolver::~PetscSolver() = default;
void PetscSolver::compute(const FemModel&, double, double, const std::vector<std::uint8_t>&) {}
PetscSolveStats PetscSolver::solve(const Eigen::VectorXd&, Eigen::VectorXd&) { return {}; }
int PetscSolver::ranks() const { return 1; }
PetscSaddleStats petsc_solve_saddle(const Eigen::SparseMatrix<double>&, Eigen::Index, const Eigen::VectorXd&,
                                    const Eigen::VectorXd&, Eigen::VectorXd&, double, int, const std::string&) {
  throw InvalidArgument(std::string("solver backend petsc: ") + kMissing);
}

int petsc_start_distributed() {
  if (launched_ranks() > 1)
    throw InvalidArgument(std::to_string(launched_ranks()) + " ranks launched: " + kMissing + "; or run without mpirun");
  return 0;
}
int petsc_serve() { return 0; }
void petsc_finish(int) {}
bool petsc_distributed() { return false; }
std::vector<double> rank_peak_memory_mb() { return {}; }
int petsc_start_shared() { return petsc_start_distributed(); }
int petsc_ranks() { return 1; }
std::vector<std::string> petsc_gather(const std::string& mine) { return {mine}; }
bool petsc_all_ok(bool ok) { return ok; }
void petsc_end_shared() {}
void petsc_abort(const std::string& message) { throw Error(message); }

}  // namespace incise
