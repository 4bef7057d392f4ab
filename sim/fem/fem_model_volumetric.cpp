// FemModel, nodal-averaged: the vertex volumes, the volumetric blocks and rows (B, nodal_b()) and
// the volumetric pass of K x (docs/solver.md#nodal-averaged-product).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include <Eigen/SparseCore>

#include "mesh/errors.h"
#include "sim/fem/fem_model.h"
#include "sim/fem/fem_model_detail.h"

namespace incise {

using namespace fem_detail;

void FemModel::nodal_volume_of(std::uint32_t vi) {
  double v = 0, kv = 0;
  if (vi < mesh_->vertex_capacity() && mesh_->is_alive(VertexId(vi)))
    for (TetId t : mesh_->incident_tets(VertexId(vi))) {
      v += vol_[t.idx()] / 4;
      kv += kappa_[t.idx()] * vol_[t.idx()] / 4;
    }
  nvol_[vi] = v;
  nkv_[vi] = kv;
}

namespace {
// 3-vectors summed per vertex of one vertex's 1-ring: open addressing (a list searched linearly
// was most of the volumetric blocks' time: docs/solver.md#nodal-averaged-product), cleared by
// the slots used.
class RingSums {
public:
  Eigen::Vector3d& at(std::uint32_t w) {
    if (2 * (used_.size() + 1) > key_.size()) grow();
    std::size_t i = slot(w);
    if (key_[i] == kEmpty) {
      key_[i] = w;
      val_[i].setZero();
      used_.push_back(std::uint32_t(i));
    }
    return val_[i];
  }
  template <class F>
  void for_each(F&& f) const {
    for (std::uint32_t i : used_) f(key_[i], val_[i]);
  }
  void clear() {
    for (std::uint32_t i : used_) key_[i] = kEmpty;
    used_.clear();
  }

private:
  static constexpr std::uint32_t kEmpty = 0xffffffffu;
  std::size_t slot(std::uint32_t w) const {
    const std::size_t mask = key_.size() - 1;
    std::size_t i = (w * 2654435761u) & mask;
    while (key_[i] != kEmpty && key_[i] != w) i = (i + 1) & mask;
    return i;
  }
  void grow() {
    std::vector<std::pair<std::uint32_t, Eigen::Vector3d>> old;
    for (std::uint32_t i : used_) old.emplace_back(key_[i], val_[i]);
    key_.assign(std::max<std::size_t>(64, 2 * key_.size()), kEmpty);
    val_.resize(key_.size());
    used_.clear();
    for (const auto& [w, v] : old) at(w) = v;
  }
  std::vector<std::uint32_t> key_, used_;
  std::vector<Eigen::Vector3d> val_;
};
}  // namespace

// Block (v, v) of B^T B = sum_a kappa_a V_a (d theta_a / dx_v)(d theta_a / dx_v)^T over the
// vertices a sharing a tet with v, d theta_a / dx_v = (1 / V_a) sum_{t∋a,v} (V_t / 4) R_t grad N_v.
void FemModel::volumetric_block(std::uint32_t vi, Eigen::Matrix3d& blk) const {
  thread_local RingSums ring;
  ring.clear();
  for (std::uint32_t slot : corner_slots_[vi]) {
    const std::uint32_t ti = slot / 4;
    Eigen::Vector3d h = (vol_[ti] / 4) * shape_gradient(bm_[ti], int(slot % 4));
    if (kind_ == FemKind::Corotational) h = quat_[ti] * h;
    for (std::uint32_t a : verts_[ti]) ring.at(a) += h;
  }
  ring.for_each([&](std::uint32_t a, const Eigen::Vector3d& s) {
    if (nvol_[a] > 0) blk.noalias() += (nkv_[a] / (nvol_[a] * nvol_[a])) * s * s.transpose();
  });
}

void FemModel::nodal_b_row(std::uint32_t a, std::vector<std::pair<std::uint32_t, Eigen::Vector3d>>& row) const {
  row.clear();
  if (!nodal_averaged() || a >= mesh_->vertex_capacity() || !mesh_->is_alive(VertexId(a)) || !(nvol_[a] > 0)) return;
  const double w = std::sqrt(nkv_[a]) / nvol_[a];  // sqrt(kappa_a V_a) / V_a
  thread_local RingSums sums;
  sums.clear();
  for (TetId t : mesh_->incident_tets(VertexId(a))) {
    const std::uint32_t ti = t.idx();
    const Eigen::Matrix3d r = quat_[ti].toRotationMatrix();
    for (int j = 0; j < 4; ++j) sums.at(verts_[ti][std::size_t(j)]) += (w * vol_[ti] / 4) * (r * shape_gradient(bm_[ti], j));
  }
  sums.for_each([&](std::uint32_t v, const Eigen::Vector3d& g) { row.emplace_back(v, g); });
}

Eigen::SparseMatrix<double, Eigen::RowMajor> FemModel::nodal_b() const {
  if (!nodal_averaged() && !edge_smoothed()) return {};
  if (edge_smoothed()) {
    // The vertex rows, then the smoothed deviatoric rows C: B^T B is then all of K, and the
    // factor of a snapshot (elements()) is exact.
    std::vector<std::vector<std::pair<std::uint32_t, Eigen::Vector3d>>> vrows(vertex_capacity_);
    parallel_range(vertex_capacity_, [&](std::size_t a) { nodal_b_row(std::uint32_t(a), vrows[a]); });
    const Eigen::SparseMatrix<double> c = smoothed_rows();
    std::vector<Eigen::Triplet<double>> trip;
    trip.reserve(std::size_t(c.nonZeros()) + 9 * 27 * vertex_capacity_);
    for (std::size_t a = 0; a < vertex_capacity_; ++a)
      for (const auto& [w, d] : vrows[a])
        for (int k = 0; k < 3; ++k) trip.emplace_back(Eigen::Index(a), Eigen::Index(3 * w + std::uint32_t(k)), d[k]);
    const Eigen::Index off = Eigen::Index(vertex_capacity_);
    for (Eigen::Index col = 0; col < c.outerSize(); ++col)
      for (Eigen::SparseMatrix<double>::InnerIterator it(c, col); it; ++it) trip.emplace_back(off + it.row(), col, it.value());
    Eigen::SparseMatrix<double, Eigen::RowMajor> b(off + c.rows(), rows());
    b.setFromTriplets(trip.begin(), trip.end());
    return b;
  }
  const std::size_t nv = vertex_capacity_;
  std::vector<std::vector<std::pair<std::uint32_t, Eigen::Vector3d>>> rows(nv);
  parallel_range(nv, [&](std::size_t a) {
    nodal_b_row(std::uint32_t(a), rows[a]);
    std::sort(rows[a].begin(), rows[a].end(), [](const auto& p, const auto& q) { return p.first < q.first; });
  });
  Eigen::SparseMatrix<double, Eigen::RowMajor> b(Eigen::Index(nv), Eigen::Index(3 * nv));
  Eigen::VectorXi nnz = Eigen::VectorXi::Zero(Eigen::Index(nv));
  for (std::size_t a = 0; a < nv; ++a) nnz[Eigen::Index(a)] = int(3 * rows[a].size());
  b.reserve(nnz);
  for (std::size_t a = 0; a < nv; ++a)
    for (const auto& [w, d] : rows[a])
      for (int c = 0; c < 3; ++c) b.insert(Eigen::Index(a), Eigen::Index(3 * w + c)) = d[c];
  b.makeCompressed();
  return b;
}

// Pass 1 per tet div_t, pass 2 per vertex kappa_a theta_a, pass 3 per tet the mean pressure and
// the corner forces, added into *y when given. In parallel each pass is conflict-free (vertices
// gather their corners' div and forces through corner_slots_). Small meshes run serially and
// scatter instead: every pass then sweeps the tets in order, no per-vertex slot lists to chase
// and no per-corner scratch (docs/solver.md#behind-the-constants).
void FemModel::volumetric_pass(const Eigen::VectorXd* x, bool rotation, double sign, Eigen::VectorXd* y) const {
  const bool corot = kind_ == FemKind::Corotational;
  const bool serial = tet_capacity_ < kVolumetricSerialBelow;
  auto divergence = [&](std::size_t ti) {
    double d = 0;
    if (x) {
      const auto& v = verts_[ti];
      const Eigen::Vector3d x0 = x->segment<3>(3 * v[0]);
      Eigen::Matrix3d e;
      for (int j = 0; j < 3; ++j) e.col(j) = x->segment<3>(3 * v[j + 1]) - x0;
      if (corot) e = quat_[ti].toRotationMatrix().transpose() * e;
      d = e.cwiseProduct(bm_[ti].transpose()).sum();  // tr(R^T E B) = tr(R^T H)
    }
    if (rotation && corot) d += quat_[ti].toRotationMatrix().trace() - 3;  // tr(R^T F - I) - tr(R^T H)
    return d;
  };
  auto corner_forces = [&](std::size_t ti) {  // column j: sign V pbar R grad N_{j+1}
    const auto& v = verts_[ti];
    const double p = (ptheta_[v[0]] + ptheta_[v[1]] + ptheta_[v[2]] + ptheta_[v[3]]) / 4;
    pbar_[ti] = p;
    if (corot) return Eigen::Matrix3d((sign * vol_[ti] * p) * quat_[ti].toRotationMatrix() * bm_[ti].transpose());
    return Eigen::Matrix3d((sign * vol_[ti] * p) * bm_[ti].transpose());
  };
  auto theta = [&](std::size_t vi, double s) { ptheta_[vi] = nodal_pressure(vi, s); };
  if (serial) {
    std::fill(ptheta_.begin(), ptheta_.end(), 0.0);
    for (std::size_t ti = 0; ti < tet_capacity_; ++ti)
      if (alive_[ti]) {
        const double vd = vol_[ti] * divergence(ti);
        for (std::uint32_t v : verts_[ti]) ptheta_[v] += vd;
      }
    for (std::size_t vi = 0; vi < vertex_capacity_; ++vi) theta(vi, ptheta_[vi]);
    for (std::size_t ti = 0; ti < tet_capacity_; ++ti) {
      if (!alive_[ti]) continue;
      const Eigen::Matrix3d g = corner_forces(ti);
      if (!y) continue;
      const auto& v = verts_[ti];
      y->segment<3>(3 * v[0]) -= g.rowwise().sum();
      for (int j = 0; j < 3; ++j) y->segment<3>(3 * v[j + 1]) += g.col(j);
    }
    return;
  }
  parallel_range(tet_capacity_, [&](std::size_t ti) {
    if (alive_[ti]) div_[ti] = divergence(ti);
  });
  parallel_range(vertex_capacity_, [&](std::size_t vi) {
    double s = 0;
    for (std::uint32_t slot : corner_slots_[vi]) s += vol_[slot / 4] * div_[slot / 4];
    theta(vi, s);
  });
  parallel_range(tet_capacity_, [&](std::size_t ti) {
    if (!alive_[ti]) return;
    const Eigen::Matrix3d g = corner_forces(ti);
    force_[ti].rightCols<3>() = g;
    force_[ti].col(0) = -g.rowwise().sum();
  });
  if (y) gather(*y, true);
}

}  // namespace incise
