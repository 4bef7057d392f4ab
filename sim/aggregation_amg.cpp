#include "sim/aggregation_amg.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <random>

#include <Eigen/Eigenvalues>
#include <Eigen/SparseCore>
#include <Eigen/SparseCholesky>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace incise {

namespace {

using Mat6 = Eigen::Matrix<double, 6, 6>;
using Vec6 = Eigen::Matrix<double, 6, 1>;

double now_ms() {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

Eigen::Matrix3d cross_matrix(const Eigen::Vector3d& p) {
  Eigen::Matrix3d m;
  m << 0, -p.z(), p.y(), p.z(), 0, -p.x(), -p.y(), p.x(), 0;
  return m;
}

// B_v^T u for the rigid modes B_v = [I | -[p]x] of a vertex at scaled position p: (u, p x u).
Vec6 modes_t(const Eigen::Vector3d& p, const Eigen::Vector3d& u) {
  Vec6 out;
  out << u, p.cross(u);
  return out;
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

struct AggregationAmg::Coarse {
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower> ldlt;
  Eigen::Index rows = 0;
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
}

void AggregationAmg::apply(const TopologyChange& change) {
  if (!change.empty()) stale_ = true;
}

void AggregationAmg::mark_stale() { stale_ = true; }

void AggregationAmg::setup(const LinearOperator& a, const std::vector<std::uint8_t>* free) {
  a_ = &a;
  free_ = free;
  smoother_.setup(a, free);
  if (stale_ || !coarse_ || Eigen::Index(p_.size() * 3) != a.rows()) build(a, free);
}

void AggregationAmg::project(Eigen::VectorXd& v) const {
  if (!free_) return;
  for (Eigen::Index i = 0; i < v.size(); ++i)
    if (!(*free_)[std::size_t(i)]) v[i] = 0;
}

void AggregationAmg::build(const LinearOperator& a, const std::vector<std::uint8_t>* free) {
  const double t0 = now_ms();
  stats_ = {};
  const std::size_t nv = std::size_t(a.rows() / 3);
  // Vertices with all three unknowns free are aggregated; the others are left to the smoother.
  std::vector<std::uint8_t> eligible(nv, 0);
  for (std::size_t v = 0; v < nv; ++v)
    eligible[v] = !free || ((*free)[3 * v] && (*free)[3 * v + 1] && (*free)[3 * v + 2]);
  agg_ = aggregate_vertices(model_->mesh(), eligible, opt_.ring);
  const double t1 = now_ms();
  prolongator(free);
  const double t2 = now_ms();
  coarse_operator();
  const double t3 = now_ms();
  if (opt_.smoother_weight > 0) weight_ = opt_.smoother_weight;
  else if (weight_ == 0) weight_ = (4.0 / 3.0) / (1.1 * estimate_lambda_max(a, free));
  stats_.aggregate_ms = t1 - t0;
  stats_.prolongator_ms = t2 - t1;
  stats_.coarse_ms = t3 - t2 - stats_.factor_ms;
  stats_.aggregates = agg_.count();
  stats_.total_ms = now_ms() - t0;
  stale_ = false;
  ++builds_;
  ++version_;
}

void AggregationAmg::prolongator(const std::vector<std::uint8_t>*) {
  const TetMesh& mesh = model_->mesh();
  const std::size_t na = agg_.count();
  centre_.assign(na, Eigen::Vector3d::Zero());
  scale_.assign(na, 1.0);
  t_.assign(na, Mat6::Zero());
  modes_.assign(na, 0);
  offset_.assign(na + 1, 0);
  p_.assign(agg_.of.size(), Eigen::Matrix<double, 3, 6>::Zero());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, na, 64), [&](const tbb::blocked_range<std::size_t>& range) {
    for (std::size_t ai = range.begin(); ai != range.end(); ++ai) {
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
        const Eigen::Vector3d p = (mesh.rest(VertexId(v)) - c) / h;
        Eigen::Matrix<double, 3, 6> b;
        b << Eigen::Matrix3d::Identity(), -cross_matrix(p);
        p_[v] = b * t;
      }
    }
  });
  for (std::size_t ai = 0; ai < na; ++ai) offset_[ai + 1] = offset_[ai] + modes_[ai];
  stats_.coarse_unknowns = std::size_t(offset_[na]);
}

// A_c = P^T (a M + c K) P, one row of aggregates per task: the 6x6 blocks of B^T A B (rigid
// modes before the per-aggregate orthonormalization T) from each member's corners of its
// incident tets, then T_a^T (.) T_b. Element block (i, j) of a tet, with h = R grad N:
// V (mu (g_i . g_j) I + mu h_j h_i^T + lambda h_i h_j^T), the same as the matrix-free K x.
void AggregationAmg::coarse_operator() {
  const TetMesh& mesh = model_->mesh();
  const std::size_t na = agg_.count();
  const double c = stiffness_coeff_, am = mass_coeff_;
  const Eigen::VectorXd& mass = model_->lumped_mass();
  std::vector<std::vector<std::pair<std::int32_t, Mat6>>> rows(na);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, na, 16), [&](const tbb::blocked_range<std::size_t>& range) {
    for (std::size_t ai = range.begin(); ai != range.end(); ++ai) {
      auto& row = rows[ai];
      auto block = [&](std::int32_t b) -> Mat6& {
        for (auto& [id, m] : row)
          if (id == b) return m;
        row.emplace_back(b, Mat6::Zero());
        return row.back().second;
      };
      block(std::int32_t(ai));  // the diagonal block first
      for (std::uint32_t v : agg_.members[ai]) {
        const Eigen::Vector3d pv = (mesh.rest(VertexId(v)) - centre_[ai]) / scale_[ai];
        if (am != 0) block(std::int32_t(ai)) += am * mass[Eigen::Index(3 * v)] * modes_tt(pv, pv);
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
          Vec6 e[4];
          for (int j = 0; j < 4; ++j) {
            g[j] = shape_gradient(bm, j);
            hr[j] = r * g[j];
            e[j] = modes_t(pv, hr[j]);
          }
          for (int j = 0; j < 4; ++j) {
            const std::uint32_t w = ids[std::size_t(j)];
            const std::int32_t bj = agg_.of[w];
            if (bj < 0) continue;
            const Eigen::Vector3d pw = (mesh.rest(VertexId(w)) - centre_[std::size_t(bj)]) / scale_[std::size_t(bj)];
            Mat6& blk = block(bj);
            blk.noalias() += (vmu * g[i].dot(g[j])) * modes_tt(pv, pw);
            blk.noalias() += (vmu * e[j]) * modes_t(pw, hr[i]).transpose();
            blk.noalias() += (vlam * e[i]) * modes_t(pw, hr[j]).transpose();
          }
        }
      }
      // Into the orthonormal coarse basis.
      for (auto& [b, m] : row) m = t_[ai].transpose() * m * t_[std::size_t(b)];
    }
  });
  std::vector<Eigen::Triplet<double>> lower;
  for (std::size_t ai = 0; ai < na; ++ai)
    for (const auto& [b, m] : rows[ai]) {
      if (std::size_t(b) > ai) continue;
      const int ka = modes_[ai], kb = modes_[std::size_t(b)];
      for (int p = 0; p < ka; ++p)
        for (int q = 0; q < kb; ++q) {
          const Eigen::Index row = offset_[ai] + p, col = offset_[std::size_t(b)] + q;
          if (row >= col) lower.emplace_back(row, col, m(p, q));
        }
    }
  const Eigen::Index n = offset_[na];
  Eigen::SparseMatrix<double> ac(n, n);
  ac.setFromTriplets(lower.begin(), lower.end());
  stats_.coarse_nonzeros = std::size_t(ac.nonZeros());
  const double tf = now_ms();
  if (!coarse_) coarse_ = std::make_unique<Coarse>();
  coarse_->rows = n;
  coarse_->ldlt.compute(ac);
  coarse_->ok = n > 0 && coarse_->ldlt.info() == Eigen::Success;
  if (coarse_->ok) {
    // SimplicialLDLT does not fail on an indefinite or singular matrix: check the pivots (a
    // part the cut set free makes A_c singular; without a coarse level M^-1 stays SPD).
    const auto d = coarse_->ldlt.vectorD();
    const double dmax = d.cwiseAbs().maxCoeff();
    for (Eigen::Index i = 0; i < d.size() && coarse_->ok; ++i) coarse_->ok = d[i] > 1e-12 * dmax;
  }
  stats_.factor_ok = coarse_->ok;
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
  // z += P A_c^-1 P^T x
  auto coarse_correct = [&](const Eigen::VectorXd& x, Eigen::VectorXd& out) {
    if (!coarse) return;
    rc_.setZero(coarse_->rows);
    const std::size_t na = agg_.count();
    for (std::size_t ai = 0; ai < na; ++ai) {
      const int k = modes_[ai];
      auto seg = rc_.segment(offset_[ai], k);
      for (std::uint32_t v : agg_.members[ai])
        seg.noalias() += (p_[v].transpose() * x.segment<3>(3 * Eigen::Index(v))).head(k);
    }
    ec_ = coarse_->ldlt.solve(rc_);
    for (std::size_t ai = 0; ai < na; ++ai) {
      const int k = modes_[ai];
      const auto seg = ec_.segment(offset_[ai], k);
      for (std::uint32_t v : agg_.members[ai])
        out.segment<3>(3 * Eigen::Index(v)).noalias() += p_[v].leftCols(k) * seg;
    }
  };
  if (opt_.cycle == AggregationAmgOptions::Cycle::Additive) {
    smoother_.apply(r, z);
    coarse_correct(r, z);
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
