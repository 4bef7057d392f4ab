// FemModel assembled: the per-tet element data (elements()) and the sparse K (assemble()) that the
// direct solver, the assembled backend and the background factor use.
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

FemElements FemModel::elements() const {
  FemElements e{alive_, verts_, bm_, {}, vol_, mu_, lambda_, nodal_b()};
  if (edge_smoothed()) {  // all of K is in B^T B (see nodal_b()); no per-tet blocks
    std::fill(e.mu.begin(), e.mu.end(), 0.0);
    std::fill(e.lambda.begin(), e.lambda.end(), 0.0);
  }
  e.rot.resize(quat_.size());
  for (std::size_t t = 0; t < quat_.size(); ++t) e.rot[t] = quat_[t].toRotationMatrix();
  return e;
}

Eigen::SparseMatrix<double> FemModel::assemble() const {
  // Row-wise from the vertex incidence: each vertex's block row is filled by one task, so the
  // assembly is parallel and needs no triplet list (144 per tet would not fit at 1M tets).
  // K is symmetric, so filling CSR arrays into a column-major matrix gives K itself.
  const std::size_t nv = vertex_capacity_;
  std::vector<std::vector<std::uint32_t>> nbrs(nv);
  parallel_range(nv, [&](std::size_t vi) {
    if (vi >= mesh_->vertex_capacity() || !mesh_->is_alive(VertexId(std::uint32_t(vi)))) return;
    auto& nb = nbrs[vi];
    for (TetId t : mesh_->incident_tets(VertexId(std::uint32_t(vi))))
      for (std::uint32_t w : verts_[t.idx()]) nb.push_back(w);
    std::sort(nb.begin(), nb.end());
    nb.erase(std::unique(nb.begin(), nb.end()), nb.end());
  });
  const Eigen::Index n = rows();
  Eigen::SparseMatrix<double> k(n, n);
  std::vector<std::int64_t> start(nv + 1, 0);
  for (std::size_t vi = 0; vi < nv; ++vi) start[vi + 1] = start[vi] + std::int64_t(9 * nbrs[vi].size());
  k.resizeNonZeros(Eigen::Index(start[nv]));
  auto* outer = k.outerIndexPtr();
  auto* inner = k.innerIndexPtr();
  double* val = k.valuePtr();
  for (std::size_t vi = 0; vi < nv; ++vi) {
    const std::int64_t per_row = std::int64_t(3 * nbrs[vi].size());
    for (int a = 0; a < 3; ++a) outer[3 * vi + a] = int(start[vi] + a * per_row);
  }
  outer[n] = int(start[nv]);
  parallel_range(nv, [&](std::size_t vi) {
    const auto& nb = nbrs[vi];
    const std::int64_t per_row = std::int64_t(3 * nb.size());
    for (int a = 0; a < 3; ++a)
      for (std::size_t c = 0; c < nb.size(); ++c)
        for (int b = 0; b < 3; ++b) {
          const std::int64_t pos = start[vi] + a * per_row + std::int64_t(3 * c + b);
          inner[pos] = int(3 * nb[c] + b);
          val[pos] = 0;
        }
    if (nb.empty() || edge_smoothed()) return;  // EdgeSmoothed: the deviatoric part is smoothed_stiffness()
    for (TetId t : mesh_->incident_tets(VertexId(std::uint32_t(vi)))) {
      const std::uint32_t ti = t.idx();
      const auto& tv = verts_[ti];
      const Eigen::Matrix3d r = quat_[ti].toRotationMatrix();
      int i = 0;
      while (tv[i] != vi) ++i;
      for (int j = 0; j < 4; ++j) {
        const Eigen::Matrix3d blk = element_block(bm_[ti], vol_[ti], mu_[ti], lambda_[ti], r, i, j);
        const std::size_t c = std::size_t(std::lower_bound(nb.begin(), nb.end(), tv[j]) - nb.begin());
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b) val[start[vi] + a * per_row + std::int64_t(3 * c + b)] += blk(a, b);
      }
    }
  });
  if (nodal_averaged() || edge_smoothed()) {  // edge-smoothed: B holds the smoothed rows too
    const Eigen::SparseMatrix<double, Eigen::RowMajor> b = nodal_b();
    const Eigen::SparseMatrix<double> bc = b, bt = b.transpose();
    k += Eigen::SparseMatrix<double>(bt * bc);
  }
  if (barrier_.held() > 0 && kind_ == FemKind::Corotational) barrier_.add_to(k);
  k.makeCompressed();  // the assembled backend reads the CSR arrays directly
  return k;
}

}  // namespace incise
