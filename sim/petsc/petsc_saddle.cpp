// petsc_solve_saddle (sim/petsc/petsc_saddle.h).
#include "sim/petsc/petsc_saddle.h"

#include <algorithm>
#include <cstdlib>
#include <vector>

#include "sim/petsc/petsc_internal.h"

namespace incise {

namespace {

// CSR arrays PETSc reads in place (they must outlive the Mat).
struct Csr {
  std::vector<PetscInt> ia, ja;
  std::vector<PetscScalar> va;
};

}  // namespace

PetscSaddleStats petsc_solve_saddle(const Eigen::SparseMatrix<double>& a, Eigen::Index u_rows,
                                    const Eigen::VectorXd& p_diagonal, const Eigen::VectorXd& b, Eigen::VectorXd& x,
                                    double tolerance, int max_iterations, const std::string& options) {
  petsc_detail::ensure_initialized();
  const Eigen::SparseMatrix<double, Eigen::RowMajor> ar = a;
  const PetscInt n = PetscInt(ar.rows()), nu = PetscInt(u_rows);
  // A as it is; P: A's displacement block and the pressure diagonal.
  Csr ca, cp;
  ca.ia.push_back(0);
  cp.ia.push_back(0);
  for (PetscInt r = 0; r < n; ++r) {
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(ar, r); it; ++it) {
      ca.ja.push_back(PetscInt(it.col()));
      ca.va.push_back(it.value());
      if (r < nu && it.col() < nu) {
        cp.ja.push_back(PetscInt(it.col()));
        cp.va.push_back(it.value());
      }
    }
    if (r >= nu) {
      cp.ja.push_back(r);
      cp.va.push_back(p_diagonal[r - nu]);
    }
    ca.ia.push_back(PetscInt(ca.ja.size()));
    cp.ia.push_back(PetscInt(cp.ja.size()));
  }
  Mat am = nullptr, pm = nullptr;
  Vec xv = nullptr, bv = nullptr;
  IS isu = nullptr, isp = nullptr;
  KSP ksp = nullptr;
  PetscOptions db = nullptr;
  INCISE_PETSC(MatCreateSeqAIJWithArrays(PETSC_COMM_SELF, n, n, ca.ia.data(), ca.ja.data(), ca.va.data(), &am));
  INCISE_PETSC(MatCreateSeqAIJWithArrays(PETSC_COMM_SELF, n, n, cp.ia.data(), cp.ja.data(), cp.va.data(), &pm));
  INCISE_PETSC(VecCreateSeqWithArray(PETSC_COMM_SELF, 1, n, const_cast<double*>(b.data()), &bv));  // only read
  INCISE_PETSC(VecCreateSeqWithArray(PETSC_COMM_SELF, 1, n, x.data(), &xv));
  INCISE_PETSC(ISCreateStride(PETSC_COMM_SELF, nu, 0, 1, &isu));
  INCISE_PETSC(ISCreateStride(PETSC_COMM_SELF, n - nu, nu, 1, &isp));
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
    if ((err = KSPCreate(PETSC_COMM_SELF, &ksp))) break;
    if ((err = KSPSetOperators(ksp, am, pm))) break;
    if ((err = KSPSetType(ksp, KSPMINRES))) break;
    PC pc = nullptr;
    if ((err = KSPGetPC(ksp, &pc))) break;
    if ((err = PCSetType(pc, PCFIELDSPLIT))) break;
    if ((err = PCFieldSplitSetIS(pc, "u", isu))) break;
    if ((err = PCFieldSplitSetIS(pc, "p", isp))) break;
    if ((err = PCFieldSplitSetType(pc, PC_COMPOSITE_ADDITIVE))) break;
    if ((err = KSPSetTolerances(ksp, tolerance, PETSC_DEFAULT, PETSC_DEFAULT, max_iterations))) break;
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

}  // namespace incise
