#include "sim/fem/fem_model.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>

#include <Eigen/SparseCore>

#include <Eigen/LU>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "mesh/errors.h"
#include "sim/fem/fem_model_detail.h"
#include "sim/linalg/simd_clones.h"

namespace incise {

using namespace fem_detail;

Eigen::Matrix3d element_block(const Eigen::Matrix3d& bm, double vol, double mu, double lambda, const Eigen::Matrix3d& r,
                              int i, int j) {
  const Eigen::Vector3d gi = shape_gradient(bm, i), gj = shape_gradient(bm, j);
  const Eigen::Matrix3d blk =
      vol * (mu * gi.dot(gj) * Eigen::Matrix3d::Identity() + mu * gj * gi.transpose() + lambda * gi * gj.transpose());
  return r * blk * r.transpose();
}

double von_mises_of(const Eigen::Matrix3d& s) {
  const double a = s(0, 0) - s(1, 1), b = s(1, 1) - s(2, 2), c = s(2, 2) - s(0, 0);
  const double sh = s(0, 1) * s(0, 1) + s(1, 2) * s(1, 2) + s(0, 2) * s(0, 2);
  return std::sqrt(0.5 * (a * a + b * b + c * c) + 3 * sh);
}

FemModel::FemModel(const TetMesh& mesh, const MaterialTable& materials, FemKind kind, Formulation formulation,
                   bool smooth_edges)
    : mesh_(&mesh), materials_(materials), kind_(kind), formulation_(formulation),
      smooth_(smooth_edges || formulation == Formulation::EdgeSmoothed), kernel_(kind == FemKind::Corotational) {
  if (is_mixed(formulation_))
    throw InvalidArgument("fem: the mixed formulation has pressure unknowns; FemModel is displacement only");
  check_material(materials_.fallback(), "materials.*");
  for (const auto& [label, m] : materials_.by_label()) check_material(m, "materials." + std::to_string(label));
  grow();
  parallel_range(tet_capacity_, [&](std::size_t t) { compute_tet(std::uint32_t(t)); });
  // Every V_a before any diagonal block: a vertex's volumetric block reads its 1-ring's.
  if (nodal_averaged()) parallel_range(vertex_capacity_, [&](std::size_t v) { nodal_volume_of(std::uint32_t(v)); });
  if (edge_smoothed()) {
    edge_index_.reserve(tet_capacity_ + tet_capacity_ / 2);
    for (std::size_t t = 0; t < tet_capacity_; ++t)
      if (alive_[t]) register_tet(std::uint32_t(t));
    parallel_range(edge_tets_.size(), [&](std::size_t e) { edge_moduli(std::uint32_t(e)); });
  }
  // Tets enter the kernel by their smallest vertex id, so each slab sweeps x and y in order
  // (hardware prefetch instead of a cache miss per corner on large meshes).
  std::vector<std::pair<std::uint32_t, std::uint32_t>> order;
  order.reserve(tet_capacity_);
  for (std::size_t t = 0; t < tet_capacity_; ++t)
    if (alive_[t]) order.emplace_back(*std::min_element(verts_[t].begin(), verts_[t].end()), std::uint32_t(t));
  std::sort(order.begin(), order.end());
  kernel_.configure(*mesh_);
  for (const auto& [v, t] : order) kernel_.add(*mesh_, t, verts_[t], bm_[t], vol_[t] * mu_[t], vol_[t] * lambda_[t], vol_[t]);
  parallel_range(vertex_capacity_, [&](std::size_t v) { compute_vertex(std::uint32_t(v)); });
}

void FemModel::grow() {
  const std::size_t nt = mesh_->tet_capacity(), nv = mesh_->vertex_capacity();
  if (tet_capacity_ == 0) {
    // Room for edits from the start: the first cut then does not copy every per-tet array (an
    // O(mesh) spike in its frame); later growth is geometric (std::vector), so amortized.
    const std::size_t room = nt + nt / 8 + 256;
    alive_.reserve(room);
    verts_.reserve(room);
    bm_.reserve(room);
    vol_.reserve(room);
    mu_.reserve(room);
    lambda_.reserve(room);
    kappa_.reserve(room);
    rho_.reserve(room);
    quat_.reserve(room);
    force_.reserve(room);
    if (nodal_averaged()) vgrad_.reserve(4 * room);
  }
  if (nt > tet_capacity_) {
    alive_.resize(nt, 0);
    verts_.resize(nt);
    bm_.resize(nt, Eigen::Matrix3d::Zero());
    vol_.resize(nt, 0);
    mu_.resize(nt, 0);
    lambda_.resize(nt, 0);
    kappa_.resize(nt, 0);
    rho_.resize(nt, 0);
    quat_.resize(nt, Eigen::Quaterniond::Identity());
    force_.resize(nt);
    if (nodal_averaged()) {
      div_.resize(nt, 0.0);
      pbar_.resize(nt, 0.0);
      vgrad_.resize(4 * nt, Eigen::Vector3d::Zero());
    }
    if (edge_smoothed()) {
      tet_edges_.resize(nt);
      registered_.resize(nt, 0);
      teps_.resize(nt, Eigen::Matrix3d::Zero());
      tsig_.resize(nt, Eigen::Matrix3d::Zero());
    }
    tet_capacity_ = nt;
  }
  if (nv > vertex_capacity_) {
    // Geometric growth: a conservativeResize per added vertex would make every split O(mesh).
    // Slots beyond the mesh's capacity behave as dead vertices (zero rows, not free).
    const std::size_t cap = vertex_capacity_ == 0 ? nv : std::max(nv, vertex_capacity_ + vertex_capacity_ / 2);
    const Eigen::Index old = diag_.size();
    diag_.conservativeResize(Eigen::Index(3 * cap));
    rhs_.conservativeResize(Eigen::Index(3 * cap));
    rhs_.tail(rhs_.size() - old).setZero();
    mass_.conservativeResize(Eigen::Index(3 * cap));
    diag_.tail(diag_.size() - old).setZero();
    mass_.tail(mass_.size() - old).setZero();
    corner_slots_.resize(cap);
    blocks_.resize(cap, Eigen::Matrix3d::Zero());
    if (edge_smoothed()) sblock_.resize(cap, Eigen::Matrix3d::Zero());
    iso_.resize(cap, 0.0);
    if (nodal_averaged()) {
      nvol_.resize(cap, 0.0);
      nkv_.resize(cap, 0.0);
      ptheta_.resize(cap, 0.0);
      ring_mark_.resize(cap, 0);
      ring_.resize(cap);
      ring_at_.resize(cap);
    }
    vertex_capacity_ = cap;
  }
}

void FemModel::compute_tet(std::uint32_t ti) {
  const TetId t(ti);
  if (!mesh_->is_alive(t)) {
    alive_[ti] = 0;
    return;
  }
  const auto& v = mesh_->tet_vertices(t);
  for (int k = 0; k < 4; ++k) verts_[ti][k] = v[k].idx();
  const Vec3& x0 = mesh_->rest(v[0]);
  Eigen::Matrix3d dm;
  dm.col(0) = mesh_->rest(v[1]) - x0;
  dm.col(1) = mesh_->rest(v[2]) - x0;
  dm.col(2) = mesh_->rest(v[3]) - x0;
  const double vol = dm.determinant() / 6;
  if (!(vol > 0) || !std::isfinite(vol))
    throw InvalidMesh("fem: tet " + std::to_string(ti) + " has rest volume " + std::to_string(vol) +
                      " (degenerate or inverted); repair the mesh first");
  bm_[ti] = dm.inverse();
  vol_[ti] = vol;
  const Material& m = materials_.get(mesh_->label(t));
  mu_[ti] = m.mu();
  kappa_[ti] = m.lambda() + 2 * m.mu() / 3;
  // Nodal-averaged: the per-tet element keeps only the deviatoric part (its volumetric part,
  // lambda + 2 mu / 3 = 0, moves to the vertices).
  lambda_[ti] = nodal_averaged() ? -2 * m.mu() / 3 : m.lambda();
  rho_[ti] = m.density;
  quat_[ti].setIdentity();  // R = I, as the kernel's add() starts
  alive_[ti] = 1;
  if (nodal_averaged()) volume_gradients(ti);
}

void FemModel::compute_vertex(std::uint32_t vi) {
  double m = 0, iso = 0;
  const VertexId v(vi);
  auto& slots = corner_slots_[vi];
  slots.clear();
  if (vi < mesh_->vertex_capacity() && mesh_->is_alive(v)) {
    for (TetId t : mesh_->incident_tets(v)) {
      const std::uint32_t ti = t.idx();
      int j = 0;
      while (verts_[ti][j] != vi) ++j;
      slots.push_back(4 * ti + std::uint32_t(j));
      iso += vol_[ti] * mu_[ti] * shape_gradient(bm_[ti], j).squaredNorm();
      m += rho_[ti] * vol_[ti] / 4;
    }
  }
  iso_[vi] = iso;
  mass_.segment<3>(3 * vi).setConstant(m);
  if (nodal_averaged()) build_ring(vi);
  vertex_block(vi);
}

// Block (i, i) of the element matrix, V (mu |g|^2 I + (mu + lambda) (R g)(R g)^T), summed over the
// vertex's corners (the rotation-free part is iso_, the rest c c^T with c = sqrt(V (mu + lambda))
// R g), and the vertex's b_R: the sum of its corners' forces V R sigma(I - R^T) g. From the
// stored rotations, as corner_terms() computes them for a packet (the whole-mesh pass,
// relinearize(), scatters them instead).
void FemModel::vertex_block(std::uint32_t vi) {
  Eigen::Matrix3d blk = iso_[vi] * Eigen::Matrix3d::Identity();
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  for (std::uint32_t slot : corner_slots_[vi]) {
    const std::uint32_t ti = slot / 4;
    const Eigen::Matrix3d r = quat_[ti].toRotationMatrix();
    const Eigen::Vector3d g = shape_gradient(bm_[ti], int(slot % 4));
    const Eigen::Vector3d c = std::sqrt(vol_[ti] * (mu_[ti] + lambda_[ti])) * (r * g);
    blk.noalias() += c * c.transpose();
    rhs += vol_[ti] * r * stress_of(Eigen::Matrix3d::Identity() - r.transpose(), mu_[ti], lambda_[ti]) * g;
  }
  rhs_.segment<3>(3 * vi) = rhs;
  if (edge_smoothed()) {
    smoothed_rest_block(vi);
    smoothed_block(vi, blk);
  }
  if (nodal_averaged()) volumetric_block(vi, blk);
  blocks_[vi] = blk;
  diag_.segment<3>(3 * vi) = blk.diagonal();
}

void FemModel::apply(const TopologyChange& change) {
  grow();
  ++work_.updates;
  vrhs_valid_ = false;  // V_a, the slots and the tets changed: the next rhs sums in full
  barrier_.apply(change);
  std::vector<std::uint32_t> edges;  // EdgeSmoothed: edges whose tets changed
  for (TetId t : change.removed_tets) {
    if (t.idx() < tet_capacity_) {
      alive_[t.idx()] = 0;
      if (edge_smoothed() && registered_[t.idx()]) {
        edges.insert(edges.end(), tet_edges_[t.idx()].begin(), tet_edges_[t.idx()].end());
        unregister_tet(t.idx());
      }
    }
    kernel_.remove(t.idx());
  }
  for (TetId t : change.added_tets) {
    const std::uint32_t ti = t.idx();
    compute_tet(ti);
    if (alive_[ti]) kernel_.add(*mesh_, ti, verts_[ti], bm_[ti], vol_[ti] * mu_[ti], vol_[ti] * lambda_[ti], vol_[ti]);
    if (edge_smoothed() && alive_[ti] && !registered_[ti]) {
      register_tet(ti);
      edges.insert(edges.end(), tet_edges_[ti].begin(), tet_edges_[ti].end());
    }
    ++work_.tets_recomputed;
  }
  if (edge_smoothed()) {
    std::sort(edges.begin(), edges.end());
    edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
    for (std::uint32_t e : edges) edge_moduli(e);
    work_.edges_updated += edges.size();
  }
  for (VertexId v : change.removed_vertices) {
    if (nodal_averaged()) {
      nvol_[v.idx()] = nkv_[v.idx()] = 0;
      ring_[v.idx()].clear();
      ring_at_[v.idx()].clear();
    }
    corner_slots_[v.idx()].clear();
    iso_[v.idx()] = 0;
    blocks_[v.idx()].setZero();
    diag_.segment<3>(3 * v.idx()).setZero();
    rhs_.segment<3>(3 * v.idx()).setZero();
    mass_.segment<3>(3 * v.idx()).setZero();
    ++work_.vertices_updated;
  }
  // Nodal-averaged: all touched V_a first, since each touched vertex's block reads its 1-ring's.
  if (nodal_averaged())
    for (VertexId v : change.touched_vertices) nodal_volume_of(v.idx());
  for (VertexId v : change.touched_vertices) {
    compute_vertex(v.idx());
    ++work_.vertices_updated;
  }
  if (nodal_averaged()) refresh_ring(change);
}

// The volumetric part of vertex w's diagonal block reads V_a and kappa_a of every a in w's
// 1-ring: after an edit, the untouched neighbours of touched vertices are recomputed (their
// corner terms are unchanged, their incident tets too). Marks are cleared before returning.
void FemModel::refresh_ring(const TopologyChange& change) {
  std::vector<std::uint32_t> marked;
  auto mark = [&](std::uint32_t v) {
    if (ring_mark_[v]) return false;
    ring_mark_[v] = 1;
    marked.push_back(v);
    return true;
  };
  for (VertexId v : change.touched_vertices) mark(v.idx());
  for (VertexId v : change.removed_vertices) mark(v.idx());
  for (VertexId v : change.touched_vertices) {
    if (!mesh_->is_alive(v)) continue;
    for (TetId t : mesh_->incident_tets(v))
      for (std::uint32_t w : verts_[t.idx()])
        if (mark(w)) {
          vertex_block(w);
          ++work_.blocks_updated;
        }
  }
  for (std::uint32_t v : marked) ring_mark_[v] = 0;
}

inline Eigen::Matrix3d FemModel::tet_stress(std::uint32_t ti, const Eigen::VectorXd& x, bool subtract_rotation,
                                            const Eigen::Matrix3d& r) const {
  const auto& v = verts_[ti];
  const Eigen::Vector3d x0 = x.segment<3>(3 * v[0]);
  Eigen::Matrix3d d;
  for (int j = 0; j < 3; ++j) d.col(j) = x.segment<3>(3 * v[j + 1]) - x0;
  Eigen::Matrix3d h = d * bm_[ti];
  if (kind_ == FemKind::Corotational) {
    h = r.transpose() * h;
    if (subtract_rotation) h += r.transpose() - Eigen::Matrix3d::Identity();  // R^T F - I
  }
  return stress_of(h, mu_[ti], lambda_[ti]);
}

Eigen::Vector3d FemModel::corner_sum(const std::vector<Eigen::Matrix<double, 3, 4>>& forces, std::size_t vi) const {
  const double* f = forces.data()->data();  // Matrix<double,3,4> is column-major: corner j at 3j
  Eigen::Vector3d s = Eigen::Vector3d::Zero();
  for (std::uint32_t slot : corner_slots_[vi]) s += Eigen::Map<const Eigen::Vector3d>(f + 3 * std::size_t(slot));
  return s;
}

void FemModel::gather(Eigen::VectorXd& y, bool accumulate) const {
  parallel_range(vertex_capacity_, [&](std::size_t vi) {
    const Eigen::Vector3d s = corner_sum(force_, vi);
    if (accumulate) y.segment<3>(3 * vi) += s;
    else y.segment<3>(3 * vi) = s;
  });
}

void FemModel::multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const {
  if (x.size() != rows()) throw InvalidArgument("fem: K*x with a vector of the wrong size (apply() the last change?)");
  if (edge_smoothed()) {
    smoothed_product(x, y);
  } else if (nodal_averaged()) {
    // Two coloured sweeps of the kernel and a vertex pass: the tets' divergences summed at
    // their vertices, the nodal pressures, then the deviatoric and volumetric forces together
    // (docs/solver.md#nodal-averaged-product).
    const bool serial = tet_capacity_ < kVolumetricSerialBelow;
    for_each_index(vertex_capacity_, serial, [&](std::size_t v) { ptheta_[v] = 0; });
    kernel_.strain_sweep(x, nullptr, ptheta_.data());
    for_each_index(vertex_capacity_, serial, [&](std::size_t v) { ptheta_[v] = nodal_pressure(v, ptheta_[v]); });
    kernel_.multiply(x, y, rows(), ptheta_.data());
  } else {
    kernel_.multiply(x, y, rows());
  }
  barrier_.add_product(x, y);
}

void FemModel::add_rotation_rhs(Eigen::VectorXd& b) const {
  if (kind_ != FemKind::Corotational) return;
  if (b.size() != rows()) throw InvalidArgument("fem: rotation rhs with a vector of the wrong size");
  if (edge_smoothed())
    deviatoric_pass(nullptr, true, -1.0, &b);  // the smoothed force of the rotations' own strain, negated
  else
    b += rhs_;  // summed per vertex with the diagonal (vertex_block)
  if (nodal_averaged()) {
    // The volumetric force of the rotations' own strain tr(R^T - I), negated (as rhs_'s).
    rotation_volumetric_rhs(b);
  }
  barrier_.add_rhs(b);
}

void FemModel::internal_forces(const Eigen::VectorXd& u, Eigen::VectorXd& f) const {
  if (u.size() != rows()) throw InvalidArgument("fem: internal forces with a vector of the wrong size");
  if (edge_smoothed()) {
    f.setZero(rows());
    deviatoric_pass(&u, true, -1.0, &f);
  } else {
    parallel_range(tet_capacity_, [&](std::size_t ti) {
      if (!alive_[ti]) return;
      const Eigen::Matrix3d r = quat_[ti].toRotationMatrix();
      const Eigen::Matrix3d p = vol_[ti] * r * tet_stress(std::uint32_t(ti), u, true, r);
      const Eigen::Matrix3d g = p * bm_[ti].transpose();
      force_[ti].rightCols<3>() = -g;
      force_[ti].col(0) = g.rowwise().sum();
    });
    f.resize(rows());
    gather(f, false);
  }
  if (nodal_averaged()) {
    volumetric_pass(&u, true, -1.0, &f);
  }
  barrier_.add_internal_forces(u, f);
}

std::vector<double> FemModel::von_mises(const Eigen::VectorXd& u) const {
  std::vector<double> out(tet_capacity_, 0.0);
  if (nodal_averaged()) volumetric_pass(&u, true, 1.0, nullptr);  // pbar_ per tet
  // The rotation of u itself (exact polar decomposition), not the stored one: the stored
  // rotations are the solver's state (warm starts of the next relinearization), and a stress
  // read for output must not change the run (it once did: frames written or coloured by
  // stress cut a slightly different mesh than frames that were not).
  auto rotation_of_u = [&](std::size_t ti) -> Eigen::Matrix3d {
    if (kind_ != FemKind::Corotational) return Eigen::Matrix3d::Identity();
    const auto& v = verts_[ti];
    Eigen::Matrix3d d;
    for (int j = 0; j < 3; ++j) d.col(j) = u.segment<3>(3 * v[j + 1]) - u.segment<3>(3 * v[0]);
    return polar_rotation(Eigen::Matrix3d::Identity() + d * bm_[ti]);
  };
  if (edge_smoothed()) {
    std::vector<Eigen::Matrix3d> rot(tet_capacity_, Eigen::Matrix3d::Identity());
    parallel_range(tet_capacity_, [&](std::size_t ti) {
      if (alive_[ti]) rot[ti] = rotation_of_u(ti);
    });
    deviatoric_pass(&u, true, 1.0, nullptr, &rot);  // tsig_ per tet
  }
  parallel_range(tet_capacity_, [&](std::size_t ti) {
    if (!alive_[ti]) return;
    Eigen::Matrix3d s = edge_smoothed() ? tsig_[ti] : tet_stress(std::uint32_t(ti), u, true, rotation_of_u(ti));
    if (nodal_averaged()) s.diagonal().array() += pbar_[ti];
    out[ti] = von_mises_of(s);
  });
  return out;
}

std::vector<double> FemModel::pressure(const Eigen::VectorXd& u) const {
  if (u.size() != rows()) throw InvalidArgument("fem: pressure of a vector of the wrong size");
  std::vector<double> out(tet_capacity_, 0.0);
  if (nodal_averaged()) {
    volumetric_pass(&u, true, 1.0, nullptr);
    for (std::size_t ti = 0; ti < tet_capacity_; ++ti)
      if (alive_[ti]) out[ti] = pbar_[ti];
    return out;
  }
  parallel_range(tet_capacity_, [&](std::size_t ti) {
    if (alive_[ti]) out[ti] = tet_stress(std::uint32_t(ti), u, true, quat_[ti].toRotationMatrix()).trace() / 3;
  });
  return out;
}

void interpolate_added_vertices(const TopologyChange& change, std::size_t vertex_slots, Eigen::VectorXd& field) {
  const Eigen::Index old = field.size();
  if (Eigen::Index(3 * vertex_slots) > old) {
    field.conservativeResize(Eigen::Index(3 * vertex_slots));
    field.tail(field.size() - old).setZero();
  }
  // Added first, then moved, each in order (the TopologyChange contract).
  for (const auto* list : {&change.added_vertices, &change.moved_vertices})
    for (const VertexOrigin& o : *list)
      field.segment<3>(3 * o.vertex.idx()) = interpolate_origin(
          o, Eigen::Vector3d(Eigen::Vector3d::Zero()), [&](VertexId p) { return Eigen::Vector3d(field.segment<3>(3 * p.idx())); });
  for (VertexId v : change.removed_vertices) field.segment<3>(3 * v.idx()).setZero();
}

}  // namespace incise
