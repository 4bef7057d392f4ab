#include "sim/async_cholesky.h"

#include <chrono>

#include <Eigen/SparseCore>
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

double now_ms() {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch()).count();
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

// Runs on the background thread; owns everything it reads.
std::shared_ptr<AsyncCholesky::Factor> factorize(const FemElements& e, const Eigen::VectorXd& mass,
                                                 const std::vector<std::uint8_t>& free, double a, double c) {
  const double t0 = now_ms();
  auto f = std::make_shared<AsyncCholesky::Factor>();
  f->index.assign(free.size(), -1);
  for (std::size_t i = 0; i < free.size(); ++i)
    if (free[i]) f->index[i] = std::int32_t(f->rows++);
  std::vector<Eigen::Triplet<double>> lower;  // the factorizations read the lower triangle only
  lower.reserve(e.alive.size() * 78);
  for (std::size_t t = 0; t < e.alive.size(); ++t) {
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
  if (a != 0)
    for (std::size_t i = 0; i < free.size(); ++i)
      if (f->index[i] >= 0) lower.emplace_back(f->index[i], f->index[i], a * mass[Eigen::Index(i)]);
  Eigen::SparseMatrix<double> k(f->rows, f->rows);
  k.setFromTriplets(lower.begin(), lower.end());
  lower = {};
  f->llt.compute(k);
  f->ok = f->llt.info() == Eigen::Success;
  f->ms = now_ms() - t0;
  return f;
}

}  // namespace

AsyncCholesky::AsyncCholesky(const FemModel& model, const AsyncCholeskyOptions& options)
    : model_(&model), opt_(options) {}

AsyncCholesky::~AsyncCholesky() {
  if (job_.valid()) job_.wait();
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
  // The snapshot is taken here, on the frame thread (a copy of the per-tet arrays); the job
  // owns it, so later edits and rotations never race with the factorization.
  auto task = [e = model_->elements(), mass = a != 0 ? model_->lumped_mass() : Eigen::VectorXd(), fr = free, a, c] {
    return factorize(e, mass, fr, a, c);
  };
  job_ = std::async(opt_.background ? std::launch::async : std::launch::deferred, std::move(task));
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
  const std::size_t nv = factor_->index.size() / 3;
  uncovered_.assign(nv, 0);
  for (std::size_t v = 0; v < nv; ++v)
    for (int p = 0; p < 3; ++p)
      if (factor_->index[3 * v + std::size_t(p)] < 0) uncovered_[v] = 1;
  for (std::uint32_t v : changed_since_snapshot_)
    if (v < nv) uncovered_[v] = 1;
  changed_since_snapshot_.clear();
  mapped_.clear();
  touched_.clear();
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
  const bool want = stale_ || (!factor_ && !failed_ && !too_large_) ||
                    (factor_ && last_iterations > opt_.refactor_iterations);
  if (want && !job_.valid()) {
    start(free, a, c);
    if (job_.valid() && (!opt_.background || (!factor_ && opt_.wait_for_first))) {
      adopt();
      adopted = true;
    }
  }
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

void AsyncCholesky::apply(const TopologyChange& change) {
  if (change.empty()) return;
  stale_ = true;
  failed_ = false;
  auto uncover = [&](VertexId v) {
    if (v.idx() < uncovered_.size()) uncovered_[v.idx()] = 1;
    mapped_.erase(v.idx());
    if (job_.valid()) changed_since_snapshot_.push_back(v.idx());
  };
  for (VertexId v : change.removed_vertices) uncover(v);
  for (VertexId v : change.touched_vertices)
    if (v.idx() < uncovered_.size() && !uncovered_[v.idx()]) touched_.push_back(v.idx());
  for (const VertexOrigin& o : change.added_vertices) {
    uncover(o.vertex);
    map_added(o);
    if (job_.valid()) added_since_snapshot_.push_back(o);
  }
}

void AsyncCholesky::setup(const LinearOperator& a, const std::vector<std::uint8_t>* free) {
  free_ = free;
  fallback_.setup(a, free);
}

void AsyncCholesky::apply(const Eigen::VectorXd& r, Eigen::VectorXd& z) const {
  if (!factor_) {
    fallback_.apply(r, z);
    return;
  }
  const auto& idx = factor_->index;
  const std::size_t nv = std::size_t(r.size() / 3), ncov = std::min(nv, uncovered_.size());
  auto is_free = [&](std::size_t i) { return !free_ || (*free_)[i]; };
  rf_.setZero(factor_->rows);
  for (std::size_t v = 0; v < ncov; ++v)
    if (!uncovered_[v])
      for (std::size_t i = 3 * v; i < 3 * v + 3; ++i)
        if (is_free(i)) rf_[idx[i]] = r[Eigen::Index(i)];
  for (const auto& [v, row] : mapped_)  // P^T r: added vertices onto their parents' rows
    if (v < nv)
      for (int c = 0; c < 3; ++c)
        if (is_free(3 * v + std::size_t(c)))
          for (const auto& [p, w] : row) rf_[idx[3 * p + std::size_t(c)]] += w * r[Eigen::Index(3 * v + std::size_t(c))];
  zf_ = factor_->llt.solve(rf_);
  z.resize(r.size());
  for (std::size_t v = 0; v < nv; ++v) {
    if (v < ncov && !uncovered_[v]) {
      for (std::size_t i = 3 * v; i < 3 * v + 3; ++i) z[Eigen::Index(i)] = is_free(i) ? zf_[idx[i]] : 0.0;
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
  for (const auto& [v, row] : mapped_)  // + P F^-1 P^T r
    if (v < nv)
      for (int c = 0; c < 3; ++c) {
        const std::size_t i = 3 * v + std::size_t(c);
        if (!is_free(i)) continue;
        for (const auto& [p, w] : row) z[Eigen::Index(i)] += w * zf_[idx[3 * p + std::size_t(c)]];
      }
}

}  // namespace incise
