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

void FemModel::volume_gradients(std::uint32_t ti) {
  for (int j = 0; j < 4; ++j) {
    Eigen::Vector3d h = (vol_[ti] / 4) * shape_gradient(bm_[ti], j);
    if (kind_ == FemKind::Corotational) h = quat_[ti] * h;
    vgrad_[4 * std::size_t(ti) + std::size_t(j)] = h;
  }
}

void FemModel::build_ring(std::uint32_t vi) {
  thread_local std::vector<std::uint32_t> pos;  // by vertex id: position in ring_[vi], or none
  constexpr std::uint32_t kNone = 0xffffffffu;
  auto& ring = ring_[vi];
  auto& at = ring_at_[vi];
  ring.clear();
  at.clear();
  auto forget = [&] {
    for (std::uint32_t a : ring) pos[a] = kNone;
  };
  for (std::uint32_t slot : corner_slots_[vi])
    for (std::uint32_t a : verts_[slot / 4]) {
      if (a >= pos.size()) pos.resize(std::size_t(a) + 1, kNone);
      if (pos[a] == kNone) {
        if (ring.size() > 0xffffu) {  // positions are 16 bits
          forget();
          throw InvalidMesh("fem: vertex " + std::to_string(vi) + " has over 65,536 neighbours");
        }
        pos[a] = std::uint32_t(ring.size());
        ring.push_back(a);
      }
      at.push_back(std::uint16_t(pos[a]));
    }
  forget();
}

// Block (v, v) of B^T B = sum_a kappa_a V_a (d theta_a / dx_v)(d theta_a / dx_v)^T over the
// vertices a sharing a tet with v, d theta_a / dx_v = (1 / V_a) sum_{t∋a,v} (V_t / 4) R_t grad N_v.
void FemModel::volumetric_block(std::uint32_t vi, Eigen::Matrix3d& blk) const {
  const auto& slots = corner_slots_[vi];
  const auto& ring = ring_[vi];
  const std::uint16_t* at = ring_at_[vi].data();
  thread_local std::vector<Eigen::Vector3d> sums;
  sums.assign(ring.size(), Eigen::Vector3d::Zero());
  for (std::size_t k = 0; k < slots.size(); ++k) {
    const Eigen::Vector3d& h = vgrad_[slots[k]];
    for (std::size_t j = 0; j < 4; ++j) sums[at[4 * k + j]] += h;
  }
  for (std::size_t i = 0; i < ring.size(); ++i) {
    const std::uint32_t a = ring[i];
    if (nvol_[a] > 0) blk.noalias() += (nkv_[a] / (nvol_[a] * nvol_[a])) * sums[i] * sums[i].transpose();
  }
}

void FemModel::nodal_b_row(std::uint32_t a, std::vector<std::pair<std::uint32_t, Eigen::Vector3d>>& row) const {
  row.clear();
  if (!nodal_averaged() || a >= mesh_->vertex_capacity() || !mesh_->is_alive(VertexId(a)) || !(nvol_[a] > 0)) return;
  const double w = std::sqrt(nkv_[a]) / nvol_[a];  // sqrt(kappa_a V_a) / V_a
  const auto& slots = corner_slots_[a];
  const auto& ring = ring_[a];
  const std::uint16_t* at = ring_at_[a].data();
  row.resize(ring.size());
  for (std::size_t i = 0; i < ring.size(); ++i) row[i] = {ring[i], Eigen::Vector3d::Zero()};
  for (std::size_t k = 0; k < slots.size(); ++k) {
    const std::size_t ti = slots[k] / 4;
    for (std::size_t j = 0; j < 4; ++j) row[at[4 * k + j]].second += vgrad_[4 * ti + j];
  }
  for (auto& [v, g] : row) g *= w;
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
    return volumetric_corner_block(ti, p, sign);
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

// The rotation's own volumetric force, -V_t pbar_t R_t grad N_j per corner with pbar_t from
// div_t = tr(R_t) - 3: volumetric_pass(nullptr, true, -1, &b)'s expressions, kept.
Eigen::Matrix3d FemModel::volumetric_corner_block(std::size_t ti, double p, double sign) const {
  if (kind_ == FemKind::Corotational)
    return Eigen::Matrix3d((sign * vol_[ti] * p) * quat_[ti].toRotationMatrix() * bm_[ti].transpose());
  return Eigen::Matrix3d((sign * vol_[ti] * p) * bm_[ti].transpose());
}

void FemModel::rotation_corner_forces(std::size_t ti) const {
  const auto& v = verts_[ti];
  const double p = (rtheta_[v[0]] + rtheta_[v[1]] + rtheta_[v[2]] + rtheta_[v[3]]) / 4;
  const Eigen::Matrix3d g = volumetric_corner_block(ti, p, -1.0);
  rforce_[ti].rightCols<3>() = g;
  rforce_[ti].col(0) = -g.rowwise().sum();
}

void FemModel::rotation_vertex_sum(std::size_t vi) const { vrhs_.segment<3>(3 * vi) = corner_sum(rforce_, vi); }

void FemModel::rotation_volumetric_rhs(Eigen::VectorXd& b) const {
  if (kind_ != FemKind::Corotational) return;
  if (tet_capacity_ < kVolumetricSerialBelow) {
    // Small meshes scatter in tet order (volumetric_pass): nothing is kept.
    volumetric_pass(nullptr, true, -1.0, &b);
    return;
  }
  if (!vrhs_valid_) {
    rdiv_.assign(tet_capacity_, 0.0);
    rtheta_.assign(vertex_capacity_, 0.0);
    rforce_.resize(tet_capacity_);
    vrhs_.setZero(Eigen::Index(3 * vertex_capacity_));
    parallel_range(tet_capacity_, [&](std::size_t ti) {
      if (alive_[ti]) rdiv_[ti] = 0.0 + (quat_[ti].toRotationMatrix().trace() - 3);
    });
    parallel_range(vertex_capacity_, [&](std::size_t vi) {
      double s = 0;
      for (std::uint32_t slot : corner_slots_[vi]) s += vol_[slot / 4] * rdiv_[slot / 4];
      rtheta_[vi] = nodal_pressure(vi, s);
    });
    parallel_range(tet_capacity_, [&](std::size_t ti) {
      if (alive_[ti]) rotation_corner_forces(ti);
    });
    parallel_range(vertex_capacity_, [&](std::size_t vi) { rotation_vertex_sum(vi); });
    vrhs_valid_ = true;
  }
  b.head(vrhs_.size()) += vrhs_;
}

// After a partial relinearization of `tets` (alive), whose vertices are `verts`: their div_t,
// those vertices' theta, the corner forces of every tet around them, and the sums of those
// tets' vertices; the rest of vrhs_ is unchanged.
void FemModel::refresh_rotation_volumetric(const std::vector<std::uint32_t>& tets,
                                           const std::vector<std::uint32_t>& verts) {
  parallel_range(tets.size(), [&](std::size_t i) {
    rdiv_[tets[i]] = 0.0 + (quat_[tets[i]].toRotationMatrix().trace() - 3);
  });
  parallel_range(verts.size(), [&](std::size_t i) {
    const std::uint32_t vi = verts[i];
    double s = 0;
    for (std::uint32_t slot : corner_slots_[vi]) s += vol_[slot / 4] * rdiv_[slot / 4];
    rtheta_[vi] = nodal_pressure(vi, s);
  });
  tet_mark_.resize(tet_capacity_, 0);
  vertex_mark_.resize(vertex_capacity_, 0);
  std::vector<std::uint32_t> around, sums;
  for (std::uint32_t vi : verts)
    for (std::uint32_t slot : corner_slots_[vi])
      if (!tet_mark_[slot / 4]) {
        tet_mark_[slot / 4] = 1;
        around.push_back(slot / 4);
      }
  for (std::uint32_t ti : around)
    for (std::uint32_t v : verts_[ti])
      if (!vertex_mark_[v]) {
        vertex_mark_[v] = 1;
        sums.push_back(v);
      }
  parallel_range(around.size(), [&](std::size_t i) { rotation_corner_forces(around[i]); });
  parallel_range(sums.size(), [&](std::size_t i) { rotation_vertex_sum(sums[i]); });
  for (std::uint32_t ti : around) tet_mark_[ti] = 0;
  for (std::uint32_t v : sums) vertex_mark_[v] = 0;
  work_.rotation_rhs_sums += sums.size();
}

}  // namespace incise
