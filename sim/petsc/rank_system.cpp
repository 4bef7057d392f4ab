// RankSystem (sim/petsc/rank_system.h): one rank's rows of a PETSc solve and its KSP.
#include "sim/petsc/rank_system.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>

#include <Eigen/Core>

#include "sim/fem/fem_model.h"
#include "sim/petsc/petsc_internal.h"

namespace incise::petsc_detail {

RankSystem::OptionsScope::OptionsScope(PetscOptions o) { INCISE_PETSC(PetscOptionsPush(o)); }

RankSystem::RankSystem(MPI_Comm comm, const std::string& options, double rtol, int max_iterations)
    : comm_(comm), options_(options), rtol_(rtol), max_iterations_(max_iterations) {
  MPI_Comm_rank(comm_, &rank_);
  MPI_Comm_size(comm_, &size_);
  // Each solver reads its own options: PETSC_OPTIONS, then its scene's string (which wins).
  // The global database would carry one scene's choices into the next solver of the process.
  INCISE_PETSC(PetscOptionsCreate(&options_db_));
  if (const char* env = std::getenv("PETSC_OPTIONS")) INCISE_PETSC(PetscOptionsInsertString(options_db_, env));
  if (!options_.empty()) INCISE_PETSC(PetscOptionsInsertString(options_db_, options_.c_str()));
}

RankSystem::~RankSystem() {
  PetscBool fin = PETSC_FALSE;
  PetscFinalized(&fin);
  if (fin) return;  // PETSc already went (process exit): nothing left to free
  destroy_matrix();
  if (ksp_) KSPDestroy(&ksp_);
  if (options_db_) PetscOptionsDestroy(&options_db_);
}

// starts: the first row block (vertex) of each rank, size + 1 entries.
void RankSystem::assemble(const Header& h, const std::vector<PetscInt>& starts, const Part& p) {
  destroy_matrix();
  // A cut that added vertex slots changes the sizes: a new KSP (GAMG's levels keep the old
  // sizes through KSPReset).
  if (ksp_ && h.vertices != n_) INCISE_PETSC(KSPDestroy(&ksp_));
  n_ = h.vertices;
  vstart_ = starts;
  const PetscInt vb = vstart_[std::size_t(rank_)], ve = vstart_[std::size_t(rank_) + 1], nl = ve - vb;
  auto owned = [&](std::uint32_t v) { return PetscInt(v) >= vb && PetscInt(v) < ve; };
  const std::size_t tets = p.tet_verts.size() / 4;
  // Block sparsity of the owned rows: the vertices sharing a tet, and the diagonal always
  // (held and tetless vertices get their identity row there).
  std::vector<std::vector<PetscInt>> nbr(static_cast<std::size_t>(nl));
  for (PetscInt l = 0; l < nl; ++l) nbr[std::size_t(l)].push_back(vb + l);
  for (std::size_t t = 0; t < tets; ++t)
    for (int i = 0; i < 4; ++i) {
      const std::uint32_t v = p.tet_verts[4 * t + std::size_t(i)];
      if (!owned(v)) continue;
      for (int j = 0; j < 4; ++j) nbr[v - std::size_t(vb)].push_back(PetscInt(p.tet_verts[4 * t + std::size_t(j)]));
    }
  std::vector<PetscInt> dnnz(static_cast<std::size_t>(nl)), onnz(static_cast<std::size_t>(nl));
  for (PetscInt l = 0; l < nl; ++l) {
    auto& s = nbr[std::size_t(l)];
    std::sort(s.begin(), s.end());
    s.erase(std::unique(s.begin(), s.end()), s.end());
    for (PetscInt w : s) (w >= vb && w < ve ? dnnz : onnz)[std::size_t(l)]++;
  }
  nbr = {};
  INCISE_PETSC(MatCreate(comm_, &k_));
  INCISE_PETSC(MatSetSizes(k_, 3 * nl, 3 * nl, 3 * PetscInt(n_), 3 * PetscInt(n_)));
  INCISE_PETSC(MatSetType(k_, MATAIJ));
  INCISE_PETSC(MatSetBlockSize(k_, 3));
  INCISE_PETSC(MatXAIJSetPreallocation(k_, 3, dnnz.data(), onnz.data(), nullptr, nullptr));
  // The element blocks of the rows this rank owns: the model's own element math, one block
  // row (3 x 12) of a tet per call.
  Eigen::Matrix<double, 3, 3, Eigen::RowMajor> blk;
  Eigen::Matrix<double, 3, 12, Eigen::RowMajor> row_blocks;
  for (std::size_t t = 0; t < tets; ++t) {
    const double* d = &p.tet_data[kTetData * t];
    const Eigen::Matrix3d bm = Eigen::Map<const Eigen::Matrix3d>(d), rot = Eigen::Map<const Eigen::Matrix3d>(d + 9);
    const double vol = d[18], mu = d[19], lambda = d[20];
    if (mu == 0 && lambda == 0) continue;  // edge-smoothed: K is all B^T B
    PetscInt cols[4];
    for (int j = 0; j < 4; ++j) cols[j] = PetscInt(p.tet_verts[4 * t + std::size_t(j)]);
    for (int i = 0; i < 4; ++i) {
      if (!owned(std::uint32_t(cols[i]))) continue;
      for (int j = 0; j < 4; ++j) row_blocks.middleCols<3>(3 * j) = h.c * element_block(bm, vol, mu, lambda, rot, i, j);
      INCISE_PETSC(MatSetValuesBlocked(k_, 1, &cols[i], 4, cols, row_blocks.data(), ADD_VALUES));
    }
  }
  for (PetscInt l = 0; l < nl; ++l) {
    blk.setZero();
    for (int a = 0; a < 3; ++a) blk(a, a) = h.a * p.mass[std::size_t(3 * l + a)];
    const PetscInt row = vb + l;
    INCISE_PETSC(MatSetValuesBlocked(k_, 1, &row, 1, &row, blk.data(), ADD_VALUES));
  }
  INCISE_PETSC(MatAssemblyBegin(k_, MAT_FINAL_ASSEMBLY));
  INCISE_PETSC(MatAssemblyEnd(k_, MAT_FINAL_ASSEMBLY));
  if (h.b_rows > 0) add_b_transpose_b(h, p, nl);

  // Held unknowns: rows and columns zeroed, a diagonal of the free rows' mean scale (so the
  // held rows neither dominate nor spoil the spectrum GAMG and CG see).
  held_.clear();
  free_ = p.free;
  Vec diag = nullptr;
  INCISE_PETSC(MatCreateVecs(k_, &diag, nullptr));
  INCISE_PETSC(MatGetDiagonal(k_, diag));
  const PetscScalar* dv = nullptr;
  INCISE_PETSC(VecGetArrayRead(diag, &dv));
  double sum[2] = {0, 0};
  for (PetscInt i = 0; i < 3 * nl; ++i) {
    if (p.free[std::size_t(i)]) {
      sum[0] += std::abs(dv[i]);
      sum[1] += 1;
    } else {
      held_.push_back(3 * vb + i);
    }
  }
  INCISE_PETSC(VecRestoreArrayRead(diag, &dv));
  INCISE_PETSC(VecDestroy(&diag));
  MPI_Allreduce(MPI_IN_PLACE, sum, 2, MPI_DOUBLE, MPI_SUM, comm_);
  held_diagonal_ = sum[1] > 0 && sum[0] > 0 ? sum[0] / sum[1] : 1.0;
  INCISE_PETSC(MatZeroRowsColumns(k_, PetscInt(held_.size()), held_.data(), held_diagonal_, nullptr, nullptr));

  // GAMG's near-null space: the six rigid motions of the rest positions.
  Vec xyz = nullptr;
  INCISE_PETSC(MatCreateVecs(k_, &xyz, nullptr));
  INCISE_PETSC(VecSetBlockSize(xyz, 3));
  PetscScalar* xp = nullptr;
  INCISE_PETSC(VecGetArray(xyz, &xp));
  std::copy(p.coords.begin(), p.coords.end(), xp);
  INCISE_PETSC(VecRestoreArray(xyz, &xp));
  MatNullSpace nsp = nullptr;
  INCISE_PETSC(MatNullSpaceCreateRigidBody(xyz, &nsp));
  INCISE_PETSC(MatSetNearNullSpace(k_, nsp));
  INCISE_PETSC(MatNullSpaceDestroy(&nsp));
  INCISE_PETSC(VecDestroy(&xyz));

  INCISE_PETSC(MatCreateVecs(k_, &x_, &b_));
  if (!ksp_) {
    OptionsScope scope(options_db_);
    create_ksp();
  }
  INCISE_PETSC(KSPSetOperators(ksp_, k_, k_));
}

// b, x: this rank's rows (3 per owned vertex). x in: guess and held values; out: solution.
PetscSolveStats RankSystem::solve(const double* b, double* x) {
  PetscSolveStats st;
  const PetscInt nl = PetscInt(free_.size());
  double bn = 0;
  for (PetscInt i = 0; i < nl; ++i)
    if (free_[std::size_t(i)]) bn += b[i] * b[i];
  MPI_Allreduce(MPI_IN_PLACE, &bn, 1, MPI_DOUBLE, MPI_SUM, comm_);
  b_norm_ = std::sqrt(bn);
  if (b_norm_ == 0) {  // no load: the solution is zero on the free rows
    for (PetscInt i = 0; i < nl; ++i)
      if (free_[std::size_t(i)]) x[i] = 0;
    st.converged = true;
    st.reason = "CONVERGED_ZERO_RHS";
    return st;
  }
  PetscScalar *pb = nullptr, *px = nullptr;
  INCISE_PETSC(VecGetArray(b_, &pb));
  INCISE_PETSC(VecGetArray(x_, &px));
  for (PetscInt i = 0; i < nl; ++i) {
    px[i] = x[i];
    pb[i] = free_[std::size_t(i)] ? b[i] : held_diagonal_ * x[i];
  }
  INCISE_PETSC(VecRestoreArray(b_, &pb));
  INCISE_PETSC(VecRestoreArray(x_, &px));
  {
    OptionsScope scope(options_db_);  // GAMG reads its options at setup, inside the solve
    INCISE_PETSC(KSPSolve(ksp_, b_, x_));
  }
  PetscInt its = 0;
  KSPConvergedReason reason;
  INCISE_PETSC(KSPGetIterationNumber(ksp_, &its));
  INCISE_PETSC(KSPGetConvergedReason(ksp_, &reason));
  st.iterations = int(its);
  st.converged = reason > 0;
  st.reason = KSPConvergedReasons[reason];
  const PetscScalar* cx = nullptr;
  INCISE_PETSC(VecGetArrayRead(x_, &cx));
  std::copy(cx, cx + nl, x);
  INCISE_PETSC(VecRestoreArrayRead(x_, &cx));
  return st;
}

void RankSystem::destroy_matrix() {
  if (k_) MatDestroy(&k_);
  if (x_) VecDestroy(&x_);
  if (b_) VecDestroy(&b_);
}

// K += c B^T B (nodal-averaged and edge-smoothed: the model's B, rows split evenly).
void RankSystem::add_b_transpose_b(const Header& h, const Part& p, PetscInt nl) {
  const std::vector<PetscInt> bs = split(h.b_rows, size_);
  const PetscInt mb = bs[std::size_t(rank_) + 1] - bs[std::size_t(rank_)];
  Mat bmat = nullptr, btb = nullptr;
  INCISE_PETSC(MatCreate(comm_, &bmat));
  INCISE_PETSC(MatSetSizes(bmat, mb, 3 * nl, PetscInt(h.b_rows), 3 * PetscInt(n_)));
  INCISE_PETSC(MatSetType(bmat, MATAIJ));
  INCISE_PETSC(MatSeqAIJSetPreallocationCSR(bmat, p.b_ptr.data(), p.b_col.data(), p.b_val.data()));
  INCISE_PETSC(MatMPIAIJSetPreallocationCSR(bmat, p.b_ptr.data(), p.b_col.data(), p.b_val.data()));
  INCISE_PETSC(MatTransposeMatMult(bmat, bmat, MAT_INITIAL_MATRIX, PETSC_DEFAULT, &btb));
  INCISE_PETSC(MatAXPY(k_, h.c, btb, DIFFERENT_NONZERO_PATTERN));
  INCISE_PETSC(MatDestroy(&btb));
  INCISE_PETSC(MatDestroy(&bmat));
  PetscInt bsz = 0;
  INCISE_PETSC(MatGetBlockSize(k_, &bsz));
  if (bsz != 3) INCISE_PETSC(MatSetBlockSize(k_, 3));
}

// Converged when the residual is rtol times the free rows' right-hand side (the measure
// incise's CG uses: the held rows' diagonal * value must not loosen it).
PetscErrorCode RankSystem::converged(KSP ksp, PetscInt it, PetscReal rnorm, KSPConvergedReason* reason, void* ctx) {
  const RankSystem& s = *static_cast<const RankSystem*>(ctx);
  PetscReal rtol = 0, atol = 0, dtol = 0;
  PetscInt maxit = 0;
  PetscCall(KSPGetTolerances(ksp, &rtol, &atol, &dtol, &maxit));
  *reason = KSP_CONVERGED_ITERATING;
  if (!std::isfinite(rnorm)) *reason = KSP_DIVERGED_NANORINF;
  else if (rnorm <= std::max(rtol * s.b_norm_, atol)) *reason = KSP_CONVERGED_RTOL;
  else if (it >= maxit) *reason = KSP_DIVERGED_ITS;
  return 0;
}

void RankSystem::create_ksp() {
  INCISE_PETSC(KSPCreate(comm_, &ksp_));
  INCISE_PETSC(KSPSetType(ksp_, KSPCG));
  PC pc = nullptr;
  INCISE_PETSC(KSPGetPC(ksp_, &pc));
  INCISE_PETSC(PCSetType(pc, PCGAMG));
  INCISE_PETSC(KSPSetTolerances(ksp_, rtol_, PETSC_DEFAULT, PETSC_DEFAULT, max_iterations_));
  INCISE_PETSC(KSPSetInitialGuessNonzero(ksp_, PETSC_TRUE));
  INCISE_PETSC(KSPSetConvergenceTest(ksp_, &RankSystem::converged, this, nullptr));
  INCISE_PETSC(KSPSetFromOptions(ksp_));
  // CG measures the true residual, as incise's own CG does; other methods keep their norm.
  KSPType type = nullptr;
  INCISE_PETSC(KSPGetType(ksp_, &type));
  if (std::strcmp(type, KSPCG) == 0) INCISE_PETSC(KSPSetNormType(ksp_, KSP_NORM_UNPRECONDITIONED));
}

}  // namespace incise::petsc_detail
