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
#include "sim/linalg/simd_clones.h"

namespace incise {

namespace {

// grad N_j of a tet from its inverse rest edge matrix (row j-1 for j=1..3, minus their sum for 0).
inline Eigen::Vector3d shape_gradient(const Eigen::Matrix3d& bm, int j) {
  if (j == 0) return -(bm.row(0) + bm.row(1) + bm.row(2)).transpose();
  return bm.row(j - 1).transpose();
}

inline Eigen::Matrix3d stress_of(const Eigen::Matrix3d& h, double mu, double lambda) {
  const Eigen::Matrix3d eps = 0.5 * (h + h.transpose());
  return 2 * mu * eps + lambda * eps.trace() * Eigen::Matrix3d::Identity();
}

template <class F>
void parallel_range(std::size_t n, F&& f) {
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 512), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t i = r.begin(); i != r.end(); ++i) f(i);
  });
}

// Below this many tets the volumetric passes run serially: four parallel loops per product cost
// more in thread wake-ups than they give (as the kernel's kSerialBelow; docs/solver.md#behind-the-constants).
constexpr std::size_t kVolumetricSerialBelow = 8000;

template <class F>
void for_each_index(std::size_t n, bool serial, F&& f) {
  if (serial)
    for (std::size_t i = 0; i < n; ++i) f(i);
  else
    parallel_range(n, f);
}

// A tet's six edges as pairs of local corners.
constexpr int kTetEdge[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};

std::uint64_t edge_key(std::uint32_t a, std::uint32_t b) {
  return a < b ? (std::uint64_t(a) << 32) | b : (std::uint64_t(b) << 32) | a;
}

}  // namespace

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
    iso_.resize(cap, 0.0);
    if (nodal_averaged()) {
      nvol_.resize(cap, 0.0);
      nkv_.resize(cap, 0.0);
      ptheta_.resize(cap, 0.0);
      ring_mark_.resize(cap, 0);
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
  if (nodal_averaged()) volumetric_block(vi, blk);
  blocks_[vi] = blk;
  diag_.segment<3>(3 * vi) = blk.diagonal();
}

void FemModel::apply(const TopologyChange& change) {
  grow();
  ++work_.updates;
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
    if (nodal_averaged()) nvol_[v.idx()] = nkv_[v.idx()] = 0;
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

void FemModel::register_tet(std::uint32_t ti) {
  for (int k = 0; k < 6; ++k) {
    const std::uint32_t a = verts_[ti][std::size_t(kTetEdge[k][0])], b = verts_[ti][std::size_t(kTetEdge[k][1])];
    auto [it, fresh] = edge_index_.try_emplace(edge_key(a, b), 0u);
    if (fresh) {
      if (free_edges_.empty()) {
        it->second = std::uint32_t(edge_tets_.size());
        edge_tets_.emplace_back();
        edge_vol_.push_back(0);
        edge_mu_.push_back(0);
        edge_lambda_.push_back(0);
        esig_.push_back(Eigen::Matrix3d::Zero());
      } else {
        it->second = free_edges_.back();
        free_edges_.pop_back();
      }
    }
    edge_tets_[it->second].push_back(ti);
    tet_edges_[ti][std::size_t(k)] = it->second;
  }
  registered_[ti] = 1;
}

void FemModel::unregister_tet(std::uint32_t ti) {
  for (int k = 0; k < 6; ++k) {
    const std::uint32_t e = tet_edges_[ti][std::size_t(k)];
    auto& list = edge_tets_[e];
    auto it = std::find(list.begin(), list.end(), ti);
    if (it != list.end()) {
      *it = list.back();
      list.pop_back();
    }
    if (list.empty()) {
      edge_index_.erase(edge_key(verts_[ti][std::size_t(kTetEdge[k][0])], verts_[ti][std::size_t(kTetEdge[k][1])]));
      free_edges_.push_back(e);
      edge_vol_[e] = edge_mu_[e] = edge_lambda_[e] = 0;
    }
  }
  registered_[ti] = 0;
}

void FemModel::edge_moduli(std::uint32_t e) {
  double v = 0, vm = 0, vl = 0;
  for (std::uint32_t t : edge_tets_[e]) {
    v += vol_[t] / 6;
    vm += mu_[t] * vol_[t] / 6;
    vl += lambda_[t] * vol_[t] / 6;
  }
  edge_vol_[e] = v;
  edge_mu_[e] = v > 0 ? vm / v : 0.0;
  edge_lambda_[e] = v > 0 ? vl / v : 0.0;
}

// Pass 1 per tet (V_t / 6) eps_t, pass 2 per edge sigma_e, pass 3 per tet sigma_bar_t and the
// corner forces, gathered per vertex. Each pass is conflict-free; small meshes run serially.
void FemModel::deviatoric_pass(const Eigen::VectorXd* x, bool rotation, double sign, Eigen::VectorXd* y,
                               const std::vector<Eigen::Matrix3d>* rot) const {
  const bool corot = kind_ == FemKind::Corotational;
  const bool serial = tet_capacity_ < kVolumetricSerialBelow;
  auto rotation_of = [&](std::size_t ti) -> Eigen::Matrix3d {
    return rot ? (*rot)[ti] : Eigen::Matrix3d(quat_[ti].toRotationMatrix());
  };
  for_each_index(tet_capacity_, serial, [&](std::size_t ti) {
    if (!alive_[ti]) return;
    Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
    if (x) {
      const auto& v = verts_[ti];
      const Eigen::Vector3d x0 = x->segment<3>(3 * v[0]);
      Eigen::Matrix3d d;
      for (int j = 0; j < 3; ++j) d.col(j) = x->segment<3>(3 * v[j + 1]) - x0;
      h = d * bm_[ti];
    }
    if (corot) {
      const Eigen::Matrix3d r = rotation_of(ti);
      h = r.transpose() * h;
      if (rotation) h += r.transpose() - Eigen::Matrix3d::Identity();  // R^T F - I
    }
    teps_[ti] = (vol_[ti] / 12) * (h + h.transpose());  // (V_t / 6) sym(h)
  });
  for_each_index(edge_tets_.size(), serial, [&](std::size_t e) {
    if (edge_tets_[e].empty() || !(edge_vol_[e] > 0)) return;
    Eigen::Matrix3d eps = Eigen::Matrix3d::Zero();
    for (std::uint32_t t : edge_tets_[e]) eps += teps_[t];
    eps /= edge_vol_[e];
    esig_[e] = 2 * edge_mu_[e] * eps + (edge_lambda_[e] * eps.trace()) * Eigen::Matrix3d::Identity();
  });
  for_each_index(tet_capacity_, serial, [&](std::size_t ti) {
    if (!alive_[ti]) return;
    Eigen::Matrix3d sbar = Eigen::Matrix3d::Zero();
    for (std::uint32_t e : tet_edges_[ti]) sbar += esig_[e];
    sbar /= 6;
    tsig_[ti] = sbar;
    Eigen::Matrix3d p = (sign * vol_[ti]) * sbar;
    if (corot) p = rotation_of(ti) * p;
    const Eigen::Matrix3d g = p * bm_[ti].transpose();
    force_[ti].rightCols<3>() = g;
    force_[ti].col(0) = -g.rowwise().sum();
  });
  if (y) gather(*y, true);
}

Eigen::SparseMatrix<double> FemModel::smoothed_rows() const {
  const Eigen::Index n = rows();
  const bool corot = kind_ == FemKind::Corotational;
  const std::size_t ne = edge_tets_.size();
  // Per edge: the derivative of eps_e by unknown (w, c) is sym(M), M = sum over the edge's tets
  // holding w of (V_t / 6 V_e) (row c of R_t) grad N_w^T. Rows of C (up to 7 per edge):
  // sqrt(2 mu V)(eps_aa - tr / 3), sqrt(4 mu V) eps_ab (a < b), sqrt((lambda + 2 mu / 3) V) tr,
  // so that the squares sum to V sigma : eps.
  std::vector<std::vector<Eigen::Triplet<double>>> trip(ne);
  parallel_range(ne, [&](std::size_t e) {
    if (edge_tets_[e].empty() || !(edge_vol_[e] > 0)) return;
    std::vector<std::pair<std::uint32_t, std::array<Eigen::Matrix3d, 3>>> dom;
    for (std::uint32_t t : edge_tets_[e]) {
      const Eigen::Matrix3d r = corot ? Eigen::Matrix3d(quat_[t].toRotationMatrix()) : Eigen::Matrix3d::Identity();
      const double w = vol_[t] / (6 * edge_vol_[e]);
      for (int j = 0; j < 4; ++j) {
        const std::uint32_t v = verts_[t][std::size_t(j)];
        std::size_t at = 0;
        while (at < dom.size() && dom[at].first != v) ++at;
        if (at == dom.size()) dom.push_back({v, {Eigen::Matrix3d::Zero(), Eigen::Matrix3d::Zero(), Eigen::Matrix3d::Zero()}});
        const Eigen::Vector3d g = shape_gradient(bm_[t], j);
        for (int c = 0; c < 3; ++c) dom[at].second[std::size_t(c)] += w * r.row(c).transpose() * g.transpose();
      }
    }
    const double vol = edge_vol_[e], mu = edge_mu_[e], bulk = edge_lambda_[e] + 2 * mu / 3;
    const double sn = std::sqrt(2 * mu * vol), ss = std::sqrt(4 * mu * vol), sb = bulk > 0 ? std::sqrt(bulk * vol) : 0.0;
    const Eigen::Index row0 = Eigen::Index(7 * e);
    auto& out = trip[e];
    for (const auto& [v, ms] : dom)
      for (int c = 0; c < 3; ++c) {
        const Eigen::Matrix3d m = 0.5 * (ms[std::size_t(c)] + ms[std::size_t(c)].transpose());
        const double tr = m.trace();
        const Eigen::Index col = Eigen::Index(3 * v + std::uint32_t(c));
        for (int a = 0; a < 3; ++a) out.emplace_back(row0 + a, col, sn * (m(a, a) - tr / 3));
        out.emplace_back(row0 + 3, col, ss * m(0, 1));
        out.emplace_back(row0 + 4, col, ss * m(1, 2));
        out.emplace_back(row0 + 5, col, ss * m(0, 2));
        if (sb > 0) out.emplace_back(row0 + 6, col, sb * tr);
      }
  });
  std::vector<Eigen::Triplet<double>> all;
  std::size_t total = 0;
  for (const auto& t : trip) total += t.size();
  all.reserve(total);
  for (auto& t : trip) all.insert(all.end(), t.begin(), t.end());
  Eigen::SparseMatrix<double> c(Eigen::Index(7 * ne), n);
  c.setFromTriplets(all.begin(), all.end());
  return c;  // C: K_smoothed = C^T C
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

void FemModel::gather(Eigen::VectorXd& y, bool accumulate) const {
  const double* f = force_.data()->data();  // Matrix<double,3,4> is column-major: corner j at 3j
  parallel_range(vertex_capacity_, [&](std::size_t vi) {
    Eigen::Vector3d s = Eigen::Vector3d::Zero();
    for (std::uint32_t slot : corner_slots_[vi]) s += Eigen::Map<const Eigen::Vector3d>(f + 3 * std::size_t(slot));
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

// The edge-smoothed K x: a kernel sweep for the tets' strains (and the divergence sums of the
// nodal pressure), a pass per edge, a pass per tet, a kernel sweep for the forces
// (docs/solver.md#edge-smoothed-product). deviatoric_pass does the same with Eigen, for the
// right-hand side and the stresses.
void FemModel::smoothed_product(const Eigen::VectorXd& x, Eigen::VectorXd& y) const {
  const bool serial = tet_capacity_ < kVolumetricSerialBelow, nodal = nodal_averaged();
  const std::size_t ne = edge_tets_.size();
  if (tsym_.size() < 6 * tet_capacity_) tsym_.resize(6 * tet_capacity_), tbar_.resize(6 * tet_capacity_);
  if (esym_.size() < 6 * ne) esym_.resize(6 * ne);
  if (nodal) for_each_index(vertex_capacity_, serial, [&](std::size_t v) { ptheta_[v] = 0; });
  kernel_.strain_sweep(x, tsym_.data(), nodal ? ptheta_.data() : nullptr);
  for_each_index(ne, serial, [&](std::size_t e) {
    double* out = &esym_[6 * e];
    if (edge_tets_[e].empty() || !(edge_vol_[e] > 0)) {
      std::fill(out, out + 6, 0.0);
      return;
    }
    double eps[6] = {0, 0, 0, 0, 0, 0};
    for (std::uint32_t t : edge_tets_[e])
      for (int c = 0; c < 6; ++c) eps[c] += tsym_[6 * std::size_t(t) + c];
    const double inv = 1 / edge_vol_[e], mu2 = 2 * edge_mu_[e] * inv, lt = edge_lambda_[e] * (eps[0] + eps[1] + eps[2]) * inv;
    for (int c = 0; c < 6; ++c) out[c] = mu2 * eps[c] + (c < 3 ? lt : 0.0);
  });
  if (nodal) for_each_index(vertex_capacity_, serial, [&](std::size_t v) { ptheta_[v] = nodal_pressure(v, ptheta_[v]); });
  for_each_index(tet_capacity_, serial, [&](std::size_t ti) {
    if (!alive_[ti]) return;
    double* out = &tbar_[6 * ti];
    std::fill(out, out + 6, 0.0);
    for (std::uint32_t e : tet_edges_[ti])
      for (int c = 0; c < 6; ++c) out[c] += esym_[6 * std::size_t(e) + c];
    for (int c = 0; c < 6; ++c) out[c] /= 6;
  });
  kernel_.stress_forces(tbar_.data(), nodal ? ptheta_.data() : nullptr, y, rows());
}

void FemModel::add_rotation_rhs(Eigen::VectorXd& b) const {
  if (kind_ != FemKind::Corotational) return;
  if (b.size() != rows()) throw InvalidArgument("fem: rotation rhs with a vector of the wrong size");
  if (edge_smoothed())
    deviatoric_pass(nullptr, true, -1.0, &b);  // the smoothed force of the rotations' own strain, negated
  else
    b += rhs_;  // summed per vertex with the diagonal (vertex_block)
  if (nodal_averaged()) {
    // The volumetric force of the rotations' own strain tr(R^T - I), negated (as rhs_'s); O(mesh)
    // here rather than kept per vertex, so that apply() stays local.
    volumetric_pass(nullptr, true, -1.0, &b);
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

void FemModel::update_rotations(const Eigen::VectorXd& u) {
  if (kind_ != FemKind::Corotational) return;
  if (u.size() != rows()) throw InvalidArgument("fem: rotations from a vector of the wrong size");
  if (warm_rotations_) update_rotations_warm(u);
  else update_rotations_exact(u);
  barrier_.update(*this, u);
}

namespace {

constexpr std::size_t kLanes = RotationLanes::kLanes;

// A packet of tets besides F and q (sim/fem/rotation_extraction.h): what F and the corner terms are
// made of, and the results, as a struct of arrays so the loops over lanes vectorize.
struct TetLanes {
  alignas(64) double d[9][kLanes];   // d[3c+j]: component c of u_{j+1} - u_0
  alignas(64) double b[9][kLanes];   // b[3j+m]: B(j, m), row j = grad N_{j+1}
  alignas(64) double vmu[kLanes], vlam[kLanes];  // V mu, V lambda
  alignas(64) double c[12][kLanes];  // out: c[3j+a]: component a of corner j's diagonal term
  alignas(64) double f[12][kLanes];  // out: f[3j+a]: component a of corner j's b_R force
};

// F = I + D B.
INCISE_SIMD_CLONES void deformation_gradients(const TetLanes& __restrict t, RotationLanes& __restrict l) {
  for (std::size_t k = 0; k < kLanes; ++k)
    for (int c = 0; c < 3; ++c)
      for (int m = 0; m < 3; ++m)
        l.f[3 * c + m][k] = (c == m ? 1.0 : 0.0) + t.d[3 * c][k] * t.b[m][k] + t.d[3 * c + 1][k] * t.b[3 + m][k] +
                            t.d[3 * c + 2][k] * t.b[6 + m][k];
}

// Corner j's terms (vertex_block() has the same for one corner): the diagonal's
// sqrt(V (mu + lambda)) R grad N_j, and b_R's force P grad N_j with
// P = V R sigma(I - R^T) = V R (2 mu (I - sym R) + lambda (3 - tr R) I).
INCISE_SIMD_CLONES void corner_terms(const RotationLanes& __restrict l, TetLanes& __restrict t) {
  for (std::size_t k = 0; k < kLanes; ++k) {
    const double w = l.q[0][k], x = l.q[1][k], y = l.q[2][k], z = l.q[3][k];
    const double x2 = x + x, y2 = y + y, z2 = z + z;
    const double xx = x * x2, yy = y * y2, zz = z * z2, xy = x * y2, xz = x * z2, yz = y * z2;
    const double wx = w * x2, wy = w * y2, wz = w * z2;
    const double r[9] = {1 - (yy + zz), xy - wz, xz + wy, xy + wz, 1 - (xx + zz), yz - wx, xz - wy, yz + wx, 1 - (xx + yy)};
    const double s = std::sqrt(t.vmu[k] + t.vlam[k]);
    const double mu = t.vmu[k], diag = 2 * mu + t.vlam[k] * (3 - (r[0] + r[4] + r[8]));
    double sig[9], pm[9];
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) sig[3 * a + b] = -mu * (r[3 * a + b] + r[3 * b + a]) + (a == b ? diag : 0.0);
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) pm[3 * a + b] = r[3 * a] * sig[b] + r[3 * a + 1] * sig[3 + b] + r[3 * a + 2] * sig[6 + b];
    for (int a = 0; a < 3; ++a) {
      double sum = 0;
      for (int j = 1; j < 4; ++j) {
        const double fj = pm[3 * a] * t.b[3 * (j - 1)][k] + pm[3 * a + 1] * t.b[3 * (j - 1) + 1][k] +
                          pm[3 * a + 2] * t.b[3 * (j - 1) + 2][k];
        t.f[3 * j + a][k] = fj;
        sum += fj;
      }
      t.f[a][k] = -sum;
    }
    for (int a = 0; a < 3; ++a) {
      double sum = 0;
      for (int j = 1; j < 4; ++j) {
        const double cj = s * (r[3 * a] * t.b[3 * (j - 1)][k] + r[3 * a + 1] * t.b[3 * (j - 1) + 1][k] +
                               r[3 * a + 2] * t.b[3 * (j - 1) + 2][k]);
        t.c[3 * j + a][k] = cj;
        sum += cj;
      }
      t.c[a][k] = -sum;  // grad N_0 = -(grad N_1 + grad N_2 + grad N_3)
    }
  }
}

// A packet's rotations from its F (lanes filled by the caller), and its corner terms when
// `corners`: warm-started Newton steps from l.q (vectorized across the packet) unless `exact`,
// the exact decomposition for live lanes that did not converge (or all of them); counts those
// in `polar`.
void rotate_packet(RotationLanes& l, TetLanes& t, const bool* live, bool exact, const RotationRefinement& opt,
                   bool corners, int& steps, std::size_t& polar) {
  deformation_gradients(t, l);
  if (!exact) steps = std::max(steps, refine_rotations(l, opt.max_steps, opt.tolerance));
  for (std::size_t k = 0; k < kLanes; ++k) {
    if (!live[k] || (!exact && l.step[k] <= opt.tolerance)) continue;
    Eigen::Matrix3d f;
    for (int i = 0; i < 9; ++i) f(i / 3, i % 3) = l.f[i][k];
    const Eigen::Quaterniond q = Eigen::Quaterniond(polar_rotation(f)).normalized();
    l.q[0][k] = q.w(), l.q[1][k] = q.x(), l.q[2][k] = q.y(), l.q[3][k] = q.z();
    ++polar;
  }
  if (corners) corner_terms(l, t);
}

// Lane k's edge differences u_{j+1} - u_0 from u; false (and F = I, R = I: what a NaN
// displacement gets) where they are not finite.
inline bool gather_edges(const double* up, const std::uint32_t* v, std::size_t stride, std::size_t k, TetLanes& t) {
  const double* u0 = up + 3 * std::size_t(v[0]);
  double check = 0;
  for (int j = 0; j < 3; ++j) {
    const double* uj = up + 3 * std::size_t(v[std::size_t(j + 1) * stride]);
    for (int c = 0; c < 3; ++c) check += t.d[3 * c + j][k] = uj[c] - u0[c];
  }
  if (std::isfinite(check)) return true;
  for (int i = 0; i < 9; ++i) t.d[i][k] = 0;
  return false;
}

// Most Newton steps and exact decompositions over the threads of a pass.
struct PassStats {
  std::atomic<std::size_t> polar{0};
  std::atomic<int> steps{0};
  void add(std::size_t p, int s) {
    if (p) polar += p;
    int prev = steps.load();
    while (prev < s && !steps.compare_exchange_weak(prev, s)) {
    }
  }
};

}  // namespace

void FemModel::update_rotations_exact(const Eigen::VectorXd& u) { relinearize(u, true); }
void FemModel::update_rotations_warm(const Eigen::VectorXd& u) { relinearize(u, false); }

// The whole mesh in one pass over the kernel's packets (slabs three apart in parallel, as its
// product): per packet the rotations, written back to the kernel and to quat_, and the corner
// terms scattered straight into the vertices' diagonal blocks and b_R. No per-corner storage and
// no gather pass: the blocks stay in cache while a slab sweeps its vertices, where the per-vertex
// gather read 192 bytes a tet back from memory (its half of the relinearization's time).
void FemModel::relinearize(const Eigen::VectorXd& u, bool exact) {
  // Each vertex from its rotation-free part; its corners add the rest.
  parallel_range(vertex_capacity_, [&](std::size_t v) {
    blocks_[v] = iso_[v] * Eigen::Matrix3d::Identity();
    rhs_.segment<3>(3 * v).setZero();
  });
  PassStats stats;
  const double* up = u.data();
  static_assert(sizeof(Eigen::Matrix3d) == 9 * sizeof(double), "blocks_ is contiguous 3x3 blocks");
  double* const bp = reinterpret_cast<double*>(blocks_.data());  // raw: no aliasing reloads
  double* const rp = rhs_.data();
  kernel_.for_each_packet([&](const StiffnessKernel::Packet& p, StiffnessKernel::Rotations* rot,
                              const std::uint32_t* tets, std::size_t n) {
    static_assert(StiffnessKernel::kLanes == kLanes && sizeof(TetLanes::b) == sizeof(StiffnessKernel::Packet::b),
                  "one packet of the kernel is one packet of rotations");
    RotationLanes l;
    TetLanes t;
    bool live[kLanes];
    // The packet's layout is the lanes' (zeros in unused lanes): whole-array copies.
    std::memcpy(t.b, p.b, sizeof t.b);
    std::memcpy(t.vmu, p.mu, sizeof t.vmu);
    std::memcpy(t.vlam, p.lam, sizeof t.vlam);
    for (std::size_t k = 0; k < kLanes; ++k) {
      live[k] = k < n;
      if (live[k] && gather_edges(up, &p.v[0][k], kLanes, k, t)) {
        for (int i = 0; i < 4; ++i) l.q[i][k] = rot->q[i][k];
      } else {
        if (!live[k])
          for (int i = 0; i < 9; ++i) t.d[i][k] = 0;
        l.q[0][k] = 1, l.q[1][k] = l.q[2][k] = l.q[3][k] = 0;
      }
    }
    int steps = 0;
    std::size_t polar = 0;
    rotate_packet(l, t, live, exact, refinement_, true, steps, polar);
    for (std::size_t k = 0; k < n; ++k) {
      for (int i = 0; i < 4; ++i) rot->q[i][k] = l.q[i][k];
      quat_[tets[k]] = Eigen::Quaterniond(l.q[0][k], l.q[1][k], l.q[2][k], l.q[3][k]);
    }
    // Corner by corner: consecutive tets share vertices (as the product's scatter).
    for (int j = 0; j < 4; ++j)
      for (std::size_t k = 0; k < n; ++k) {
        const std::size_t v = p.v[j][k];
        const double c0 = t.c[3 * j][k], c1 = t.c[3 * j + 1][k], c2 = t.c[3 * j + 2][k];
        const double xy = c0 * c1, xz = c0 * c2, yz = c1 * c2;
        double* b = bp + 9 * v;
        b[0] += c0 * c0, b[1] += xy, b[2] += xz;
        b[3] += xy, b[4] += c1 * c1, b[5] += yz;
        b[6] += xz, b[7] += yz, b[8] += c2 * c2;
        double* r = rp + 3 * v;
        r[0] += t.f[3 * j][k], r[1] += t.f[3 * j + 1][k], r[2] += t.f[3 * j + 2][k];
      }
    stats.add(polar, steps);
  });
  parallel_range(vertex_capacity_, [&](std::size_t v) {
    if (nodal_averaged()) volumetric_block(std::uint32_t(v), blocks_[v]);
    diag_.segment<3>(3 * v) = blocks_[v].diagonal();
  });
  rotation_stats_ = {mesh_->num_tets(), stats.polar.load(), stats.steps.load()};
}

// Packets of kLanes consecutive tet ids: the unit of partial updates.
std::size_t FemModel::rotation_packets() const { return (tet_capacity_ + kLanes - 1) / kLanes; }

void FemModel::update_rotations_partial(const Eigen::VectorXd& u, std::size_t first, std::size_t count) {
  if (kind_ != FemKind::Corotational) return;
  if (u.size() != rows()) throw InvalidArgument("fem: rotations from a vector of the wrong size");
  const std::size_t packets = rotation_packets();
  if (packets == 0) return;
  if (count >= packets) {
    update_rotations(u);
    return;
  }
  first %= packets;
  const std::size_t end = first + count;
  // Wrapping past the last packet: two ranges; the stats add up.
  update_rotation_packets(u, !warm_rotations_, first, std::min(end, packets));
  RotationStats stats = rotation_stats_;
  if (end > packets) {
    update_rotation_packets(u, !warm_rotations_, 0, end - packets);
    stats.exact += rotation_stats_.exact;
    stats.max_steps = std::max(stats.max_steps, rotation_stats_.max_steps);
  }
  // The diagonal blocks of the vertices of those tets (their corner terms changed). Nodal-
  // averaged blocks reach the 2-ring: every block then.
  std::vector<std::uint32_t> verts;
  auto mark = [&](std::size_t p0, std::size_t p1) {
    for (std::size_t ti = p0 * kLanes; ti < std::min(p1 * kLanes, tet_capacity_); ++ti)
      if (alive_[ti])
        for (std::uint32_t v : verts_[ti])
          if (!vertex_mark_[v]) {
            vertex_mark_[v] = 1;
            verts.push_back(v);
          }
  };
  if (nodal_averaged()) {
    parallel_range(vertex_capacity_, [&](std::size_t v) { vertex_block(std::uint32_t(v)); });
  } else {
    vertex_mark_.resize(vertex_capacity_, 0);
    mark(first, std::min(end, packets));
    if (end > packets) mark(0, end - packets);
    parallel_range(verts.size(), [&](std::size_t i) { vertex_block(verts[i]); });
    for (std::uint32_t v : verts) vertex_mark_[v] = 0;
  }
  rotation_stats_ = stats;
  rotation_stats_.tets = std::min(count * kLanes, mesh_->num_tets());
  barrier_.update(*this, u);
}

// Packets [begin, end), in parallel: the rotations only (the caller refreshes the blocks of their
// vertices).
void FemModel::update_rotation_packets(const Eigen::VectorXd& u, bool exact, std::size_t begin, std::size_t end) {
  PassStats stats;
  const double* up = u.data();
  tbb::parallel_for(tbb::blocked_range<std::size_t>(begin, end, 64), [&](const tbb::blocked_range<std::size_t>& range) {
    RotationLanes l;
    TetLanes t;
    bool live[kLanes];
    std::size_t polar = 0;
    int steps = 0;
    for (std::size_t p = range.begin(); p != range.end(); ++p) {
      for (std::size_t k = 0; k < kLanes; ++k) {
        const std::size_t ti = p * kLanes + k;
        live[k] = ti < tet_capacity_ && alive_[ti];
        Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
        if (live[k]) {
          const Eigen::Matrix3d& bm = bm_[ti];
          for (int i = 0; i < 9; ++i) t.b[i][k] = bm(i / 3, i % 3);
          t.vmu[k] = vol_[ti] * mu_[ti];
          t.vlam[k] = vol_[ti] * lambda_[ti];
          if (gather_edges(up, verts_[ti].data(), 1, k, t)) q = quat_[ti];
        } else {
          for (int i = 0; i < 9; ++i) t.d[i][k] = t.b[i][k] = 0;
          t.vmu[k] = t.vlam[k] = 0;
        }
        l.q[0][k] = q.w(), l.q[1][k] = q.x(), l.q[2][k] = q.y(), l.q[3][k] = q.z();
      }
      // No corner terms: the caller recomputes the touched vertices from their tets' rotations.
      rotate_packet(l, t, live, exact, refinement_, false, steps, polar);
      for (std::size_t k = 0; k < kLanes; ++k) {
        if (!live[k]) continue;
        const std::uint32_t ti = std::uint32_t(p * kLanes + k);
        const Eigen::Quaterniond q(l.q[0][k], l.q[1][k], l.q[2][k], l.q[3][k]);
        quat_[ti] = q;
        kernel_.set_rotation(ti, q);  // no two threads write the same slot
      }
    }
    stats.add(polar, steps);
  });
  rotation_stats_ = {end - begin >= rotation_packets() ? mesh_->num_tets() : (end - begin) * kLanes, stats.polar.load(),
                     stats.steps.load()};
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
