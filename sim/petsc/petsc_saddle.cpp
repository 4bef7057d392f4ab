// petsc_solve_saddle (sim/petsc/petsc_saddle.h): the saddle-point system's rows cut into one
// contiguous range per rank (rank 0 holds the system and sends each rank its rows), one
// distributed matrix, MINRES with the field split on every rank.
#include "sim/petsc/petsc_saddle.h"

#include <algorithm>
#include <cstdlib>
#include <vector>

#include "sim/petsc/petsc_internal.h"
#include "sim/petsc/petsc_session.h"
#include "sim/petsc/rank_messages.h"

namespace incise {

namespace petsc_detail {

namespace {

// What every rank needs besides its rows.
struct SaddleHeader {
  long long n = 0, nu = 0;
  double tolerance = 0;
  int max_iterations = 0;
};

// Rows [first, last) of a (row-major), its pressure rows' share of p_diagonal.
SaddleRows rows_of(const Eigen::SparseMatrix<double, Eigen::RowMajor>& a, const Eigen::VectorXd& p_diagonal,
                   Eigen::Index nu, PetscInt first, PetscInt last) {
  SaddleRows r;
  r.ptr.push_back(0);
  for (PetscInt i = first; i < last; ++i) {
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(a, i); it; ++it) {
      r.col.push_back(PetscInt(it.col()));
      r.val.push_back(it.value());
    }
    r.ptr.push_back(PetscInt(r.col.size()));
    if (i >= nu) r.p_diagonal.push_back(p_diagonal[i - nu]);
  }
  return r;
}

// Every rank's part of the solve: its rows [first, first + local) of the system, b and x on
// those rows (x: the guess in, the solution out). Collective over comm.
PetscSaddleStats solve_rows(MPI_Comm comm, const SaddleHeader& h, PetscInt first, const SaddleRows& rows,
                            const double* b, double* x, const std::string& options) {
  const PetscInt n = PetscInt(h.n), nu = PetscInt(h.nu), local = PetscInt(rows.ptr.size()) - 1;
  // P: A's displacement block and the pressure diagonal.
  std::vector<PetscInt> pptr{0}, pcol;
  std::vector<double> pval;
  for (PetscInt i = 0; i < local; ++i) {
    const PetscInt row = first + i;
    for (PetscInt k = rows.ptr[std::size_t(i)]; k < rows.ptr[std::size_t(i) + 1]; ++k)
      if (row < nu && rows.col[std::size_t(k)] < nu) {
        pcol.push_back(rows.col[std::size_t(k)]);
        pval.push_back(rows.val[std::size_t(k)]);
      }
    if (row >= nu) {
      pcol.push_back(row);
      pval.push_back(rows.p_diagonal[std::size_t(row - std::max(first, nu))]);
    }
    pptr.push_back(PetscInt(pcol.size()));
  }
  Mat am = nullptr, pm = nullptr;
  Vec xv = nullptr, bv = nullptr;
  IS isu = nullptr, isp = nullptr;
  KSP ksp = nullptr;
  PetscOptions db = nullptr;
  // Copies the arrays (PETSc keeps its own).
  INCISE_PETSC(MatCreateMPIAIJWithArrays(comm, local, local, n, n, rows.ptr.data(), rows.col.data(), rows.val.data(), &am));
  INCISE_PETSC(MatCreateMPIAIJWithArrays(comm, local, local, n, n, pptr.data(), pcol.data(), pval.data(), &pm));
  INCISE_PETSC(VecCreateMPIWithArray(comm, 1, local, n, b, &bv));  // only read
  INCISE_PETSC(VecCreateMPIWithArray(comm, 1, local, n, x, &xv));
  // This rank's rows of each field (displacements first in the numbering).
  const PetscInt u_end = std::min(first + local, nu), p_first = std::max(first, nu);
  INCISE_PETSC(ISCreateStride(comm, std::max<PetscInt>(0, u_end - first), first, 1, &isu));
  INCISE_PETSC(ISCreateStride(comm, std::max<PetscInt>(0, first + local - p_first), p_first, 1, &isp));
  // The defaults first, then PETSC_OPTIONS, then the scene's (the last word wins).
  INCISE_PETSC(PetscOptionsCreate(&db));
  INCISE_PETSC(PetscOptionsInsertString(db, "-fieldsplit_u_ksp_type preonly -fieldsplit_u_pc_type gamg "
                                            "-fieldsplit_p_ksp_type preonly -fieldsplit_p_pc_type jacobi"));
  if (const char* env = std::getenv("PETSC_OPTIONS")) INCISE_PETSC(PetscOptionsInsertString(db, env));
  if (!options.empty()) INCISE_PETSC(PetscOptionsInsertString(db, options.c_str()));
  INCISE_PETSC(PetscOptionsPush(db));
  PetscSaddleStats st;
  PetscErrorCode err = 0;
  do {  // the options stay pushed for the set-up and the solve; popped below on every path
    if ((err = KSPCreate(comm, &ksp))) break;
    if ((err = KSPSetOperators(ksp, am, pm))) break;
    if ((err = KSPSetType(ksp, KSPMINRES))) break;
    PC pc = nullptr;
    if ((err = KSPGetPC(ksp, &pc))) break;
    if ((err = PCSetType(pc, PCFIELDSPLIT))) break;
    if ((err = PCFieldSplitSetIS(pc, "u", isu))) break;
    if ((err = PCFieldSplitSetIS(pc, "p", isp))) break;
    if ((err = PCFieldSplitSetType(pc, PC_COMPOSITE_ADDITIVE))) break;
    if ((err = KSPSetTolerances(ksp, h.tolerance, PETSC_DEFAULT, PETSC_DEFAULT, h.max_iterations))) break;
    if ((err = KSPSetInitialGuessNonzero(ksp, PETSC_TRUE))) break;
    if ((err = KSPSetFromOptions(ksp))) break;
    if ((err = KSPSolve(ksp, bv, xv))) break;
    PetscInt its = 0;
    KSPConvergedReason reason;
    if ((err = KSPGetIterationNumber(ksp, &its))) break;
    if ((err = KSPGetConvergedReason(ksp, &reason))) break;
    st.iterations = int(its);
    st.converged = reason > 0;
    st.reason = KSPConvergedReasons[reason];
  } while (false);
  PetscOptionsPop();
  if (ksp) KSPDestroy(&ksp);
  ISDestroy(&isu);
  ISDestroy(&isp);
  VecDestroy(&xv);
  VecDestroy(&bv);
  MatDestroy(&am);
  MatDestroy(&pm);
  PetscOptionsDestroy(&db);
  INCISE_PETSC(err);
  return st;
}

}  // namespace

void serve_saddle(MPI_Comm comm) {
  SaddleHeader h;
  MPI_Bcast(&h, int(sizeof h), MPI_BYTE, 0, comm);
  std::string options;
  broadcast_string(options, comm);
  int size = 0, rank = 0;
  MPI_Comm_size(comm, &size);
  MPI_Comm_rank(comm, &rank);
  const std::vector<PetscInt> starts = split(h.n, size);
  SaddleRows rows;
  receive_saddle_rows(rows, comm);
  std::vector<double> b, x;
  scatter_rows(starts, nullptr, b, comm, 1);
  scatter_rows(starts, nullptr, x, comm, 1);
  solve_rows(comm, h, starts[std::size_t(rank)], rows, b.data(), x.data(), options);
  gather_rows(starts, x, nullptr, comm, 1);
}

}  // namespace petsc_detail

using namespace petsc_detail;

PetscSaddleStats petsc_solve_saddle(const Eigen::SparseMatrix<double>& a, Eigen::Index u_rows,
                                    const Eigen::VectorXd& p_diagonal, const Eigen::VectorXd& b, Eigen::VectorXd& x,
                                    double tolerance, int max_iterations, const std::string& options) {
  ensure_initialized();
  const Eigen::SparseMatrix<double, Eigen::RowMajor> ar = a;
  SaddleHeader h;
  h.n = (long long)ar.rows();
  h.nu = (long long)u_rows;
  h.tolerance = tolerance;
  h.max_iterations = max_iterations;
  if (!petsc_distributed()) {  // this process alone
    const SaddleRows rows = rows_of(ar, p_diagonal, u_rows, 0, PetscInt(h.n));
    return solve_rows(PETSC_COMM_SELF, h, 0, rows, b.data(), x.data(), options);
  }
  // Rank 0 of a distributed run: every rank takes a contiguous range of the rows.
  MPI_Comm comm = PETSC_COMM_WORLD;
  const int size = petsc_ranks();
  const std::vector<PetscInt> starts = split(h.n, size);
  std::vector<double> bl, xl;
  try {
    broadcast_command(kSaddle, 0);
    MPI_Bcast(&h, int(sizeof h), MPI_BYTE, 0, comm);
    std::string o = options;
    broadcast_string(o, comm);
    for (int r = 1; r < size; ++r)
      send_saddle_rows(rows_of(ar, p_diagonal, u_rows, starts[std::size_t(r)], starts[std::size_t(r) + 1]), r, comm);
  } catch (const std::exception& ex) {
    abort_all(std::string("petsc: rank 0: ") + ex.what());
  }
  scatter_rows(starts, b.data(), bl, comm, 1);
  scatter_rows(starts, x.data(), xl, comm, 1);
  const PetscSaddleStats st =
      solve_rows(comm, h, 0, rows_of(ar, p_diagonal, u_rows, 0, starts[1]), bl.data(), xl.data(), options);
  gather_rows(starts, xl, x.data(), comm, 1);
  return st;
}

}  // namespace incise
