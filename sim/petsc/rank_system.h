#pragma once
// One solver's share of a PETSc solve on one rank (sim/petsc/petsc_solver.h): it assembles its
// own rows of a M + c K (+ c B^T B) from the part rank 0 sent (rank_messages.h), eliminates the
// held unknowns, attaches the rigid-body near-null space, and runs the KSP (CG + GAMG unless
// the solver's options say otherwise) on its rows. Every call is collective over the solver's
// communicator.
#include <cstdint>
#include <string>
#include <vector>

#include <petscksp.h>

#include "sim/petsc/petsc_solver.h"
#include "sim/petsc/rank_messages.h"

namespace incise::petsc_detail {

class RankSystem {
public:
  // Reads PETSC_OPTIONS, then `options` (which win), into a database of its own.
  RankSystem(MPI_Comm comm, const std::string& options, double rtol, int max_iterations);
  ~RankSystem();
  RankSystem(const RankSystem&) = delete;
  RankSystem& operator=(const RankSystem&) = delete;

  int size() const { return size_; }
  PetscOptions options() const { return options_db_; }
  const std::vector<PetscInt>& vertex_start() const { return vstart_; }

  // starts: the first row block (vertex) of each rank, size + 1 entries.
  void assemble(const Header& h, const std::vector<PetscInt>& starts, const Part& p);
  // b, x: this rank's rows (3 per owned vertex). x in: guess and held values; out: solution.
  PetscSolveStats solve(const double* b, double* x);

private:
  void destroy_matrix();
  void add_b_transpose_b(const Header& h, const Part& p, PetscInt nl);
  static PetscErrorCode converged(KSP ksp, PetscInt it, PetscReal rnorm, KSPConvergedReason* reason, void* ctx);
  void create_ksp();

  // The solver's options as the default database while it lives in PETSc calls.
  struct OptionsScope {
    explicit OptionsScope(PetscOptions o);
    ~OptionsScope() { PetscOptionsPop(); }
  };

  MPI_Comm comm_;
  int rank_ = 0, size_ = 1;
  std::string options_;
  PetscOptions options_db_ = nullptr;
  double rtol_;
  int max_iterations_;
  long long n_ = 0;
  std::vector<PetscInt> vstart_, held_;
  std::vector<std::uint8_t> free_;
  double held_diagonal_ = 1, b_norm_ = 0;
  Mat k_ = nullptr;
  Vec x_ = nullptr, b_ = nullptr;
  KSP ksp_ = nullptr;
};

}  // namespace incise::petsc_detail
