#include "sim/fem/inversion_barrier.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>

#include "sim/fem/fem_model.h"

namespace incise {

void InversionBarrier::update(const FemModel& model, const Eigen::VectorXd& u) {
  terms_.clear();
  if (!enabled()) return;
  const TetMesh& mesh = model.mesh();
  const std::size_t n = mesh.tet_capacity();
  held_.resize(n, 0);
  const double release = std::min(1.0, 2 * opt_.j_min);
  tbb::enumerable_thread_specific<std::vector<Term>> found;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1024), [&](const tbb::blocked_range<std::size_t>& r) {
    auto& mine = found.local();
    for (std::size_t ti = r.begin(); ti != r.end(); ++ti) {
      const TetId t(static_cast<std::uint32_t>(ti));
      if (!model.tet_alive(t)) continue;
      const auto& v = model.tet_vertex_ids(t);
      const Eigen::Matrix3d& b = model.tet_shape_matrix(t);  // row j-1: grad N_j
      Eigen::Matrix3d d;                                       // columns u_j - u_0
      for (int j = 1; j < 4; ++j) d.col(j - 1) = u.segment<3>(3 * v[j]) - u.segment<3>(3 * v[0]);
      const Eigen::Matrix3d f = Eigen::Matrix3d::Identity() + d * b;
      const double jk = f.determinant();
      if (!(jk < opt_.j_min) && !(held_[ti] && jk < release)) {
        held_[ti] = 0;
        continue;
      }
      held_[ti] = 1;
      Eigen::Matrix3d cof;  // d det F / dF
      cof.col(0) = f.col(1).cross(f.col(2));
      cof.col(1) = f.col(2).cross(f.col(0));
      cof.col(2) = f.col(0).cross(f.col(1));
      Term term;
      term.tet = t.idx();
      term.v = v;
      Eigen::Vector3d g0 = Eigen::Vector3d::Zero();
      for (int j = 1; j < 4; ++j) {
        const Eigen::Vector3d gj = cof * b.row(j - 1).transpose();
        term.g.segment<3>(3 * j) = gj;
        g0 -= gj;
      }
      term.g.segment<3>(0) = g0;
      const double p_wave = model.tet_kappa(t) + 4 * model.tet_mu(t) / 3;
      term.w = 2 * opt_.stiffness * p_wave * model.tet_volume(t);
      double gu = 0;
      for (int j = 0; j < 4; ++j) gu += term.g.segment<3>(3 * j).dot(u.segment<3>(3 * v[j]));
      term.c = std::max(opt_.j_min, jk) - jk + gu;
      mine.push_back(term);
    }
  });
  for (auto& part : found) terms_.insert(terms_.end(), part.begin(), part.end());
  // In tet order, not in the order the threads found them: the product sums the terms in this
  // order, and a scene must give the same frames on every run, however busy the machine.
  std::sort(terms_.begin(), terms_.end(), [](const Term& a, const Term& b) { return a.tet < b.tet; });
}

void InversionBarrier::apply(const TopologyChange& change) {
  terms_.clear();
  for (TetId t : change.removed_tets)
    if (t.idx() < held_.size()) held_[t.idx()] = 0;
}

void InversionBarrier::add_product(const Eigen::VectorXd& x, Eigen::VectorXd& y) const {
  for (const Term& t : terms_) {
    double s = 0;
    for (int j = 0; j < 4; ++j) s += t.g.segment<3>(3 * j).dot(x.segment<3>(3 * t.v[j]));
    for (int j = 0; j < 4; ++j) y.segment<3>(3 * t.v[j]) += t.w * s * t.g.segment<3>(3 * j);
  }
}

void InversionBarrier::add_rhs(Eigen::VectorXd& b) const {
  for (const Term& t : terms_)
    for (int j = 0; j < 4; ++j) b.segment<3>(3 * t.v[j]) += t.w * t.c * t.g.segment<3>(3 * j);
}

void InversionBarrier::add_internal_forces(const Eigen::VectorXd& u, Eigen::VectorXd& f) const {
  for (const Term& t : terms_) {
    double s = 0;
    for (int j = 0; j < 4; ++j) s += t.g.segment<3>(3 * j).dot(u.segment<3>(3 * t.v[j]));
    for (int j = 0; j < 4; ++j) f.segment<3>(3 * t.v[j]) += t.w * (t.c - s) * t.g.segment<3>(3 * j);
  }
}

void InversionBarrier::add_to(Eigen::SparseMatrix<double>& k) const {
  // The tet's 12 x 12 entries lie in K's pattern (a tet's corners are neighbours).
  for (const Term& t : terms_)
    for (int i = 0; i < 12; ++i)
      for (int j = 0; j < 12; ++j)
        k.coeffRef(Eigen::Index(3 * t.v[i / 3] + i % 3), Eigen::Index(3 * t.v[j / 3] + j % 3)) +=
            t.w * t.g[i] * t.g[j];
}

}  // namespace incise
