// PetscSolver (sim/petsc/petsc_solver.h): rank 0 cuts the model's elements into per-rank parts,
// every rank assembles its own rows into one distributed matrix and runs the KSP.
#include "sim/petsc/petsc_solver.h"

#include <algorithm>
#include <chrono>
#include <climits>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <map>

#include <Eigen/SparseCore>

#include "mesh/clock.h"
#include "mesh/errors.h"
#include "sim/fem_model.h"
#include "sim/petsc/petsc_internal.h"
#include "sim/petsc/petsc_session.h"
#include "sim/petsc/vertex_partition.h"

namespace incise {

bool petsc_built() { return true; }

namespace petsc_detail {

namespace {

constexpr int kTetData = 21;  // per tet: shape matrix (9), rotation (9), volume, mu, lambda

// What one rank receives to assemble its rows.
struct Part {
  std::vector<std::uint32_t> tet_verts;  // #T by 4: the tets touching the rank's vertices
  std::vector<double> tet_data;          // #T by kTetData
  std::vector<std::uint8_t> free;        // per owned unknown
  std::vector<double> mass, coords;      // per owned unknown: lumped mass, rest position
  std::vector<PetscInt> b_ptr, b_col;    // B's rows of this rank's share (CSR, global columns)
  std::vector<double> b_val;
};

struct Header {
  long long vertices = 0, b_rows = 0;
  double a = 0, c = 1;
};

// Contiguous ranges: rank r owns [n r / size, n (r + 1) / size).
std::vector<PetscInt> split(long long n, int size) {
  std::vector<PetscInt> s(static_cast<std::size_t>(size) + 1);
  for (int r = 0; r <= size; ++r) s[std::size_t(r)] = PetscInt(n * r / size);
  return s;
}

constexpr int kTag = 4711;

template <class T>
void send_vector(const std::vector<T>& v, int dest, MPI_Comm comm) {
  long long n = (long long)v.size();
  MPI_Send(&n, 1, MPI_LONG_LONG, dest, kTag, comm);
  const char* p = reinterpret_cast<const char*>(v.data());
  for (long long left = n * (long long)sizeof(T); left > 0;) {
    const int chunk = int(std::min<long long>(left, INT_MAX / 2));
    MPI_Send(p, chunk, MPI_BYTE, dest, kTag, comm);
    p += chunk;
    left -= chunk;
  }
}

template <class T>
void receive_vector(std::vector<T>& v, MPI_Comm comm) {
  long long n = 0;
  MPI_Recv(&n, 1, MPI_LONG_LONG, 0, kTag, comm, MPI_STATUS_IGNORE);
  v.resize(std::size_t(n));
  char* p = reinterpret_cast<char*>(v.data());
  for (long long left = n * (long long)sizeof(T); left > 0;) {
    const int chunk = int(std::min<long long>(left, INT_MAX / 2));
    MPI_Recv(p, chunk, MPI_BYTE, 0, kTag, comm, MPI_STATUS_IGNORE);
    p += chunk;
    left -= chunk;
  }
}

void send_part(const Part& p, int dest, MPI_Comm comm) {
  send_vector(p.tet_verts, dest, comm);
  send_vector(p.tet_data, dest, comm);
  send_vector(p.free, dest, comm);
  send_vector(p.mass, dest, comm);
  send_vector(p.coords, dest, comm);
  send_vector(p.b_ptr, dest, comm);
  send_vector(p.b_col, dest, comm);
  send_vector(p.b_val, dest, comm);
}

void receive_part(Part& p, MPI_Comm comm) {
  receive_vector(p.tet_verts, comm);
  receive_vector(p.tet_data, comm);
  receive_vector(p.free, comm);
  receive_vector(p.mass, comm);
  receive_vector(p.coords, comm);
  receive_vector(p.b_ptr, comm);
  receive_vector(p.b_col, comm);
  receive_vector(p.b_val, comm);
}

}  // namespace

// One solver's share on one rank: its rows of the matrix, its KSP.
class System {
public:
  System(MPI_Comm comm, const std::string& options, double rtol, int max_iterations)
      : comm_(comm), options_(options), rtol_(rtol), max_iterations_(max_iterations) {
    MPI_Comm_rank(comm_, &rank_);
    MPI_Comm_size(comm_, &size_);
    // Each solver reads its own options: PETSC_OPTIONS, then its scene's string (which wins).
    // The global database would carry one scene's choices into the next solver of the process.
    INCISE_PETSC(PetscOptionsCreate(&options_db_));
    if (const char* env = std::getenv("PETSC_OPTIONS")) INCISE_PETSC(PetscOptionsInsertString(options_db_, env));
    if (!options_.empty()) INCISE_PETSC(PetscOptionsInsertString(options_db_, options_.c_str()));
  }
  ~System() {
    PetscBool fin = PETSC_FALSE;
    PetscFinalized(&fin);
    if (fin) return;  // PETSc already went (process exit): nothing left to free
    destroy_matrix();
    if (ksp_) KSPDestroy(&ksp_);
    if (options_db_) PetscOptionsDestroy(&options_db_);
  }
  int size() const { return size_; }
  PetscOptions options() const { return options_db_; }
  const std::vector<PetscInt>& vertex_start() const { return vstart_; }

  // starts: the first row block (vertex) of each rank, size + 1 entries.
  void assemble(const Header& h, const std::vector<PetscInt>& starts, const Part& p) {
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
  PetscSolveStats solve(const double* b, double* x) {
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

private:
  void destroy_matrix() {
    if (k_) MatDestroy(&k_);
    if (x_) VecDestroy(&x_);
    if (b_) VecDestroy(&b_);
  }

  // K += c B^T B (nodal-averaged and edge-smoothed: the model's B, rows split evenly).
  void add_b_transpose_b(const Header& h, const Part& p, PetscInt nl) {
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
  static PetscErrorCode converged(KSP ksp, PetscInt it, PetscReal rnorm, KSPConvergedReason* reason, void* ctx) {
    const System& s = *static_cast<const System*>(ctx);
    PetscReal rtol = 0, atol = 0, dtol = 0;
    PetscInt maxit = 0;
    PetscCall(KSPGetTolerances(ksp, &rtol, &atol, &dtol, &maxit));
    *reason = KSP_CONVERGED_ITERATING;
    if (!std::isfinite(rnorm)) *reason = KSP_DIVERGED_NANORINF;
    else if (rnorm <= std::max(rtol * s.b_norm_, atol)) *reason = KSP_CONVERGED_RTOL;
    else if (it >= maxit) *reason = KSP_DIVERGED_ITS;
    return 0;
  }

  void create_ksp() {
    INCISE_PETSC(KSPCreate(comm_, &ksp_));
    INCISE_PETSC(KSPSetType(ksp_, KSPCG));
    PC pc = nullptr;
    INCISE_PETSC(KSPGetPC(ksp_, &pc));
    INCISE_PETSC(PCSetType(pc, PCGAMG));
    INCISE_PETSC(KSPSetTolerances(ksp_, rtol_, PETSC_DEFAULT, PETSC_DEFAULT, max_iterations_));
    INCISE_PETSC(KSPSetInitialGuessNonzero(ksp_, PETSC_TRUE));
    INCISE_PETSC(KSPSetConvergenceTest(ksp_, &System::converged, this, nullptr));
    INCISE_PETSC(KSPSetFromOptions(ksp_));
    // CG measures the true residual, as incise's own CG does; other methods keep their norm.
    KSPType type = nullptr;
    INCISE_PETSC(KSPGetType(ksp_, &type));
    if (std::strcmp(type, KSPCG) == 0) INCISE_PETSC(KSPSetNormType(ksp_, KSP_NORM_UNPRECONDITIONED));
  }

  // The solver's options as the default database while it lives in PETSc calls.
  struct OptionsScope {
    explicit OptionsScope(PetscOptions o) { INCISE_PETSC(PetscOptionsPush(o)); }
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

namespace {

std::map<int, std::unique_ptr<System>>& served() {
  static std::map<int, std::unique_ptr<System>> m;
  return m;
}

// Scatter (rank 0 -> ranks) or gather the rows of a vector of 3 per vertex slot.
void scatter_rows(const System& s, const double* all, std::vector<double>& mine, MPI_Comm comm) {
  const auto& vs = s.vertex_start();
  std::vector<int> counts(static_cast<std::size_t>(s.size())), displs(static_cast<std::size_t>(s.size()));
  for (int r = 0; r < s.size(); ++r) {
    counts[std::size_t(r)] = int(3 * (vs[std::size_t(r) + 1] - vs[std::size_t(r)]));
    displs[std::size_t(r)] = int(3 * vs[std::size_t(r)]);
  }
  int rank = 0;
  MPI_Comm_rank(comm, &rank);
  mine.resize(std::size_t(counts[std::size_t(rank)]));
  MPI_Scatterv(all, counts.data(), displs.data(), MPI_DOUBLE, mine.data(), counts[std::size_t(rank)], MPI_DOUBLE, 0, comm);
}
void gather_rows(const System& s, const std::vector<double>& mine, double* all, MPI_Comm comm) {
  const auto& vs = s.vertex_start();
  std::vector<int> counts(static_cast<std::size_t>(s.size())), displs(static_cast<std::size_t>(s.size()));
  for (int r = 0; r < s.size(); ++r) {
    counts[std::size_t(r)] = int(3 * (vs[std::size_t(r) + 1] - vs[std::size_t(r)]));
    displs[std::size_t(r)] = int(3 * vs[std::size_t(r)]);
  }
  MPI_Gatherv(mine.data(), int(mine.size()), MPI_DOUBLE, all, counts.data(), displs.data(), MPI_DOUBLE, 0, comm);
}

void broadcast_string(std::string& s, MPI_Comm comm) {
  long long n = (long long)s.size();
  MPI_Bcast(&n, 1, MPI_LONG_LONG, 0, comm);
  s.resize(std::size_t(n));
  if (n) MPI_Bcast(s.data(), int(n), MPI_CHAR, 0, comm);
}

}  // namespace

void serve_command(Command c, int id) {
  MPI_Comm comm = PETSC_COMM_WORLD;
  switch (c) {
    case kCreate: {
      std::string options;
      broadcast_string(options, comm);
      double rtol = 0;
      int maxit = 0;
      MPI_Bcast(&rtol, 1, MPI_DOUBLE, 0, comm);
      MPI_Bcast(&maxit, 1, MPI_INT, 0, comm);
      served()[id] = std::make_unique<System>(comm, options, rtol, maxit);
      break;
    }
    case kAssemble: {
      Header h;
      MPI_Bcast(&h, int(sizeof h), MPI_BYTE, 0, comm);
      int size = 0;
      MPI_Comm_size(comm, &size);
      std::vector<PetscInt> starts(static_cast<std::size_t>(size) + 1);
      MPI_Bcast(starts.data(), size + 1, MPIU_INT, 0, comm);
      Part p;
      receive_part(p, comm);
      served().at(id)->assemble(h, starts, p);
      break;
    }
    case kSolve: {
      System& s = *served().at(id);
      std::vector<double> b, x;
      scatter_rows(s, nullptr, b, comm);
      scatter_rows(s, nullptr, x, comm);
      s.solve(b.data(), x.data());
      gather_rows(s, x, nullptr, comm);
      break;
    }
    case kDestroy: served().erase(id); break;
    case kFinish: served().clear(); break;
    case kMemory: break;  // petsc_serve answers it
  }
}

}  // namespace petsc_detail

using namespace petsc_detail;

struct PetscSolver::Impl {
  MPI_Comm comm = PETSC_COMM_SELF;
  bool distributed = false;
  int id = 0;
  std::unique_ptr<System> system;
  // Over several ranks: the rows' order (vertex slot -> row block; empty: the slots' own order)
  // and each rank's first row block. Kept while the slot count is, redone when it grows.
  std::vector<PetscInt> perm, starts;
  // b or x (3 per vertex slot) in the rows' order, and back.
  void to_rows(const Eigen::VectorXd& v, std::vector<double>& out) const {
    out.resize(std::size_t(v.size()));
    for (std::size_t s = 0; s < perm.size(); ++s)
      for (int k = 0; k < 3; ++k) out[std::size_t(3 * perm[s] + k)] = v[Eigen::Index(3 * s + std::size_t(k))];
  }
  void from_rows(const std::vector<double>& in, Eigen::VectorXd& v) const {
    for (std::size_t s = 0; s < perm.size(); ++s)
      for (int k = 0; k < 3; ++k) v[Eigen::Index(3 * s + std::size_t(k))] = in[std::size_t(3 * perm[s] + k)];
  }
};

PetscSolver::PetscSolver(const std::string& options, double tolerance, int max_iterations) : impl_(new Impl) {
  ensure_initialized();
  Impl& m = *impl_;
  m.distributed = petsc_distributed();
  m.comm = m.distributed ? PETSC_COMM_WORLD : PETSC_COMM_SELF;
  if (m.distributed) {
    m.id = state().next_id++;
    broadcast_command(kCreate, m.id);
    std::string o = options;
    broadcast_string(o, m.comm);
    MPI_Bcast(&tolerance, 1, MPI_DOUBLE, 0, m.comm);
    MPI_Bcast(&max_iterations, 1, MPI_INT, 0, m.comm);
  }
  m.system = std::make_unique<System>(m.comm, options, tolerance, max_iterations);
}

PetscSolver::~PetscSolver() {
  if (impl_->distributed && petsc_distributed()) broadcast_command(kDestroy, impl_->id);
}

int PetscSolver::ranks() const { return impl_->system->size(); }

void PetscSolver::compute(const FemModel& model, double a, double c, const std::vector<std::uint8_t>& free) {
  const auto t0 = std::chrono::steady_clock::now();
  Impl& m = *impl_;
  const FemElements e = model.elements();
  const int size = m.system->size();
  Header h;
  h.vertices = (long long)model.vertex_slots();
  h.a = a;
  h.c = c;
  Eigen::SparseMatrix<double, Eigen::RowMajor> bmat = e.nodal_b;
  bmat.makeCompressed();
  h.b_rows = bmat.rows();
  if (size > 1 && m.perm.size() != std::size_t(h.vertices))
    partition_vertices(e, std::size_t(h.vertices), size, m.system->options(), m.perm, m.starts);
  else if (size == 1)
    m.starts = split(h.vertices, 1);
  const std::vector<PetscInt>& vs = m.starts;
  const std::vector<PetscInt> bs = split(h.b_rows, size);
  std::vector<std::uint32_t> slot_of;  // row block -> vertex slot
  if (!m.perm.empty()) {
    slot_of.resize(m.perm.size());
    for (std::size_t v = 0; v < m.perm.size(); ++v) slot_of[std::size_t(m.perm[v])] = std::uint32_t(v);
  }
  auto row_of = [&](std::uint32_t v) { return m.perm.empty() ? PetscInt(v) : m.perm[v]; };
  auto owner = [&](std::uint32_t v) { return int(std::upper_bound(vs.begin(), vs.end(), row_of(v)) - vs.begin()) - 1; };
  // Each tet goes to every rank owning one of its vertices.
  std::vector<std::vector<std::uint32_t>> tets(static_cast<std::size_t>(size));
  for (std::size_t t = 0; t < e.alive.size(); ++t) {
    if (!e.alive[t]) continue;
    int seen[4];
    int k = 0;
    for (std::uint32_t v : e.verts[t]) {
      const int r = owner(v);
      if (std::find(seen, seen + k, r) == seen + k) {
        seen[k++] = r;
        tets[std::size_t(r)].push_back(std::uint32_t(t));
      }
    }
  }
  const Eigen::VectorXd& mass = model.lumped_mass();
  const TetMesh& mesh = model.mesh();
  auto part_of = [&](int r) {
    Part p;
    const auto& ts = tets[std::size_t(r)];
    p.tet_verts.reserve(4 * ts.size());
    p.tet_data.reserve(kTetData * ts.size());
    for (std::uint32_t t : ts) {
      for (std::uint32_t v : e.verts[t]) p.tet_verts.push_back(std::uint32_t(row_of(v)));
      p.tet_data.insert(p.tet_data.end(), e.bm[t].data(), e.bm[t].data() + 9);
      p.tet_data.insert(p.tet_data.end(), e.rot[t].data(), e.rot[t].data() + 9);
      p.tet_data.push_back(e.vol[t]);
      p.tet_data.push_back(e.mu[t]);
      p.tet_data.push_back(e.lambda[t]);
    }
    for (PetscInt row = vs[std::size_t(r)]; row < vs[std::size_t(r) + 1]; ++row) {
      const PetscInt v = slot_of.empty() ? row : PetscInt(slot_of[std::size_t(row)]);
      const bool alive = std::size_t(v) < mesh.vertex_capacity() && mesh.is_alive(VertexId(std::uint32_t(v)));
      const Vec3 x = alive ? mesh.rest(VertexId(std::uint32_t(v))) : Vec3::Zero();
      for (int k = 0; k < 3; ++k) {
        const std::size_t i = std::size_t(3 * v + k);
        p.free.push_back(free[i]);
        p.mass.push_back(mass[Eigen::Index(i)]);
        p.coords.push_back(x[k]);
      }
    }
    const PetscInt r0 = bs[std::size_t(r)], r1 = bs[std::size_t(r) + 1];
    if (h.b_rows > 0) {
      const auto* outer = bmat.outerIndexPtr();
      p.b_ptr.reserve(std::size_t(r1 - r0 + 1));
      for (PetscInt i = r0; i <= r1; ++i) p.b_ptr.push_back(PetscInt(outer[i] - outer[r0]));
      // Columns in the rows' order, sorted again within each row.
      std::vector<std::pair<PetscInt, double>> entries;
      for (PetscInt i = r0; i < r1; ++i) {
        entries.clear();
        for (auto k = outer[i]; k < outer[i + 1]; ++k) {
          const auto col = bmat.innerIndexPtr()[k];
          entries.emplace_back(3 * row_of(std::uint32_t(col / 3)) + PetscInt(col % 3), bmat.valuePtr()[k]);
        }
        std::sort(entries.begin(), entries.end());
        for (const auto& [col, val] : entries) {
          p.b_col.push_back(col);
          p.b_val.push_back(val);
        }
      }
    }
    return p;
  };
  if (m.distributed) {
    try {
      broadcast_command(kAssemble, m.id);
      MPI_Bcast(&h, int(sizeof h), MPI_BYTE, 0, m.comm);
      MPI_Bcast(m.starts.data(), size + 1, MPIU_INT, 0, m.comm);
      for (int r = 1; r < size; ++r) send_part(part_of(r), r, m.comm);
    } catch (const std::exception& ex) {
      abort_all(std::string("petsc: rank 0: ") + ex.what());
    }
  }
  m.system->assemble(h, m.starts, part_of(0));
  assemble_ms_ = ms_since(t0);
}

PetscSolveStats PetscSolver::solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  Impl& m = *impl_;
  System& s = *m.system;
  std::vector<double> bl, xl;
  if (m.distributed) broadcast_command(kSolve, m.id);
  PetscSolveStats st;
  if (m.perm.empty()) {
    scatter_rows(s, b.data(), bl, m.comm);
    scatter_rows(s, x.data(), xl, m.comm);
    st = s.solve(bl.data(), xl.data());
    gather_rows(s, xl, x.data(), m.comm);
  } else {
    std::vector<double> rows;
    m.to_rows(b, rows);
    scatter_rows(s, rows.data(), bl, m.comm);
    m.to_rows(x, rows);
    scatter_rows(s, rows.data(), xl, m.comm);
    st = s.solve(bl.data(), xl.data());
    gather_rows(s, xl, rows.data(), m.comm);
    m.from_rows(rows, x);
  }
  st.assemble_ms = assemble_ms_;
  return st;
}

}  // namespace incise
