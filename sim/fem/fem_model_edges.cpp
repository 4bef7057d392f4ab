// FemModel, edge-smoothed: the edge table kept by apply() (register / unregister a tet, the edge
// domains' moduli) and the smoothed products (docs/solver.md#edge-smoothed-product).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include <Eigen/SparseCore>

#include "mesh/errors.h"
#include "sim/fem/fem_model.h"
#include "sim/fem/fem_model_detail.h"

#if defined(__GNUC__) && defined(__x86_64__)
#include <immintrin.h>
#define INCISE_EDGES_AVX2 1
#endif

namespace incise {

using namespace fem_detail;

namespace {

// The smoothed product's two passes between its sweeps, over a range: per edge its tets'
// (V_t / 6) sym strains summed into its stress, per tet the mean of its six edges' stresses.
// Six numbers a tet or edge; the AVX2 versions add them as a 4- and a 2-vector.
void edge_stresses(std::size_t begin, std::size_t end, const EdgeTetLists& edge_tets,
                   const double* tsym, const double* vol, const double* mu, const double* lam, double* esym) {
  for (std::size_t e = begin; e < end; ++e) {
    double* out = esym + 6 * e;
    if (edge_tets.empty(e) || !(vol[e] > 0)) {
      std::fill(out, out + 6, 0.0);
      continue;
    }
    double eps[6] = {0, 0, 0, 0, 0, 0};
    for (std::uint32_t t : edge_tets[e])
      for (int c = 0; c < 6; ++c) eps[c] += tsym[6 * std::size_t(t) + c];
    const double inv = 1 / vol[e], mu2 = 2 * mu[e] * inv, lt = lam[e] * (eps[0] + eps[1] + eps[2]) * inv;
    for (int c = 0; c < 6; ++c) out[c] = mu2 * eps[c] + (c < 3 ? lt : 0.0);
  }
}

void tet_stresses(std::size_t begin, std::size_t end, const std::uint8_t* alive,
                  const std::array<std::uint32_t, 6>* tet_edges, const double* esym, double* tbar) {
  for (std::size_t ti = begin; ti < end; ++ti) {
    if (!alive[ti]) continue;
    double* out = tbar + 6 * ti;
    std::fill(out, out + 6, 0.0);
    for (std::uint32_t e : tet_edges[ti])
      for (int c = 0; c < 6; ++c) out[c] += esym[6 * std::size_t(e) + c];
    for (int c = 0; c < 6; ++c) out[c] /= 6;
  }
}

#ifdef INCISE_EDGES_AVX2
__attribute__((target("avx2,fma"))) void edge_stresses_avx2(std::size_t begin, std::size_t end,
                                                            const EdgeTetLists& edge_tets,
                                                            const double* tsym, const double* vol, const double* mu,
                                                            const double* lam, double* esym) {
  for (std::size_t e = begin; e < end; ++e) {
    double* out = esym + 6 * e;
    const std::span<const std::uint32_t> list = edge_tets[e];
    if (list.empty() || !(vol[e] > 0)) {
      _mm256_storeu_pd(out, _mm256_setzero_pd());
      _mm_storeu_pd(out + 4, _mm_setzero_pd());
      continue;
    }
    __m256d a = _mm256_setzero_pd();
    __m128d b = _mm_setzero_pd();
    for (std::uint32_t t : list) {
      const double* p = tsym + 6 * std::size_t(t);
      a = _mm256_add_pd(a, _mm256_loadu_pd(p));
      b = _mm_add_pd(b, _mm_loadu_pd(p + 4));
    }
    alignas(32) double d[4];
    _mm256_store_pd(d, a);
    const double inv = 1 / vol[e], lt = lam[e] * (d[0] + d[1] + d[2]) * inv;
    const __m256d mu2 = _mm256_set1_pd(2 * mu[e] * inv);
    _mm256_storeu_pd(out, _mm256_fmadd_pd(mu2, a, _mm256_set_pd(0.0, lt, lt, lt)));
    _mm_storeu_pd(out + 4, _mm_mul_pd(_mm256_castpd256_pd128(mu2), b));
  }
}

__attribute__((target("avx2,fma"))) void tet_stresses_avx2(std::size_t begin, std::size_t end,
                                                           const std::uint8_t* alive,
                                                           const std::array<std::uint32_t, 6>* tet_edges,
                                                           const double* esym, double* tbar) {
  const __m256d sixth = _mm256_set1_pd(1.0 / 6);
  for (std::size_t ti = begin; ti < end; ++ti) {
    if (!alive[ti]) continue;
    __m256d a = _mm256_setzero_pd();
    __m128d b = _mm_setzero_pd();
    for (std::uint32_t e : tet_edges[ti]) {
      const double* p = esym + 6 * std::size_t(e);
      a = _mm256_add_pd(a, _mm256_loadu_pd(p));
      b = _mm_add_pd(b, _mm_loadu_pd(p + 4));
    }
    double* out = tbar + 6 * ti;
    _mm256_storeu_pd(out, _mm256_mul_pd(a, sixth));
    _mm_storeu_pd(out + 4, _mm_mul_pd(b, _mm256_castpd256_pd128(sixth)));
  }
}
#endif

}  // namespace

void FemModel::register_tet(std::uint32_t ti) {
  for (int k = 0; k < 6; ++k) {
    const std::uint32_t a = verts_[ti][std::size_t(kTetEdge[k][0])], b = verts_[ti][std::size_t(kTetEdge[k][1])];
    auto [it, fresh] = edge_index_.try_emplace(edge_key(a, b), 0u);
    if (fresh) {
      if (free_edges_.empty()) {
        it->second = std::uint32_t(edge_tets_.size());
        edge_tets_.add_edge();
        edge_vol_.push_back(0);
        edge_mu_.push_back(0);
        edge_lambda_.push_back(0);
        esig_.push_back(Eigen::Matrix3d::Zero());
      } else {
        it->second = free_edges_.back();
        free_edges_.pop_back();
      }
    }
    edge_tets_.push(it->second, ti);
    tet_edges_[ti][std::size_t(k)] = it->second;
  }
  registered_[ti] = 1;
}

void FemModel::unregister_tet(std::uint32_t ti) {
  for (int k = 0; k < 6; ++k) {
    const std::uint32_t e = tet_edges_[ti][std::size_t(k)];
    edge_tets_.remove(e, ti);
    if (edge_tets_.empty(e)) {
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

// At rest, the block sums over the edges e of v's tets (v lies in each one's domain) V_e (mu_e
// |G|^2 I + (mu_e + lambda_e) G G^T), G = sum over the tets around e holding v of (V_t / 6 V_e)
// grad N_v: the unit displacement of v along c strains edge e by sym(e_c G^T). Kept per vertex
// and recomputed with its standard block (after edits: the touched vertices' 1-ring).
void FemModel::smoothed_rest_block(std::uint32_t v) {
  thread_local std::vector<std::uint32_t> pos;  // by edge id: position in `edges`, or none
  thread_local std::vector<std::uint32_t> edges;
  thread_local std::vector<Eigen::Vector3d> sums;
  constexpr std::uint32_t kNone = 0xffffffffu;
  if (pos.size() < edge_tets_.size()) pos.resize(edge_tets_.size(), kNone);
  edges.clear();
  sums.clear();
  for (std::uint32_t slot : corner_slots_[v]) {
    const std::uint32_t ti = slot / 4;
    if (!alive_[ti] || !registered_[ti]) continue;
    const Eigen::Vector3d h = (vol_[ti] / 6) * shape_gradient(bm_[ti], int(slot % 4));
    for (std::uint32_t e : tet_edges_[ti]) {
      if (pos[e] == kNone) {
        pos[e] = std::uint32_t(edges.size());
        edges.push_back(e);
        sums.push_back(Eigen::Vector3d::Zero());
      }
      sums[pos[e]] += h;
    }
  }
  Eigen::Matrix3d& blk = sblock_[v];
  blk.setZero();
  for (std::size_t i = 0; i < edges.size(); ++i) {
    const std::uint32_t e = edges[i];
    pos[e] = kNone;
    if (!(edge_vol_[e] > 0)) continue;
    const Eigen::Vector3d g = sums[i] / edge_vol_[e];
    blk.diagonal().array() += edge_vol_[e] * edge_mu_[e] * g.squaredNorm();
    blk.noalias() += (edge_vol_[e] * (edge_mu_[e] + edge_lambda_[e])) * g * g.transpose();
  }
}

// Rotated: R sblock R^T, R the normalized mean of v's tets' rotations (sign-aligned quaternions).
// Exact where the tets around each of v's edges share one rotation (a rigid turn, and always
// for Linear); elsewhere a preconditioner's estimate that costs a pass over v's corners, not
// the product's work (docs/solver.md#edge-smoothed-product).
void FemModel::smoothed_block(std::uint32_t v, Eigen::Matrix3d& blk) const {
  if (kind_ != FemKind::Corotational || corner_slots_[v].empty()) {
    blk = sblock_[v];
    return;
  }
  const Eigen::Quaterniond& q0 = quat_[corner_slots_[v].front() / 4];
  Eigen::Vector4d sum = Eigen::Vector4d::Zero();
  for (std::uint32_t slot : corner_slots_[v]) {
    const Eigen::Vector4d q = quat_[slot / 4].coeffs();
    sum += q.dot(q0.coeffs()) < 0 ? Eigen::Vector4d(-q) : q;
  }
  const Eigen::Matrix3d r = Eigen::Quaterniond(sum).normalized().toRotationMatrix();
  blk.noalias() = r * sblock_[v] * r.transpose();
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
    if (edge_tets_.empty(e) || !(edge_vol_[e] > 0)) return;
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
    if (edge_tets_.empty(e) || !(edge_vol_[e] > 0)) return;
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
  const bool simd = kernel_.simd();
  for_each_chunk(ne, serial, [&](std::size_t b, std::size_t e) {
#ifdef INCISE_EDGES_AVX2
    if (simd) {
      edge_stresses_avx2(b, e, edge_tets_, tsym_.data(), edge_vol_.data(), edge_mu_.data(), edge_lambda_.data(),
                         esym_.data());
      return;
    }
#endif
    edge_stresses(b, e, edge_tets_, tsym_.data(), edge_vol_.data(), edge_mu_.data(), edge_lambda_.data(), esym_.data());
  });
  if (nodal) for_each_index(vertex_capacity_, serial, [&](std::size_t v) { ptheta_[v] = nodal_pressure(v, ptheta_[v]); });
  for_each_chunk(tet_capacity_, serial, [&](std::size_t b, std::size_t e) {
#ifdef INCISE_EDGES_AVX2
    if (simd) {
      tet_stresses_avx2(b, e, alive_.data(), tet_edges_.data(), esym_.data(), tbar_.data());
      return;
    }
#endif
    tet_stresses(b, e, alive_.data(), tet_edges_.data(), esym_.data(), tbar_.data());
  });
  kernel_.stress_forces(tbar_.data(), nodal ? ptheta_.data() : nullptr, y, rows());
}

}  // namespace incise
