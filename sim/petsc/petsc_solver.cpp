// PetscSolver (sim/petsc/petsc_solver.h): rank 0 cuts the model's elements into per-rank parts,
// every rank assembles its own rows into one distributed matrix and runs the KSP.
#include "sim/petsc/petsc_solver.h"

#include <algorithm>
#include <chrono>
#include <map>
#include <memory>

#include <Eigen/SparseCore>

#include "mesh/clock.h"
#include "mesh/errors.h"
#include "sim/fem/fem_model.h"
#include "sim/petsc/petsc_internal.h"
#include "sim/petsc/petsc_session.h"
#include "sim/petsc/rank_messages.h"
#include "sim/petsc/rank_system.h"
#include "sim/petsc/vertex_partition.h"

namespace incise {

bool petsc_built() { return true; }

namespace petsc_detail {

namespace {

std::map<int, std::unique_ptr<RankSystem>>& served() {
  static std::map<int, std::unique_ptr<RankSystem>> m;
  return m;
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
      served()[id] = std::make_unique<RankSystem>(comm, options, rtol, maxit);
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
      RankSystem& s = *served().at(id);
      std::vector<double> b, x;
      scatter_rows(s.vertex_start(), nullptr, b, comm);
      scatter_rows(s.vertex_start(), nullptr, x, comm);
      s.solve(b.data(), x.data());
      gather_rows(s.vertex_start(), x, nullptr, comm);
      break;
    }
    case kSaddle: serve_saddle(comm); break;
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
  std::unique_ptr<RankSystem> system;
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
  m.system = std::make_unique<RankSystem>(m.comm, options, tolerance, max_iterations);
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
  RankSystem& s = *m.system;
  std::vector<double> bl, xl;
  if (m.distributed) broadcast_command(kSolve, m.id);
  PetscSolveStats st;
  if (m.perm.empty()) {
    scatter_rows(s.vertex_start(), b.data(), bl, m.comm);
    scatter_rows(s.vertex_start(), x.data(), xl, m.comm);
    st = s.solve(bl.data(), xl.data());
    gather_rows(s.vertex_start(), xl, x.data(), m.comm);
  } else {
    std::vector<double> rows;
    m.to_rows(b, rows);
    scatter_rows(s.vertex_start(), rows.data(), bl, m.comm);
    m.to_rows(x, rows);
    scatter_rows(s.vertex_start(), rows.data(), xl, m.comm);
    st = s.solve(bl.data(), xl.data());
    gather_rows(s.vertex_start(), xl, rows.data(), m.comm);
    m.from_rows(rows, x);
  }
  st.assemble_ms = assemble_ms_;
  return st;
}

}  // namespace incise
