#include "sim/fem/aggregation_amg.h"

#include "mesh/clock.h"
#include "sim/linalg/blas_threads.h"
#include "sim/linalg/block_cholesky.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <random>

#include <Eigen/Eigenvalues>
#include <Eigen/SparseCore>
#ifdef INCISE_HAVE_CHOLMOD
#include <Eigen/CholmodSupport>
#else
#include <Eigen/SparseCholesky>
#endif
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

namespace incise {

namespace {

using Mat6 = Eigen::Matrix<double, 6, 6>;
using Vec6 = Eigen::Matrix<double, 6, 1>;
constexpr Eigen::Index kParallelFrom = 6000;  // unknowns: below, one thread applies the coarse correction

Eigen::Matrix3d cross_matrix(const Eigen::Vector3d& p) {
  Eigen::Matrix3d m;
  m << 0, -p.z(), p.y(), p.z(), 0, -p.x(), -p.y(), p.x(), 0;
  return m;
}

// B_v^T B_w = [[I, -[q]x], [[p]x, (p.q) I - q p^T]] for B_v at p and B_w at q.
Mat6 modes_tt(const Eigen::Vector3d& p, const Eigen::Vector3d& q) {
  Mat6 m;
  m.topLeftCorner<3, 3>().setIdentity();
  m.topRightCorner<3, 3>() = -cross_matrix(q);
  m.bottomLeftCorner<3, 3>() = cross_matrix(p);
  m.bottomRightCorner<3, 3>() = p.dot(q) * Eigen::Matrix3d::Identity() - q * p.transpose();
  return m;
}

Eigen::Vector3d shape_gradient(const Eigen::Matrix3d& bm, int j) {
  if (j == 0) return -(bm.row(0) + bm.row(1) + bm.row(2)).transpose();
  return bm.row(j - 1).transpose();
}

}  // namespace

// The coarse factor. Up to AggregationAmgOptions::block_factor_aggregates aggregates of
// (mostly) six modes: the block Cholesky of sim/linalg/block_cholesky.h, faster than CHOLMOD's
// simplicial LL^T there. Larger ones, or translations only (three modes padded to six), go to
// a general sparse factor: CHOLMOD (simplicial LL^T up to kSupernodalFrom unknowns,
// supernodal with one BLAS thread above; AMD ordering) or Eigen's SimplicialLDLT without it.
// Figures: docs/solver.md#behind-the-constants (bench_fem_precond --only amg-build).
struct AggregationAmg::Coarse {
  bool block = true;  // which factor holds the matrix
  BlockCholesky6 factor;
#ifdef INCISE_HAVE_CHOLMOD
  static constexpr Eigen::Index kSupernodalFrom = 1200;
  Coarse() {
    single_threaded_blas();
    ldlt.cholmod().print = 0;  // a failure (not positive definite) is reported by ok, not on stdout
    ldlt.cholmod().nmethods = 1;
    ldlt.cholmod().method[0].ordering = CHOLMOD_AMD;
  }
  void compute(const Eigen::SparseMatrix<double>& a) {
    ldlt.setMode(a.rows() < kSupernodalFrom ? Eigen::CholmodSimplicialLLt : Eigen::CholmodSupernodalLLt);
    ldlt.compute(a);
  }
  Eigen::CholmodDecomposition<Eigen::SparseMatrix<double>, Eigen::Lower> ldlt;
#else
  void compute(const Eigen::SparseMatrix<double>& a) { ldlt.compute(a); }
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower> ldlt;
#endif
  std::vector<Eigen::Index> offset;  // general factor: each aggregate's first coarse unknown
  Eigen::VectorXd rc, ec;            // general factor: the packed coarse vectors
  bool ok = false;
};

AggregationAmg::AggregationAmg(const FemModel& model, const AggregationAmgOptions& options)
    : model_(&model), opt_(options) {}

AggregationAmg::~AggregationAmg() = default;

void AggregationAmg::frame(double a, double c, int last_iterations) {
  if (a != mass_coeff_ || c != stiffness_coeff_) stale_ = true;
  mass_coeff_ = a;
  stiffness_coeff_ = c;
  if (model_->kind() == FemKind::Corotational && last_iterations > opt_.rebuild_iterations) stale_ = true;
  if (topology_changed_ && last_iterations > opt_.topology_rebuild_iterations) stale_ = true;
}

void AggregationAmg::apply(const TopologyChange& change) {
  if (change.empty()) return;
  if (!coarse_ || stale_) {
    stale_ = true;
    return;
  }
  if (opt_.topology_rebuild_iterations > 0) {
    topology_changed_ = true;
    return;
  }
  // Patched at the next setup(): the aggregates of these vertices are dissolved and redone.
  for (const auto* list : {&change.touched_vertices, &change.removed_vertices})
    for (VertexId v : *list) pending_.push_back(v.idx());
  for (const VertexOrigin& o : change.added_vertices) pending_.push_back(o.vertex.idx());
  for (const VertexOrigin& o : change.moved_vertices) pending_.push_back(o.vertex.idx());
  // A tet's corners couple through it: a new tet changes blocks between its corners even where
  // a corner's set of incident tets did not change.
  for (TetId t : change.added_tets)
    if (model_->tet_alive(t))
      for (std::uint32_t v : model_->tet_vertex_ids(t)) pending_.push_back(v);
}

void AggregationAmg::mark_stale() { stale_ = true; }

void AggregationAmg::setup(const LinearOperator& a, const std::vector<std::uint8_t>* free) {
  a_ = &a;
  free_ = free;
  const double t0 = now_ms();
  smoother_.setup(a, free);
  smoother_ms_ = now_ms() - t0;
  if (!stale_ && coarse_ && !pending_.empty()) {
    patch(a, free);
    // Rows computed with this frame's rotations beside rows of an earlier build can make A_c
    // indefinite (once in 30 patches on the organ cut scene); smoothing alone then cost 140
    // iterations in that frame, a rebuild costs a few patches.
    if (!coarse_->ok) ++failed_patches_;
  }
  if (stale_ || !coarse_) build(a, free);
}

double AggregationAmg::next_setup_ms() const {
  // Before the first build: an estimate per tet (docs/solver.md#behind-the-constants), so that a budgeted frame
  // does not find out by building.
  if (stale_ || !coarse_) return build_ms_ > 0 ? smoother_ms_ + build_ms_ : 2.5e-3 * double(model_->mesh().num_tets());
  if (!pending_.empty() && patch_ms_ > 0) return smoother_ms_ + patch_ms_;
  return smoother_ms_ > 0 ? smoother_ms_ : -1;
}

void AggregationAmg::project(Eigen::VectorXd& v) const {
  if (!free_) return;
  for (Eigen::Index i = 0; i < v.size(); ++i)
    if (!(*free_)[std::size_t(i)]) v[i] = 0;
}

namespace {
// Vertices with all three unknowns free are aggregated; the others are left to the smoother.
bool all_free(const std::vector<std::uint8_t>* free, std::size_t v) {
  return !free || (v * 3 + 2 < free->size() && (*free)[3 * v] && (*free)[3 * v + 1] && (*free)[3 * v + 2]);
}
}  // namespace

void AggregationAmg::build(const LinearOperator& a, const std::vector<std::uint8_t>* free) {
  const double t0 = now_ms();
  stats_ = {};
  const std::size_t nv = std::size_t(a.rows() / 3);
  std::vector<std::uint8_t> eligible(nv, 0);
  for (std::size_t v = 0; v < nv; ++v) eligible[v] = all_free(free, v);
  ring_ = opt_.ring > 0 ? opt_.ring : 2;
  agg_ = aggregate_vertices(model_->mesh(), eligible, ring_);
  if (opt_.ring <= 0 && agg_.count() > std::size_t(std::max(0, opt_.ring3_above))) {
    ring_ = 3;
    agg_ = aggregate_vertices(model_->mesh(), eligible, ring_);
  }
  agg_.of.resize(nv, -1);
  const double t1 = now_ms();
  const std::size_t na = agg_.count();
  centre_.assign(na, Eigen::Vector3d::Zero());
  scale_.assign(na, 1.0);
  t_.assign(na, Mat6::Zero());
  modes_.assign(na, 0);
  p_.assign(nv, Eigen::Matrix<double, 3, 6>::Zero());
  pos_.assign(nv, Eigen::Vector3d::Zero());
  rows_.assign(na, {});
  vol_u_.assign(model_->nodal_averaged() ? nv : 0, {});
  std::vector<std::uint32_t> all(na);
  for (std::uint32_t k = 0; k < na; ++k) all[k] = k;
  prolongator(all);
  const double t2 = now_ms();
  coarse_rows(all, 0);
  const double t3 = now_ms();
  factor();
  if (opt_.smoother_weight > 0) weight_ = opt_.smoother_weight;
  else if (weight_ == 0) weight_ = (4.0 / 3.0) / (1.1 * estimate_lambda_max(a, free));
  stats_.aggregate_ms = t1 - t0;
  stats_.prolongator_ms = t2 - t1;
  stats_.coarse_ms = t3 - t2;
  stats_.total_ms = build_ms_ = now_ms() - t0;
  stats_.ring = ring_;
  pending_.clear();
  stale_ = topology_changed_ = false;
  ++builds_;
  ++version_;
}

// The local update after cuts: dissolve the aggregates of the vertices the changes named,
// re-aggregate their members and the new vertices on the current connectivity, redo P for
// the new aggregates and their rows of A_c (the neighbouring rows get the transposed blocks;
// blocks between two untouched aggregates keep their values, since a tet whose corners lie in
// untouched aggregates was not changed), then refactor the coarse matrix. Rows computed now
// use the current rotations, the others those of their build: close, and the pivots are
// checked (a failure means a full rebuild).
void AggregationAmg::patch(const LinearOperator& a, const std::vector<std::uint8_t>* free) {
  const double t0 = now_ms();
  stats_ = {};
  const std::size_t nv = std::size_t(a.rows() / 3);
  if (agg_.of.size() < nv) {
    agg_.of.resize(nv, -1);
    p_.resize(nv, Eigen::Matrix<double, 3, 6>::Zero());
    pos_.resize(nv, Eigen::Vector3d::Zero());
  }
  std::sort(pending_.begin(), pending_.end());
  pending_.erase(std::unique(pending_.begin(), pending_.end()), pending_.end());
  std::vector<std::int32_t> dissolved;
  for (std::uint32_t v : pending_)
    if (v < nv && agg_.of[v] >= 0) dissolved.push_back(agg_.of[v]);
  std::sort(dissolved.begin(), dissolved.end());
  dissolved.erase(std::unique(dissolved.begin(), dissolved.end()), dissolved.end());
  std::vector<std::uint32_t> pool;
  for (std::int32_t d : dissolved) {
    for (auto& [b, m] : rows_[std::size_t(d)])  // neighbours forget d
      if (b != d) {
        auto& rb = rows_[std::size_t(b)];
        rb.erase(std::remove_if(rb.begin(), rb.end(), [&](const auto& e) { return e.first == d; }), rb.end());
      }
    for (std::uint32_t v : agg_.members[std::size_t(d)]) {
      agg_.of[v] = -1;
      p_[v].setZero();
      pool.push_back(v);
    }
    agg_.members[std::size_t(d)].clear();
    rows_[std::size_t(d)].clear();
    modes_[std::size_t(d)] = 0;
  }
  for (std::uint32_t v : pending_)
    if (v < nv && agg_.of[v] < 0) pool.push_back(v);
  std::sort(pool.begin(), pool.end());
  pool.erase(std::unique(pool.begin(), pool.end()), pool.end());
  // Read only at pool vertices and their neighbours: set there, and cleared there after (kept
  // between patches, so that a patch does not allocate one entry per vertex of the mesh).
  std::vector<std::uint8_t>& eligible = eligible_;
  if (eligible.size() < nv) eligible.resize(nv, 0);
  std::vector<std::uint32_t> marked;
  for (std::uint32_t v : pool) {
    eligible[v] = all_free(free, v);
    marked.push_back(v);
    for (TetId t : model_->mesh().incident_tets(VertexId(v)))
      for (VertexId w : model_->mesh().tet_vertices(t)) {
        eligible[w.idx()] = all_free(free, w.idx());
        marked.push_back(w.idx());
      }
  }
  const std::size_t first = agg_.count();
  aggregate_more(model_->mesh(), eligible, ring_, pool, agg_);
  for (std::uint32_t v : marked) eligible[v] = 0;
  const std::size_t na = agg_.count();
  centre_.resize(na, Eigen::Vector3d::Zero());
  scale_.resize(na, 1.0);
  t_.resize(na, Mat6::Zero());
  modes_.resize(na, 0);
  rows_.resize(na);
  std::vector<std::uint32_t> fresh;
  for (std::size_t k = first; k < na; ++k) fresh.push_back(std::uint32_t(k));
  const double t1 = now_ms();
  prolongator(fresh);
  const double t2 = now_ms();
  const bool nodal = model_->nodal_averaged();
  if (nodal) {
    if (vol_u_.size() < nv) vol_u_.resize(nv);
    exchange_volumetric(first, -1);  // before coarse_rows keeps the new B_a P
  }
  coarse_rows(fresh, first);
  for (std::uint32_t k : fresh)  // the untouched neighbours' blocks towards the new aggregates
    for (const auto& [b, m] : rows_[k])
      if (std::size_t(b) < first) rows_[std::size_t(b)].emplace_back(std::int32_t(k), m.transpose());
  if (nodal) exchange_volumetric(first, +1);
  const double t3 = now_ms();
  factor();
  if (!coarse_->ok) stale_ = true;  // setup() rebuilds at once
  stats_.aggregate_ms = t1 - t0;
  stats_.prolongator_ms = t2 - t1;
  stats_.coarse_ms = t3 - t2;
  stats_.total_ms = patch_ms_ = now_ms() - t0;
  stats_.patched_aggregates = fresh.size();
  stats_.ring = ring_;
  pending_.clear();
  ++patches_;
  ++version_;
}

// Nodal-averaged K reaches the 2-ring: a vertex a adds c (B_a P)^T (B_a P) to A_c, coupling
// every pair of aggregates its row of B reaches. A cut changes the rows of B of the vertices
// it names (their tets, V_a and kappa_a), and no other: the terms of those vertices are
// exchanged in the blocks between aggregates the patch left (the fresh aggregates' rows are
// made whole by coarse_rows, and the dissolved ones' are gone). The term taken out is the one
// put in (vol_u_), so the blocks stay the sums of the terms they hold: with rotations, each
// term of the frame it was made in, as the rest of a patched A_c. O(change): the pending
// vertices' rows of B, where recomputing the rows of every aggregate holding their 1-ring read
// those aggregates' whole 2-rings.
void AggregationAmg::exchange_volumetric(std::size_t first, double sign) {
  const double c = sign * stiffness_coeff_;
  auto kept = [&](std::int32_t b) { return b >= 0 && std::size_t(b) < first && !agg_.members[std::size_t(b)].empty(); };
  std::vector<std::pair<std::uint32_t, Eigen::Vector3d>> brow;
  std::vector<std::pair<std::int32_t, Vec6>> fresh_u;
  for (std::uint32_t a : pending_) {
    if (a >= vol_u_.size()) continue;
    auto& u = vol_u_[a];
    if (sign > 0) {
      coarse_b_row(a, brow, fresh_u);
      u.assign(fresh_u.begin(), fresh_u.end());
    }
    for (const auto& [h, uh] : u) {
      if (!kept(h)) continue;
      auto& row = rows_[std::size_t(h)];
      for (const auto& term : u) {
        const std::int32_t g = term.first;
        if (!kept(g)) continue;
        auto it = std::find_if(row.begin(), row.end(), [&](const auto& e) { return e.first == g; });
        if (it == row.end()) {
          row.emplace_back(g, Mat6::Zero());
          it = row.end() - 1;
        }
        it->second.noalias() += (c * uh) * term.second.transpose();
      }
    }
  }
}

void AggregationAmg::prolongator(const std::vector<std::uint32_t>& which) {
  const TetMesh& mesh = model_->mesh();
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, which.size(), 64), [&](const tbb::blocked_range<std::size_t>& range) {
    for (std::size_t wi = range.begin(); wi != range.end(); ++wi) {
      const std::size_t ai = which[wi];
      const auto& m = agg_.members[ai];
      Eigen::Vector3d c = Eigen::Vector3d::Zero();
      for (std::uint32_t v : m) c += mesh.rest(VertexId(v));
      c /= double(m.size());
      double h = 0;
      for (std::uint32_t v : m) h = std::max(h, (mesh.rest(VertexId(v)) - c).norm());
      if (!(h > 0)) h = 1;
      centre_[ai] = c;
      scale_[ai] = h;
      Mat6& t = t_[ai];
      int k = 3;
      if (opt_.rotations) {
        // Gram matrix of the aggregate's modes, G = sum B_v^T B_v; T = V_k L_k^-1/2 over the
        // eigenpairs G can carry, so that Q = B T is orthonormal.
        Mat6 g = Mat6::Zero();
        for (std::uint32_t v : m) {
          const Eigen::Vector3d p = (mesh.rest(VertexId(v)) - c) / h;
          g += modes_tt(p, p);
        }
        Eigen::SelfAdjointEigenSolver<Mat6> es(g);
        const Vec6 l = es.eigenvalues();
        const double top = l[5];
        k = 0;
        for (int i = 5; i >= 0; --i)
          if (l[i] > 1e-3 * top) t.col(k++) = es.eigenvectors().col(i) / std::sqrt(l[i]);
      } else {
        t.topLeftCorner<3, 3>() = Eigen::Matrix3d::Identity() / std::sqrt(double(m.size()));
      }
      modes_[ai] = k;
      for (std::uint32_t v : m) {
        const Eigen::Vector3d p = pos_[v] = (mesh.rest(VertexId(v)) - c) / h;
        Eigen::Matrix<double, 3, 6> b;
        b << Eigen::Matrix3d::Identity(), -cross_matrix(p);
        p_[v] = b * t;
      }
    }
  });
}

// A_c = P^T (a M + c K) P, one row of aggregates per task. For each member v, its row of
// 3x3 blocks of a M + c K is summed first from its corners in its incident tets (element block
// (i, j) with h = R grad N: V (mu (g_i . g_j) I + mu h_j h_i^T + lambda h_i h_j^T), as the
// matrix-free K x uses it), then each block A_vw enters the aggregates' 6x6 block of B^T A B
// (rigid modes before the per-aggregate orthonormalization T) as B_v^T A_vw B_w, and finally
// T_a^T (.) T_b. Summing the fine blocks first does the 6x6 work once per vertex pair instead
// of once per tet corner pair (about 5 tets share an edge).
void AggregationAmg::coarse_rows(const std::vector<std::uint32_t>& which, std::size_t keep_from) {
  const TetMesh& mesh = model_->mesh();
  const double c = stiffness_coeff_, am = mass_coeff_;
  const Eigen::VectorXd& mass = model_->lumped_mass();
  const bool nodal = model_->nodal_averaged();

  // One aggregate a task: a patch redoes a few dozen rows, each worth a core (a grain of 8 left
  // a patch's rows on one).
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, which.size(), 1), [&](const tbb::blocked_range<std::size_t>& range) {
    std::vector<std::pair<std::uint32_t, Eigen::Matrix3d>> fine;  // v's row: (w, A_vw)
    std::vector<std::pair<std::uint32_t, Eigen::Vector3d>> brow;  // a row of B
    std::vector<std::uint32_t> arows;                             // nodal: the B rows reaching ai
    std::vector<std::pair<std::int32_t, Vec6>> coarse_b;          // nodal: a B row times P
    for (std::size_t wi = range.begin(); wi != range.end(); ++wi) {
      const std::size_t ai = which[wi];
      auto& row = rows_[ai];
      row.clear();
      auto block = [&](std::int32_t b) -> Mat6& {
        for (auto& [id, m] : row)
          if (id == b) return m;
        row.emplace_back(b, Mat6::Zero());
        return row.back().second;
      };
      block(std::int32_t(ai));  // the diagonal block first
      for (std::uint32_t v : agg_.members[ai]) {
        fine.clear();
        fine.emplace_back(v, (am * mass[Eigen::Index(3 * v)]) * Eigen::Matrix3d::Identity());
        auto fine_block = [&](std::uint32_t w) -> Eigen::Matrix3d& {
          for (auto& [id, m] : fine)
            if (id == w) return m;
          fine.emplace_back(w, Eigen::Matrix3d::Zero());
          return fine.back().second;
        };
        for (TetId t : mesh.incident_tets(VertexId(v))) {
          if (!model_->tet_alive(t)) continue;
          const auto& ids = model_->tet_vertex_ids(t);
          int i = 0;
          while (ids[std::size_t(i)] != v) ++i;
          const Eigen::Matrix3d r = model_->tet_quaternion(t).toRotationMatrix();
          const Eigen::Matrix3d& bm = model_->tet_shape_matrix(t);
          const double vol = model_->tet_volume(t), vmu = c * vol * model_->tet_mu(t),
                       vlam = c * vol * model_->tet_lambda(t);
          Eigen::Vector3d g[4], hr[4];
          for (int j = 0; j < 4; ++j) {
            g[j] = shape_gradient(bm, j);
            hr[j] = r * g[j];
          }
          for (int j = 0; j < 4; ++j) {
            const std::uint32_t w = ids[std::size_t(j)];
            if (agg_.of[w] < 0) continue;
            Eigen::Matrix3d& a = fine_block(w);
            a.diagonal().array() += vmu * g[i].dot(g[j]);
            a.noalias() += (vmu * hr[j]) * hr[i].transpose();
            a.noalias() += (vlam * hr[i]) * hr[j].transpose();
          }
        }
        const Eigen::Vector3d& pv = pos_[v];
        for (const auto& [w, a] : fine) {
          // B_v^T A B_w with B = [I | -[p]x]: M = A B_w = [A | -A [p_w]x], then (M; p_v x M).
          Eigen::Matrix<double, 3, 6> m;
          m.leftCols<3>() = a;
          m.rightCols<3>().noalias() = -a * cross_matrix(pos_[w]);
          Mat6& blk = block(agg_.of[w]);
          blk.topRows<3>() += m;
          for (int k = 0; k < 6; ++k) blk.block<3, 1>(3, k) += pv.cross(Eigen::Vector3d(m.col(k)));
        }
      }
  // Into the orthonormal coarse basis.
      for (auto& [b, m] : row) m = t_[ai].transpose() * m * t_[std::size_t(b)];
      if (nodal) volumetric_rows(ai, keep_from, row, arows, brow, coarse_b);
    }
  });
}

// Nodal-averaged K's volumetric part, c B^T B, straight into aggregate ai's coarse row:
// P^T B^T B P = sum over vertices a of (B_a P)^T (B_a P), B_a P a row of 6-vectors, one per
// aggregate a's B row reaches. Only the a whose B row reaches ai's members count: the 1-rings
// of the members. Each B row is made once per aggregate (not once per member whose ring holds
// it) and no 2-ring of fine blocks is built.
void AggregationAmg::volumetric_rows(std::size_t ai, std::size_t keep_from, std::vector<std::pair<std::int32_t, Mat6>>& row,
                                     std::vector<std::uint32_t>& arows,
                                     std::vector<std::pair<std::uint32_t, Eigen::Vector3d>>& brow,
                                     std::vector<std::pair<std::int32_t, Vec6>>& coarse_b) {
  const TetMesh& mesh = model_->mesh();
  const double c = stiffness_coeff_;
  // The members' 1-rings, each vertex once (stamps per thread, not a sort: a row reads a few
  // thousand corners).
  thread_local std::vector<std::uint32_t> seen;
  thread_local std::uint32_t stamp = 0;
  if (seen.size() < mesh.vertex_capacity()) seen.resize(mesh.vertex_capacity(), 0);
  if (++stamp == 0) {  // wrapped: forget old stamps
    std::fill(seen.begin(), seen.end(), 0);
    stamp = 1;
  }
  arows.clear();
  for (std::uint32_t v : agg_.members[ai])
    for (TetId t : mesh.incident_tets(VertexId(v)))
      if (model_->tet_alive(t))
        for (std::uint32_t a : model_->tet_vertex_ids(t))
          if (seen[a] != stamp) {
            seen[a] = stamp;
            arows.push_back(a);
          }
  auto block = [&](std::int32_t b) -> Mat6& {
    for (auto& [id, m] : row)
      if (id == b) return m;
    row.emplace_back(b, Mat6::Zero());
    return row.back().second;
  };
  for (std::uint32_t a : arows) {
    coarse_b_row(a, brow, coarse_b);
    const Vec6* mine = nullptr;
    std::int32_t keeper = -1;  // the smallest aggregate at or above keep_from: its task keeps a's B_a P
    for (const auto& [b, r] : coarse_b) {
      if (std::size_t(b) == ai) mine = &r;
      if (std::size_t(b) >= keep_from && (keeper < 0 || b < keeper)) keeper = b;
    }
    if (!mine) continue;
    for (const auto& [b, r] : coarse_b) block(b).noalias() += (c * *mine) * r.transpose();
    if (std::size_t(keeper) == ai) vol_u_[a].assign(coarse_b.begin(), coarse_b.end());
  }
}

void AggregationAmg::coarse_b_row(std::uint32_t a, std::vector<std::pair<std::uint32_t, Eigen::Vector3d>>& brow,
                                  std::vector<std::pair<std::int32_t, Vec6>>& out) const {
  model_->nodal_b_row(a, brow);
  out.clear();
  for (const auto& [w, d] : brow) {
    const std::int32_t b = agg_.of[w];
    if (b < 0) continue;
    const Vec6 r = p_[w].transpose() * d;  // d^T P_w, P_w = B_w T_b
    auto it = std::find_if(out.begin(), out.end(), [&](const auto& e) { return e.first == b; });
    if (it == out.end())
      out.emplace_back(b, r);
    else
      it->second += r;
  }
}

// The coarse matrix from the rows (lower triangle; aggregates left empty by a patch have no
// unknowns), factored by the block Cholesky or, for large or translations-only coarse
// levels, the general sparse factor (Coarse, above).
void AggregationAmg::factor() {
  const double tf = now_ms();
  const std::size_t na = agg_.count();
  stats_.coarse_unknowns = stats_.aggregates = stats_.coarse_nonzeros = 0;
  for (std::size_t ai = 0; ai < na; ++ai) {
    const int ka = modes_[ai];
    if (ka == 0) continue;
    ++stats_.aggregates;
    stats_.coarse_unknowns += std::size_t(ka);
    for (const auto& [b, m] : rows_[ai])
      if (std::size_t(b) < ai) stats_.coarse_nonzeros += std::size_t(ka * modes_[std::size_t(b)]);
      else if (std::size_t(b) == ai) stats_.coarse_nonzeros += std::size_t(ka * (ka + 1) / 2);
  }
  if (!coarse_) coarse_ = std::make_unique<Coarse>();
  Coarse& co = *coarse_;
  // No coarse unknowns (no vertex is wholly free, e.g. rollers on every vertex of a plane-strain
  // slab): the cycle is the smoother alone. A part the cut set free makes A_c singular: the
  // factor refuses it (pivot check), and without a coarse level M^-1 stays SPD.
  co.ok = false;
  stats_.factor_nonzeros = 0;
  co.block = stats_.aggregates <= std::size_t(std::max(0, opt_.block_factor_aggregates)) &&
             double(stats_.coarse_unknowns) >= 4.5 * double(stats_.aggregates);
  if (stats_.coarse_unknowns == 0) {
  } else if (co.block) {
    co.ok = co.factor.compute(rows_, modes_);
    if (co.ok) stats_.factor_nonzeros = co.factor.nonzeros();
  } else {
    co.offset.assign(na + 1, 0);
    for (std::size_t ai = 0; ai < na; ++ai) co.offset[ai + 1] = co.offset[ai] + modes_[ai];
    std::vector<Eigen::Triplet<double>> lower;
    for (std::size_t ai = 0; ai < na; ++ai)
      for (const auto& [b, m] : rows_[ai]) {
        if (std::size_t(b) > ai) continue;
        const int ka = modes_[ai], kb = modes_[std::size_t(b)];
        for (int p = 0; p < ka; ++p)
          for (int q = 0; q < kb; ++q) {
            const Eigen::Index row = co.offset[ai] + p, col = co.offset[std::size_t(b)] + q;
            if (row >= col) lower.emplace_back(row, col, m(p, q));
          }
      }
    const Eigen::Index n = co.offset[na];
    Eigen::SparseMatrix<double> ac(n, n);
    ac.setFromTriplets(lower.begin(), lower.end());
    co.compute(ac);
    co.ok = co.ldlt.info() == Eigen::Success;
#ifdef INCISE_HAVE_CHOLMOD
    if (co.ok) stats_.factor_nonzeros = std::size_t(co.ldlt.cholmod().lnz);
#else
    if (co.ok) {
      // SimplicialLDLT does not fail on an indefinite or singular matrix: check the pivots.
      const auto d = co.ldlt.vectorD();
      const double dmax = d.cwiseAbs().maxCoeff();
      for (Eigen::Index i = 0; i < d.size() && co.ok; ++i) co.ok = d[i] > 1e-12 * dmax;
    }
    if (co.ok) stats_.factor_nonzeros = std::size_t(co.ldlt.matrixL().nestedExpression().nonZeros());
#endif
  }
  stats_.factor_ok = co.ok;
  stats_.block_factor = co.block;
  stats_.factor_ms = now_ms() - tf;
}

double AggregationAmg::estimate_lambda_max(const LinearOperator& a, const std::vector<std::uint8_t>* free) const {
  // Power iteration on S A (similar to S^1/2 A S^1/2, so its eigenvalues are real): a lower
  // estimate, hence the margin where the weight is chosen.
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> u(-1, 1);
  Eigen::VectorXd x(a.rows()), y, z;
  for (Eigen::Index i = 0; i < x.size(); ++i) x[i] = (!free || (*free)[std::size_t(i)]) ? u(rng) : 0.0;
  double lambda = 1;
  for (int it = 0; it < 12; ++it) {
    const double n = x.norm();
    if (!(n > 0)) break;
    x /= n;
    a.multiply(x, y);
    if (free)
      for (Eigen::Index i = 0; i < y.size(); ++i)
        if (!(*free)[std::size_t(i)]) y[i] = 0;
    smoother_.apply(y, z);
    lambda = z.norm();
    x.swap(z);
  }
  return std::max(lambda, 1e-3);
}

void AggregationAmg::apply(const Eigen::VectorXd& r, Eigen::VectorXd& z) const {
  const bool coarse = coarse_ && coarse_->ok;
  // A stale hierarchy (topology_rebuild_iterations) may hold vertices a cut has since removed
  // or fixed: they take no coarse correction, so z stays zero on kept unknowns.
  const bool check = topology_changed_ && free_;
  auto covered = [&](std::uint32_t v) { return !check || (*free_)[3 * std::size_t(v)]; };
  // z += P A_c^-1 P^T x, in three parts: restrict (P^T x into rc_), solve (rc_ in place),
  // prolong (z += P rc_).
  // Fixed-size 6-vectors per aggregate (P's columns beyond k are zero, and the factor returns
  // zero there). Aggregates own disjoint vertices: restriction and prolongation split over them
  // on large meshes (serial, the application was a large share of a CG iteration beside a
  // parallel K x).
  const std::size_t na = agg_.count();
  const bool parallel = r.size() >= kParallelFrom;
  auto over_aggregates = [&](auto&& f) {
    if (!parallel) {
      for (std::size_t ai = 0; ai < na; ++ai) f(ai);
      return;
    }
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, na, 8), [&](const tbb::blocked_range<std::size_t>& rg) {
      for (std::size_t ai = rg.begin(); ai != rg.end(); ++ai) f(ai);
    });
  };
  // P_v = B_v T_a with B_v = [I | -[p_v]x] (p_v the vertex's scaled position): applied from
  // the positions and T_a, not from the stored 3x6 blocks, so an application streams 3
  // numbers a vertex instead of 18 (it runs between two products, its data out of cache).
  // P^T x over a's vertices: T_a^T sum_v (x_v, p_v x x_v).
  auto restrict_to_coarse = [&](const Eigen::VectorXd& x) {
    rc_.resize(na);
    over_aggregates([&](std::size_t ai) {
      Vec6& acc = rc_[ai];
      acc.setZero();
      if (modes_[ai] == 0) return;
      Eigen::Vector3d f = Eigen::Vector3d::Zero(), m = Eigen::Vector3d::Zero();
      for (std::uint32_t v : agg_.members[ai])
        if (covered(v)) {
          const Eigen::Vector3d xv = x.segment<3>(3 * Eigen::Index(v));
          f += xv;
          m += pos_[v].cross(xv);
        }
      Vec6 y;
      y << f, m;
      acc.noalias() = t_[ai].transpose() * y;
    });
  };
  auto coarse_solve = [&] {
    Coarse& co = *coarse_;
    if (co.block) {
      co.factor.solve_in_place(rc_);
      return;
    }
    co.rc.resize(co.offset.back());
    for (std::size_t ai = 0; ai < na; ++ai) co.rc.segment(co.offset[ai], modes_[ai]) = rc_[ai].head(modes_[ai]);
    co.ec = co.ldlt.solve(co.rc);
    for (std::size_t ai = 0; ai < na; ++ai) {
      rc_[ai].setZero();
      rc_[ai].head(modes_[ai]) = co.ec.segment(co.offset[ai], modes_[ai]);
    }
  };
  // P c over a's vertices: with (t, r) = T_a c, t + r x p_v at each.
  auto prolong_into = [&](Eigen::VectorXd& out) {
    over_aggregates([&](std::size_t ai) {
      if (modes_[ai] == 0) return;
      const Vec6 c = t_[ai] * rc_[ai];
      const Eigen::Vector3d t = c.head<3>(), r = c.tail<3>();
      for (std::uint32_t v : agg_.members[ai])
        if (covered(v)) out.segment<3>(3 * Eigen::Index(v)) += t + r.cross(pos_[v]);
    });
  };
  auto coarse_correct = [&](const Eigen::VectorXd& x, Eigen::VectorXd& out) {
    if (!coarse) return;
    restrict_to_coarse(x);
    coarse_solve();
    prolong_into(out);
  };
  if (opt_.cycle == AggregationAmgOptions::Cycle::Additive) {
    if (!coarse) {
      smoother_.apply(r, z);
      return;
    }
    // z = S r + P A_c^-1 P^T r: the smoother and the coarse solve read r alone, and both are
    // serial (one memory-bound sweep, one triangular solve), so on large meshes they run side
    // by side; the sum is the same as in sequence.
    restrict_to_coarse(r);
    if (parallel) tbb::parallel_invoke([&] { smoother_.apply(r, z); }, coarse_solve);
    else {
      smoother_.apply(r, z);
      coarse_solve();
    }
    prolong_into(z);
    return;
  }
  smoother_.apply(r, z);
  z *= weight_;
  if (!coarse) {  // S-only symmetric cycle: z = w S r + w S (r - A w S r)
    a_->multiply(z, t1_);
    t1_ = r - t1_;
    project(t1_);
    smoother_.apply(t1_, t2_);
    z.noalias() += weight_ * t2_;
    return;
  }
  a_->multiply(z, t1_);
  t1_ = r - t1_;
  project(t1_);
  coarse_correct(t1_, z);
  a_->multiply(z, t1_);
  t1_ = r - t1_;
  project(t1_);
  smoother_.apply(t1_, t2_);
  z.noalias() += weight_ * t2_;
}

}  // namespace incise
