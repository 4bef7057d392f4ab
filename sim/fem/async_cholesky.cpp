#include "sim/fem/async_cholesky.h"

#include "mesh/clock.h"
#include "sim/linalg/blas_threads.h"

#include <atomic>
#include <chrono>

#ifdef __linux__
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>
#endif
#include <cmath>

#include <Eigen/SVD>
#include <Eigen/SparseCore>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#ifdef INCISE_HAVE_CHOLMOD
#include <Eigen/CholmodSupport>
#else
#include <Eigen/SparseCholesky>
#endif

namespace incise {

namespace {
#ifdef INCISE_HAVE_CHOLMOD
using FactorType = Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>, Eigen::Lower>;
#else
using FactorType = Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower>;
#endif

// The factorization thread yields to the frame: at the lowest priority it runs on what the
// frame's parallel loops leave idle, instead of halving them (at normal priority a 2 ms budget
// often did not hold while the first factor ran: docs/solver.md#behind-the-constants). Linux sets nice per thread;
// elsewhere this does nothing.
void yield_to_frames() {
#ifdef __linux__
  setpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)), 19);
#endif
}
}  // namespace

struct AsyncCholesky::Factor {
  FactorType llt;
  std::vector<std::int32_t> index;  // per unknown at the snapshot: its row in the factor, -1 if kept
  Eigen::Index rows = 0;
  bool ok = false;
  double ms = 0;
};

namespace {

// Runs on the background thread, or on the frame's for a factor the frame waits for; owns
// everything it reads. Stops (a factor with ok false) at the next phase once `cancel` is set.
std::shared_ptr<AsyncCholesky::Factor> factorize(const FemElements& e, const Eigen::VectorXd& mass,
                                                 const std::vector<std::uint8_t>& free, double a, double c,
                                                 const std::atomic<bool>& cancel) {
  const double t0 = now_ms();
  auto f = std::make_shared<AsyncCholesky::Factor>();
  auto cancelled = [&] { return cancel.load(std::memory_order_relaxed); };
  f->index.assign(free.size(), -1);
  for (std::size_t i = 0; i < free.size(); ++i)
    if (free[i]) f->index[i] = std::int32_t(f->rows++);
  std::vector<Eigen::Triplet<double>> lower;  // the factorizations read the lower triangle only
  lower.reserve(e.alive.size() * 78);
  for (std::size_t t = 0; t < e.alive.size(); ++t) {
    if (t % 4096 == 0 && cancelled()) return f;
    if (!e.alive[t]) continue;
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) {
        const Eigen::Matrix3d blk = c * e.block(t, i, j);
        for (int p = 0; p < 3; ++p) {
          const std::int32_t row = f->index[3 * e.verts[t][std::size_t(i)] + std::size_t(p)];
          if (row < 0) continue;
          for (int q = 0; q < 3; ++q) {
            const std::int32_t col = f->index[3 * e.verts[t][std::size_t(j)] + std::size_t(q)];
            if (col >= 0 && row >= col) lower.emplace_back(row, col, blk(p, q));
          }
        }
      }
  }
  // Nodal-averaged: the volumetric term B^T B (the blocks above are the deviatoric part), so
  // the factor is of the whole K, not an approximation of it.
  if (e.nodal_b.rows() > 0 && !cancelled()) {
    const Eigen::SparseMatrix<double> bc = e.nodal_b, bt = e.nodal_b.transpose();
    const Eigen::SparseMatrix<double> kv = bt * bc;
    for (Eigen::Index col = 0; col < kv.outerSize(); ++col) {
      const std::int32_t cf = col < Eigen::Index(f->index.size()) ? f->index[std::size_t(col)] : -1;
      if (cf < 0) continue;
      for (Eigen::SparseMatrix<double>::InnerIterator it(kv, col); it; ++it) {
        const std::int32_t rf = it.row() < Eigen::Index(f->index.size()) ? f->index[std::size_t(it.row())] : -1;
        if (rf >= cf) lower.emplace_back(rf, cf, c * it.value());
      }
    }
  }
  if (a != 0)
    for (std::size_t i = 0; i < free.size(); ++i)
      if (f->index[i] >= 0) lower.emplace_back(f->index[i], f->index[i], a * mass[Eigen::Index(i)]);
  if (cancelled()) return f;
  Eigen::SparseMatrix<double> k(f->rows, f->rows);
  k.setFromTriplets(lower.begin(), lower.end());
  lower = {};
#ifdef INCISE_HAVE_CHOLMOD
  f->llt.cholmod().print = 0;  // a failure (not positive definite) is reported by ok, not on stdout
#endif
  if (cancelled()) return f;
  f->llt.analyzePattern(k);  // the ordering, then the numeric factor: a phase each
  if (f->llt.info() != Eigen::Success || cancelled()) return f;
  f->llt.factorize(k);
  f->ok = f->llt.info() == Eigen::Success;
  f->ms = now_ms() - t0;
  return f;
}

}  // namespace

AsyncCholesky::AsyncCholesky(const FemModel& model, const AsyncCholeskyOptions& options)
    : model_(&model), opt_(options) {
  single_threaded_blas();
}

AsyncCholesky::~AsyncCholesky() {
  if (!job_.valid()) return;
  if (cancel_) cancel_->store(true, std::memory_order_relaxed);
  job_.wait();
}

bool AsyncCholesky::has_factor() const { return factor_ != nullptr; }

void AsyncCholesky::mark_stale() { stale_ = true; }

void AsyncCholesky::start(const std::vector<std::uint8_t>& free, double a, double c) {
  std::size_t nfree = 0;
  for (std::uint8_t f : free) nfree += f;
  too_large_ = nfree > opt_.max_unknowns;
  stale_ = false;
  snapshot_a_ = a;
  snapshot_c_ = c;
  if (too_large_ || nfree == 0) {
    factor_.reset();
    return;
  }
  changed_since_snapshot_.clear();
  added_since_snapshot_.clear();
  touched_since_snapshot_.clear();
  job_changes_ = changes_;
  // The snapshot is taken here, on the frame thread (a copy of the per-tet arrays); the job
  // owns it, so later edits and rotations never race with the factorization.
  FemElements elements = model_->elements();
  pending_rot_ = opt_.rotate && model_->kind() == FemKind::Corotational
                     ? std::make_shared<const std::vector<Eigen::Matrix3d>>(elements.rot)
                     : nullptr;
  // A factor the frame waits for (the first one, with wait_for_first) is made on the frame's
  // thread: on the lowest-priority thread, a machine busy with other processes would leave the
  // frame blocked on a thread that hardly runs (docs/solver.md#behind-the-constants).
  const bool background = opt_.background && !(factor_ == nullptr && opt_.wait_for_first);
  cancel_ = std::make_shared<std::atomic<bool>>(false);
  auto task = [e = std::move(elements), mass = a != 0 ? model_->lumped_mass() : Eigen::VectorXd(), fr = free, a, c,
               background, cancel = cancel_] {
    if (background) yield_to_frames();  // a fresh thread per job (std::launch::async)
    return factorize(e, mass, fr, a, c, *cancel);
  };
  job_ = std::async(background ? std::launch::async : std::launch::deferred, std::move(task));
  background_factorizations_ += background;
}

void AsyncCholesky::adopt() {
  std::shared_ptr<Factor> f = job_.get();
  last_ms_ = f->ms;
  if (!f->ok) {  // keep the previous factor (still SPD); retry only after the next change
    failed_ = true;
    return;
  }
  failed_ = false;
  factor_ = std::move(f);
  factor_changes_ = job_changes_;
  snap_rot_ = std::move(pending_rot_);
  q_.clear();
  const std::size_t nv = factor_->index.size() / 3;
  uncovered_.assign(nv, 0);
  for (std::size_t v = 0; v < nv; ++v)
    for (int p = 0; p < 3; ++p)
      if (factor_->index[3 * v + std::size_t(p)] < 0) uncovered_[v] = 1;
  for (std::uint32_t v : changed_since_snapshot_)
    if (v < nv) uncovered_[v] = 1;
  changed_since_snapshot_.clear();
  mapped_.clear();
  // The new factor's rows are those of its snapshot: vertices an edit touched after it are
  // stale there and keep their block-Jacobi correction (they were dropped before).
  for (std::uint32_t v : touched_) touched_mark_[v] = 0;
  touched_.clear();
  for (std::uint32_t v : touched_since_snapshot_)
    if (v < nv && !uncovered_[v]) touch(v);
  touched_since_snapshot_.clear();
  for (const VertexOrigin& o : added_since_snapshot_) map_added(o);
  added_since_snapshot_.clear();
  ++version_;
  ++factorizations_;
}

bool AsyncCholesky::frame(const std::vector<std::uint8_t>& free, double a, double c, int last_iterations) {
  bool adopted = false;
  if (job_.valid() && (!opt_.background || job_.wait_for(std::chrono::seconds(0)) == std::future_status::ready)) {
    adopt();
    adopted = true;
  }
  if (a != snapshot_a_ || c != snapshot_c_) stale_ = true;
  // Settle policy: no factorization while the blade moves (it would be stale before it lands
  // and would take a core from the frame).
  const bool moving = opt_.settle_frames > 0 && quiet_frames_ < opt_.settle_frames;
  const bool want = stale_ || (!factor_ && !failed_ && !too_large_) ||
                    (factor_ && last_iterations > opt_.refactor_iterations);
  if (want && !moving && !job_.valid()) {
    start(free, a, c);
    if (job_.valid() && (!opt_.background || (!factor_ && opt_.wait_for_first))) {
      adopt();
      adopted = true;
    }
  }
  // Block-Jacobi alone until a factor of the settled topology is in use. A switch changes
  // the preconditioner, so CG restarts (version).
  const bool settling = opt_.settle_frames > 0 && factor_ && (moving || factor_changes_ != changes_);
  if (settling != settling_) {
    settling_ = settling;
    ++version_;
  }
  if (quiet_frames_ < (1 << 30)) ++quiet_frames_;
  return adopted;
}

void AsyncCholesky::map_added(const VertexOrigin& o) {
  const std::uint32_t v = o.vertex.idx();
  mapped_.erase(v);
  std::vector<std::pair<std::uint32_t, double>> row;
  for (int k = 0; k < 4; ++k) {
    if (!o.parents[std::size_t(k)].is_valid() || o.weights[std::size_t(k)] == 0) continue;
    const std::uint32_t p = o.parents[std::size_t(k)].idx();
    const double w = o.weights[std::size_t(k)];
    if (p < uncovered_.size() && !uncovered_[p]) {
      row.emplace_back(p, w);
    } else if (auto it = mapped_.find(p); it != mapped_.end()) {  // parents precede children
      for (const auto& [q, wq] : it->second) row.emplace_back(q, w * wq);
    }
  }
  if (!row.empty()) mapped_.emplace(v, std::move(row));
}

void AsyncCholesky::touch(std::uint32_t v) {
  // Once per vertex: a vertex touched by several edits got its correction added as often.
  if (touched_mark_.size() <= v) touched_mark_.resize(std::max<std::size_t>(uncovered_.size(), v + 1), 0);
  if (touched_mark_[v]) return;
  touched_mark_[v] = 1;
  touched_.push_back(v);
}

void AsyncCholesky::apply(const TopologyChange& change) {
  if (change.empty()) return;
  stale_ = true;
  quiet_frames_ = 0;
  ++changes_;
  failed_ = false;
  auto uncover = [&](VertexId v) {
    if (v.idx() < uncovered_.size()) uncovered_[v.idx()] = 1;
    mapped_.erase(v.idx());
    if (job_.valid()) changed_since_snapshot_.push_back(v.idx());
  };
  for (VertexId v : change.touched_vertices) {
    if (v.idx() < uncovered_.size() && !uncovered_[v.idx()]) touch(v.idx());
    if (job_.valid()) touched_since_snapshot_.push_back(v.idx());
  }
  for (const VertexOrigin& o : change.added_vertices) {
    uncover(o.vertex);
    map_added(o);
    if (job_.valid()) added_since_snapshot_.push_back(o);
  }
  // Removals last: a vertex the batch added and then removed is in both lists.
  for (VertexId v : change.removed_vertices) uncover(v);
}

void AsyncCholesky::setup(const LinearOperator& a, const std::vector<std::uint8_t>* free) {
  free_ = free;
  fallback_.setup(a, free);
  if (use_moving()) moving_->setup(a, free);
  if (!settling_) update_rotation_change();
}

namespace {

// The rotation closest to m (polar factor), m = sum of rotations near each other: a few
// Newton steps R <- (R + R^-T) / 2 from m scaled to unit determinant; the SVD when m is far
// from a rotation (det <= 0 or no convergence). Identity when m is ~0.
Eigen::Matrix3d nearest_rotation(const Eigen::Matrix3d& m) {
  const double det = m.determinant();
  if (det > 0 && std::isfinite(det)) {
    Eigen::Matrix3d r = m / std::cbrt(det);
    for (int it = 0; it < 8; ++it) {
      const Eigen::Matrix3d next = 0.5 * (r + r.inverse().transpose());
      const double change = (next - r).cwiseAbs().maxCoeff();
      r = next;
      if (change < 1e-12) return r;
    }
  }
  if (!(m.cwiseAbs().maxCoeff() > 0) || !m.allFinite()) return Eigen::Matrix3d::Identity();
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d u = svd.matrixU();
  if ((u * svd.matrixV().transpose()).determinant() < 0) u.col(2) = -u.col(2);
  return u * svd.matrixV().transpose();
}

}  // namespace

void AsyncCholesky::update_rotation_change() {
  q_.clear();
  if (!factor_ || !snap_rot_ || model_->kind() != FemKind::Corotational) return;
  const TetMesh& mesh = model_->mesh();
  const std::vector<Eigen::Matrix3d>& r0 = *snap_rot_;
  const std::size_t nv = std::min(uncovered_.size(), mesh.vertex_capacity());
  q_.assign(nv, Eigen::Matrix3d::Identity());
  // Tets born after the snapshot have no snapshot rotation; a reused tet id carries the old
  // tet's, which only makes q a little less apt (M stays SPD with any orthogonal q).
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, nv, 1024), [&](const tbb::blocked_range<std::size_t>& range) {
    for (std::size_t v = range.begin(); v != range.end(); ++v) {
      if (uncovered_[v] || !mesh.is_alive(VertexId(std::uint32_t(v)))) continue;
      Eigen::Matrix3d m = Eigen::Matrix3d::Zero();
      for (TetId t : mesh.incident_tets(VertexId(std::uint32_t(v))))
        if (t.idx() < r0.size() && model_->tet_alive(t))
          m.noalias() += model_->tet_volume(t) * model_->rotation(t) * r0[t.idx()].transpose();
      q_[v] = nearest_rotation(m);
    }
  });
}

void AsyncCholesky::apply(const Eigen::VectorXd& r, Eigen::VectorXd& z) const {
  if (!factor_ || settling_) {
    if (use_moving()) moving_->apply(r, z);
    else fallback_.apply(r, z);
    return;
  }
  const auto& idx = factor_->index;
  const std::size_t nv = std::size_t(r.size() / 3), ncov = std::min(nv, uncovered_.size());
  auto is_free = [&](std::size_t i) { return !free_ || (*free_)[i]; };
  // Q_v (identity without rotation); an added vertex moves like its first parent.
  auto q = [&](std::size_t v) -> const Eigen::Matrix3d* { return v < q_.size() ? &q_[v] : nullptr; };
  // r_v with kept unknowns zeroed, rotated back to the snapshot: Q_v^T r_v.
  auto r_back = [&](std::size_t v, const Eigen::Matrix3d* qv) {
    Eigen::Vector3d x;
    for (int c = 0; c < 3; ++c) x[c] = is_free(3 * v + std::size_t(c)) ? r[Eigen::Index(3 * v + std::size_t(c))] : 0.0;
    return qv ? Eigen::Vector3d(qv->transpose() * x) : x;
  };
  rf_.setZero(factor_->rows);
  for (std::size_t v = 0; v < ncov; ++v)
    if (!uncovered_[v]) {
      const Eigen::Vector3d x = r_back(v, q(v));
      for (int c = 0; c < 3; ++c) rf_[idx[3 * v + std::size_t(c)]] = x[c];
    }
  for (const auto& [v, row] : mapped_)  // P^T Q^T r: added vertices onto their parents' rows
    if (v < nv) {
      const Eigen::Vector3d x = r_back(v, q(row.front().first));
      for (const auto& [p, w] : row)
        for (int c = 0; c < 3; ++c) rf_[idx[3 * p + std::size_t(c)]] += w * x[c];
    }
  zf_ = factor_->llt.solve(rf_);
  auto zf_vertex = [&](std::size_t p) {
    return Eigen::Vector3d(zf_[idx[3 * p]], zf_[idx[3 * p + 1]], zf_[idx[3 * p + 2]]);
  };
  z.resize(r.size());
  for (std::size_t v = 0; v < nv; ++v) {
    if (v < ncov && !uncovered_[v]) {
      const Eigen::Matrix3d* qv = q(v);
      const Eigen::Vector3d y = qv ? Eigen::Vector3d(*qv * zf_vertex(v)) : zf_vertex(v);
      for (int c = 0; c < 3; ++c) z[Eigen::Index(3 * v + std::size_t(c))] = is_free(3 * v + std::size_t(c)) ? y[c] : 0.0;
    } else {
      fallback_.apply_vertex(v, r, z);
    }
  }
  for (std::uint32_t v : touched_)  // + block-Jacobi where the factor's rows are stale
    if (v < nv && v < uncovered_.size() && !uncovered_[v]) {
      const Eigen::Vector3d keep = z.segment<3>(3 * Eigen::Index(v));
      fallback_.apply_vertex(v, r, z);
      z.segment<3>(3 * Eigen::Index(v)) += keep;
    }
  for (const auto& [v, row] : mapped_)  // + Q P F^-1 P^T Q^T r
    if (v < nv) {
      Eigen::Vector3d y = Eigen::Vector3d::Zero();
      for (const auto& [p, w] : row) y += w * zf_vertex(p);
      if (const Eigen::Matrix3d* qv = q(row.front().first)) y = *qv * y;
      for (int c = 0; c < 3; ++c)
        if (is_free(3 * v + std::size_t(c))) z[Eigen::Index(3 * v + std::size_t(c))] += y[c];
    }
}

}  // namespace incise
