// FemModel, corotational: the per-tet rotations (polar decomposition of F = I + H_t(u)), exact or
// as Newton steps from the last frame, whole or a packet range at a time (docs/solver.md#the-model-in-equations).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include <Eigen/SparseCore>

#include <atomic>
#include <cstring>
#include <Eigen/LU>
#include "sim/linalg/simd_clones.h"
#include "mesh/errors.h"
#include "sim/fem/fem_model.h"
#include "sim/fem/fem_model_detail.h"

namespace incise {

using namespace fem_detail;

void FemModel::update_rotations(const Eigen::VectorXd& u) {
  if (kind_ != FemKind::Corotational) return;
  if (u.size() != rows()) throw InvalidArgument("fem: rotations from a vector of the wrong size");
  if (warm_rotations_) update_rotations_warm(u);
  else update_rotations_exact(u);
  vrhs_valid_ = false;  // every rotation changed: the next rhs sums in full
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
    double r[9];
    rotation_from_quaternion(w, x, y, z, r);
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
    // The volume gradients are the corner terms rescaled: c_j = sqrt(V (mu + lambda)) R grad N_j.
    if (nodal_averaged())
      for (std::size_t k = 0; k < n; ++k) {
        const double s = std::sqrt(t.vmu[k] + t.vlam[k]);
        if (!(s > 0)) {
          volume_gradients(tets[k]);
          continue;
        }
        const double scale = vol_[tets[k]] / (4 * s);
        Eigen::Vector3d* h = &vgrad_[4 * std::size_t(tets[k])];
        for (int j = 0; j < 4; ++j) h[j] = scale * Eigen::Vector3d(t.c[3 * j][k], t.c[3 * j + 1][k], t.c[3 * j + 2][k]);
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
    if (edge_smoothed()) smoothed_block(std::uint32_t(v), blocks_[v]);
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
  // The diagonal blocks of the vertices of those tets (their corner terms changed). A nodal-
  // averaged block reads the gradients of the tets around its own vertex only (and the ring's
  // V_a, which rotations leave alone), so the same vertices, though K reaches the 2-ring.
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
  vertex_mark_.resize(vertex_capacity_, 0);
  mark(first, std::min(end, packets));
  if (end > packets) mark(0, end - packets);
  parallel_range(verts.size(), [&](std::size_t i) { vertex_block(verts[i]); });
  for (std::uint32_t v : verts) vertex_mark_[v] = 0;
  work_.rotation_blocks += verts.size();
  if (nodal_averaged() && vrhs_valid_) {
    std::vector<std::uint32_t> tets;
    auto list = [&](std::size_t p0, std::size_t p1) {
      for (std::size_t ti = p0 * kLanes; ti < std::min(p1 * kLanes, tet_capacity_); ++ti)
        if (alive_[ti]) tets.push_back(std::uint32_t(ti));
    };
    list(first, std::min(end, packets));
    if (end > packets) list(0, end - packets);
    refresh_rotation_volumetric(tets, verts);
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
        if (nodal_averaged()) volume_gradients(ti);
      }
    }
    stats.add(polar, steps);
  });
  rotation_stats_ = {end - begin >= rotation_packets() ? mesh_->num_tets() : (end - begin) * kLanes, stats.polar.load(),
                     stats.steps.load()};
}

}  // namespace incise
