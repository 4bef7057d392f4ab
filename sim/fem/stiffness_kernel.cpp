#include "sim/fem/stiffness_kernel.h"

#include <algorithm>
#include <cstring>
#include <limits>

#include <Eigen/Geometry>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "mesh/rest_bounds.h"
#include "sim/fem/rotation_extraction.h"
#include "sim/linalg/simd_clones.h"

#if defined(__GNUC__) && defined(__x86_64__)
#include <immintrin.h>
#define INCISE_KERNEL_AVX2 1
#endif

namespace incise {

namespace {

constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
constexpr std::size_t kSerialBelow = 8000;  // tets: below this, threads cost more than they give
constexpr std::size_t kLanes = StiffnessKernel::kLanes;

// Per packet scratch: gathered edge differences in, corner forces out.
struct Scratch {
  alignas(64) double d[9][kLanes];   // d[3c+j][k]: component c of x_{j+1} - x_0 of lane k
  alignas(64) double f[12][kLanes];  // f[3j+c][k]: component c of the force on corner j of lane k
};

// Corner forces of one packet: H = D B, (corotational: H = R^T H), P = V sigma(H),
// (corotational: P = R P), force on corner j+1 = P grad N_{j+1}, corner 0 the negated sum.
template <bool Corot>
INCISE_SIMD_CLONES void packet_forces(const StiffnessKernel::Packet& __restrict p,
                                      const StiffnessKernel::Rotations* __restrict rot, Scratch& __restrict sc,
                                      const double* __restrict pressure) {
  for (std::size_t k = 0; k < kLanes; ++k) {
    double r[9];
    if constexpr (Corot) rotation_from_quaternion(rot->q[0][k], rot->q[1][k], rot->q[2][k], rot->q[3][k], r);
    double h[9];
    for (int c = 0; c < 3; ++c)
      for (int m = 0; m < 3; ++m)
        h[3 * c + m] = sc.d[3 * c][k] * p.b[m][k] + sc.d[3 * c + 1][k] * p.b[3 + m][k] + sc.d[3 * c + 2][k] * p.b[6 + m][k];
    if constexpr (Corot) {
      double t[9];
      for (int c = 0; c < 3; ++c)
        for (int m = 0; m < 3; ++m)
          t[3 * c + m] = r[c] * h[m] + r[3 + c] * h[3 + m] + r[6 + c] * h[6 + m];
      for (int i = 0; i < 9; ++i) h[i] = t[i];
    }
    const double mu = p.mu[k], lt = p.lam[k] * (h[0] + h[4] + h[8]);
    double s[9];
    for (int c = 0; c < 3; ++c)
      for (int m = 0; m < 3; ++m) s[3 * c + m] = mu * (h[3 * c + m] + h[3 * m + c]);
    double diag = lt;
    if (pressure)
      diag += p.vol[k] * 0.25 * (pressure[p.v[0][k]] + pressure[p.v[1][k]] + pressure[p.v[2][k]] + pressure[p.v[3][k]]);
    s[0] += diag;
    s[4] += diag;
    s[8] += diag;
    if constexpr (Corot) {
      double t[9];
      for (int c = 0; c < 3; ++c)
        for (int m = 0; m < 3; ++m)
          t[3 * c + m] = r[3 * c] * s[m] + r[3 * c + 1] * s[3 + m] + r[3 * c + 2] * s[6 + m];
      for (int i = 0; i < 9; ++i) s[i] = t[i];
    }
    for (int c = 0; c < 3; ++c) {
      double sum = 0;
      for (int j = 0; j < 3; ++j) {
        const double fj = s[3 * c] * p.b[3 * j][k] + s[3 * c + 1] * p.b[3 * j + 1][k] + s[3 * c + 2] * p.b[3 * j + 2][k];
        sc.f[3 * (j + 1) + c][k] = fj;
        sum += fj;
      }
      sc.f[c][k] = -sum;
    }
  }
}


#ifdef INCISE_KERNEL_AVX2
// The AVX2 path: x and y padded to 4 doubles per vertex, so a corner's gather is one vector
// load and its scatter one vector read-modify-write (instead of three scalar ones each; the
// scalar gather and scatter were about three quarters of the product's time). Four tets at a
// time: a 4x4 transpose turns four corners' (x, y, z, 0) into x, y and z across the tets and
// back; the arithmetic is the same as packet_forces.
__attribute__((target("avx2,fma"))) inline void transpose_in(const double* x, const std::uint32_t* v, __m256d& cx,
                                                             __m256d& cy, __m256d& cz) {
  // x itself (3 per vertex): a masked load reads x, y, z and never the next vertex's entry
  // (nor past the end of x), so x needs no padded copy.
  const __m256i m = _mm256_set_epi64x(0, -1, -1, -1);
  const __m256d r0 = _mm256_maskload_pd(x + 3 * std::size_t(v[0]), m), r1 = _mm256_maskload_pd(x + 3 * std::size_t(v[1]), m);
  const __m256d r2 = _mm256_maskload_pd(x + 3 * std::size_t(v[2]), m), r3 = _mm256_maskload_pd(x + 3 * std::size_t(v[3]), m);
  const __m256d t0 = _mm256_unpacklo_pd(r0, r1), t1 = _mm256_unpackhi_pd(r0, r1);
  const __m256d t2 = _mm256_unpacklo_pd(r2, r3), t3 = _mm256_unpackhi_pd(r2, r3);
  cx = _mm256_permute2f128_pd(t0, t2, 0x20);
  cy = _mm256_permute2f128_pd(t1, t3, 0x20);
  cz = _mm256_permute2f128_pd(t0, t2, 0x31);
}

// Adds corner forces (fx, fy, fz across lanes) into y for the first `n` (<= 4) lanes, in lane
// order (lanes may share a vertex: each read-modify-write sees the previous one).
__attribute__((target("avx2,fma"))) inline void transpose_out(double* y, const std::uint32_t* v, std::size_t n,
                                                              __m256d fx, __m256d fy, __m256d fz) {
  const __m256d zero = _mm256_setzero_pd();
  const __m256d t0 = _mm256_unpacklo_pd(fx, fy), t1 = _mm256_unpackhi_pd(fx, fy);
  const __m256d t2 = _mm256_unpacklo_pd(fz, zero), t3 = _mm256_unpackhi_pd(fz, zero);
  const __m256d o[4] = {_mm256_permute2f128_pd(t0, t2, 0x20), _mm256_permute2f128_pd(t1, t3, 0x20),
                        _mm256_permute2f128_pd(t0, t2, 0x31), _mm256_permute2f128_pd(t1, t3, 0x31)};
  for (std::size_t k = 0; k < n; ++k) {
    double* yk = y + 4 * std::size_t(v[k]);
    _mm256_storeu_pd(yk, _mm256_add_pd(_mm256_loadu_pd(yk), o[k]));
  }
}

// base[idx[k]] for the four lanes (the masked gather with a zero source: the plain one leaves
// GCC warning about its undefined source register).
__attribute__((target("avx2,fma"))) inline __m256d gather4(const double* base, __m128i idx) {
  return _mm256_mask_i32gather_pd(_mm256_setzero_pd(), base, idx, _mm256_castsi256_pd(_mm256_set1_epi64x(-1)), 8);
}

// The rotations of lanes base..base+3 (row-major, r[3c+m]) from their quaternions.
__attribute__((target("avx2,fma"))) inline void rotation_avx2(const StiffnessKernel::Rotations& rot, std::size_t base,
                                                              __m256d* r) {
  const auto& q = rot.q;
  const __m256d w = _mm256_load_pd(&q[0][base]), qx = _mm256_load_pd(&q[1][base]);
  const __m256d qy = _mm256_load_pd(&q[2][base]), qz = _mm256_load_pd(&q[3][base]);
  const __m256d x2 = _mm256_add_pd(qx, qx), y2 = _mm256_add_pd(qy, qy), z2 = _mm256_add_pd(qz, qz);
  const __m256d xx = _mm256_mul_pd(qx, x2), yy = _mm256_mul_pd(qy, y2), zz = _mm256_mul_pd(qz, z2);
  const __m256d xy = _mm256_mul_pd(qx, y2), xz = _mm256_mul_pd(qx, z2), yz = _mm256_mul_pd(qy, z2);
  const __m256d wx = _mm256_mul_pd(w, x2), wy = _mm256_mul_pd(w, y2), wz = _mm256_mul_pd(w, z2);
  const __m256d one = _mm256_set1_pd(1.0);
  r[0] = _mm256_sub_pd(one, _mm256_add_pd(yy, zz));
  r[1] = _mm256_sub_pd(xy, wz);
  r[2] = _mm256_add_pd(xz, wy);
  r[3] = _mm256_add_pd(xy, wz);
  r[4] = _mm256_sub_pd(one, _mm256_add_pd(xx, zz));
  r[5] = _mm256_sub_pd(yz, wx);
  r[6] = _mm256_sub_pd(xz, wy);
  r[7] = _mm256_add_pd(yz, wx);
  r[8] = _mm256_sub_pd(one, _mm256_add_pd(xx, yy));
}

// The back half of a product over lanes base..base+3: the first Piola stresses sg (row-major;
// corotational: not yet rotated) taken to R sg, then the corner forces P grad N_{j+1} and
// corner 0 the negated sum, added into the padded y.
template <bool Corot>
__attribute__((target("avx2,fma"))) inline void corner_forces_avx2(const StiffnessKernel::Packet& p, std::size_t base,
                                                                   std::size_t lanes, const __m256d* b,
                                                                   const __m256d* r, __m256d* sg, double* y) {
  if constexpr (Corot) {
    __m256d t[9];
    for (int cc = 0; cc < 3; ++cc)
      for (int m = 0; m < 3; ++m)
        t[3 * cc + m] = _mm256_fmadd_pd(r[3 * cc + 2], sg[6 + m],
                                        _mm256_fmadd_pd(r[3 * cc + 1], sg[3 + m], _mm256_mul_pd(r[3 * cc], sg[m])));
    for (int i = 0; i < 9; ++i) sg[i] = t[i];
  }
  __m256d f[4][3];
  for (int cc = 0; cc < 3; ++cc) {
    __m256d sum = _mm256_setzero_pd();
    for (int j = 0; j < 3; ++j) {
      const __m256d fj = _mm256_fmadd_pd(sg[3 * cc + 2], b[3 * j + 2],
                                         _mm256_fmadd_pd(sg[3 * cc + 1], b[3 * j + 1], _mm256_mul_pd(sg[3 * cc], b[3 * j])));
      f[j + 1][cc] = fj;
      sum = _mm256_add_pd(sum, fj);
    }
    f[0][cc] = _mm256_sub_pd(_mm256_setzero_pd(), sum);
  }
  for (int j = 0; j < 4; ++j) transpose_out(y, &p.v[j][base], lanes, f[j][0], f[j][1], f[j][2]);
}

// The front half of a product over lanes base..base+3 of a packet: the edge differences of x,
// H = D B, and (corotational) R and the rotated H = R^T H. Shared by the product and the
// divergence sweep.
template <bool Corot>
__attribute__((target("avx2,fma"))) inline void packet_gradient_avx2(const StiffnessKernel::Packet& p,
                                                                     const StiffnessKernel::Rotations* rotations,
                                                                     std::size_t base, const double* x, __m256d* b,
                                                                     __m256d* h, __m256d* r) {
  __m256d c[4][3];
  for (int j = 0; j < 4; ++j) transpose_in(x, &p.v[j][base], c[j][0], c[j][1], c[j][2]);
  __m256d d[9];  // d[3c+j]: component c of x_{j+1} - x_0
  for (int cc = 0; cc < 3; ++cc)
    for (int j = 0; j < 3; ++j) d[3 * cc + j] = _mm256_sub_pd(c[j + 1][cc], c[0][cc]);
  for (int i = 0; i < 9; ++i) b[i] = _mm256_load_pd(&p.b[i][base]);
  for (int cc = 0; cc < 3; ++cc)
    for (int m = 0; m < 3; ++m)
      h[3 * cc + m] = _mm256_fmadd_pd(
          d[3 * cc + 2], b[6 + m], _mm256_fmadd_pd(d[3 * cc + 1], b[3 + m], _mm256_mul_pd(d[3 * cc], b[m])));
  if constexpr (Corot) {
    rotation_avx2(*rotations, base, r);
    __m256d t[9];
    for (int cc = 0; cc < 3; ++cc)
      for (int m = 0; m < 3; ++m)
        t[3 * cc + m] = _mm256_fmadd_pd(r[6 + cc], h[6 + m],
                                        _mm256_fmadd_pd(r[3 + cc], h[3 + m], _mm256_mul_pd(r[cc], h[m])));
    for (int i = 0; i < 9; ++i) h[i] = t[i];
  }
}

template <bool Corot>
__attribute__((target("avx2,fma"))) void packets_avx2(const StiffnessKernel::Packet* packets,
                                                      const StiffnessKernel::Rotations* rotations, std::size_t count,
                                                      std::size_t tets, const double* x, double* y,
                                                      const double* pressure) {
  for (std::size_t pi = 0; pi < count; ++pi) {
    const StiffnessKernel::Packet& p = packets[pi];
    const std::size_t n = std::min(kLanes, tets - pi * kLanes);
    for (std::size_t base = 0; base < n; base += 4) {
      __m256d b[9], h[9], r[9];
      packet_gradient_avx2<Corot>(p, Corot ? &rotations[pi] : nullptr, base, x, b, h, r);
      const __m256d mu = _mm256_load_pd(&p.mu[base]);
      __m256d lt = _mm256_mul_pd(_mm256_load_pd(&p.lam[base]), _mm256_add_pd(_mm256_add_pd(h[0], h[4]), h[8]));
      if (pressure) {  // + V mean(pressure at the corners); empty lanes have V = 0 and vertex 0
        __m256d sum = _mm256_setzero_pd();
        for (int j = 0; j < 4; ++j)
          sum = _mm256_add_pd(sum, gather4(pressure, _mm_loadu_si128(reinterpret_cast<const __m128i*>(&p.v[j][base]))));
        lt = _mm256_fmadd_pd(_mm256_mul_pd(_mm256_load_pd(&p.vol[base]), _mm256_set1_pd(0.25)), sum, lt);
      }
      __m256d sg[9];
      for (int cc = 0; cc < 3; ++cc)
        for (int m = 0; m < 3; ++m) sg[3 * cc + m] = _mm256_mul_pd(mu, _mm256_add_pd(h[3 * cc + m], h[3 * m + cc]));
      sg[0] = _mm256_add_pd(sg[0], lt);
      sg[4] = _mm256_add_pd(sg[4], lt);
      sg[8] = _mm256_add_pd(sg[8], lt);
      corner_forces_avx2<Corot>(p, base, std::min<std::size_t>(4, n - base), b, r, sg, y);
    }
  }
}

// stress_forces over a block's packets (see StiffnessKernel::stress_forces), into the padded y.
template <bool Corot>
__attribute__((target("avx2,fma"))) void stresses_avx2(const StiffnessKernel::Packet* packets,
                                                       const StiffnessKernel::Rotations* rotations, std::size_t count,
                                                       const std::uint32_t* tet, std::size_t tets, const double* stress,
                                                       const double* pressure, double* y) {
  for (std::size_t pi = 0; pi < count; ++pi) {
    const StiffnessKernel::Packet& p = packets[pi];
    const std::size_t n = std::min(kLanes, tets - pi * kLanes);
    for (std::size_t base = 0; base < n; base += 4) {
      const std::size_t lanes = std::min<std::size_t>(4, n - base);
      // Each lane's six stress components (empty lanes read tet 0's: their V and b are zero).
      alignas(16) std::int32_t at[4] = {0, 0, 0, 0};
      for (std::size_t k = 0; k < lanes; ++k) at[k] = std::int32_t(6 * tet[pi * kLanes + base + k]);
      const __m128i idx = _mm_load_si128(reinterpret_cast<const __m128i*>(at));
      __m256d st[6];
      for (int c = 0; c < 6; ++c) st[c] = gather4(stress + c, idx);
      const __m256d vol = _mm256_load_pd(&p.vol[base]);
      __m256d diag = _mm256_setzero_pd();
      if (pressure) {
        for (int j = 0; j < 4; ++j)
          diag = _mm256_add_pd(diag, gather4(pressure, _mm_loadu_si128(reinterpret_cast<const __m128i*>(&p.v[j][base]))));
        diag = _mm256_mul_pd(diag, _mm256_set1_pd(0.25));
      }
      __m256d sg[9];
      sg[0] = _mm256_mul_pd(vol, _mm256_add_pd(st[0], diag));
      sg[4] = _mm256_mul_pd(vol, _mm256_add_pd(st[1], diag));
      sg[8] = _mm256_mul_pd(vol, _mm256_add_pd(st[2], diag));
      sg[1] = sg[3] = _mm256_mul_pd(vol, st[3]);
      sg[2] = sg[6] = _mm256_mul_pd(vol, st[4]);
      sg[5] = sg[7] = _mm256_mul_pd(vol, st[5]);
      __m256d b[9], r[9];
      for (int i = 0; i < 9; ++i) b[i] = _mm256_load_pd(&p.b[i][base]);
      if constexpr (Corot) rotation_avx2(rotations[pi], base, r);
      corner_forces_avx2<Corot>(p, base, lanes, b, r, sg, y);
    }
  }
}

// strain_sweep over a block's packets (see StiffnessKernel::strain_sweep).
template <bool Corot>
__attribute__((target("avx2,fma"))) void strains_avx2(const StiffnessKernel::Packet* packets,
                                                      const StiffnessKernel::Rotations* rotations, std::size_t count,
                                                      const std::uint32_t* tet, std::size_t tets, const double* x,
                                                      double* out, double* sums) {
  const __m256d half = _mm256_set1_pd(0.5), sixth = _mm256_set1_pd(1.0 / 6.0);
  for (std::size_t pi = 0; pi < count; ++pi) {
    const StiffnessKernel::Packet& p = packets[pi];
    const std::size_t n = std::min(kLanes, tets - pi * kLanes);
    for (std::size_t base = 0; base < n; base += 4) {
      __m256d b[9], h[9], r[9];
      packet_gradient_avx2<Corot>(p, Corot ? &rotations[pi] : nullptr, base, x, b, h, r);
      const __m256d vol = _mm256_load_pd(&p.vol[base]), v6 = _mm256_mul_pd(vol, sixth);
      alignas(32) double e[6][4], vd[4];
      _mm256_store_pd(e[0], _mm256_mul_pd(v6, h[0]));
      _mm256_store_pd(e[1], _mm256_mul_pd(v6, h[4]));
      _mm256_store_pd(e[2], _mm256_mul_pd(v6, h[8]));
      _mm256_store_pd(e[3], _mm256_mul_pd(v6, _mm256_mul_pd(half, _mm256_add_pd(h[1], h[3]))));
      _mm256_store_pd(e[4], _mm256_mul_pd(v6, _mm256_mul_pd(half, _mm256_add_pd(h[2], h[6]))));
      _mm256_store_pd(e[5], _mm256_mul_pd(v6, _mm256_mul_pd(half, _mm256_add_pd(h[5], h[7]))));
      _mm256_store_pd(vd, _mm256_mul_pd(vol, _mm256_add_pd(_mm256_add_pd(h[0], h[4]), h[8])));
      const std::size_t lanes = std::min<std::size_t>(4, n - base);
      for (std::size_t k = 0; k < lanes; ++k) {
        if (out) {
          double* o = out + 6 * std::size_t(tet[pi * kLanes + base + k]);
          for (int c = 0; c < 6; ++c) o[c] = e[c][k];
        }
        if (sums)
          for (int j = 0; j < 4; ++j) sums[p.v[j][base + k]] += vd[k];
      }
    }
  }
}

bool cpu_has_avx2() {
  static const bool yes = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  return yes;
}
#endif

// Every block once: slabs three apart at the same time (they share no vertex), each slab on one
// thread, then the overflow block serially; or all in order on this thread.
template <class Blocks, class Run>
void for_each_block(Blocks& blocks, bool parallel, Run&& run) {
  if (!parallel) {
    for (auto& blk : blocks) run(blk);
    return;
  }
  const std::size_t nslabs = blocks.size() - 1;
  for (std::size_t colour = 0; colour < 3; ++colour)
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, (nslabs - colour + 2) / 3, 1),
                      [&](const tbb::blocked_range<std::size_t>& rg) {
                        for (std::size_t i = rg.begin(); i != rg.end(); ++i) run(blocks[3 * i + colour]);
                      });
  run(blocks.back());
}

}  // namespace

bool StiffnessKernel::simd_available() {
#ifdef INCISE_KERNEL_AVX2
  return cpu_has_avx2();
#else
  return false;
#endif
}

void StiffnessKernel::configure(const TetMesh& mesh) {
  const RestBounds box = rest_bounds(mesh);
  const Vec3 ext = box.size();
  // The axis along which vertex ids vary slowest (smallest mean step between consecutive ids,
  // relative to the extent): a slab is then a narrow range of ids, so each task sweeps a
  // compact part of x and y. Structured meshes number one axis last; spatially sorted ones
  // (Hilbert, BRIO) give about equal steps and any axis does.
  Vec3 step = Vec3::Zero();
  const Vec3* prev = nullptr;
  for (VertexId v : mesh.vertices()) {
    if (prev) step += (mesh.rest(v) - *prev).cwiseAbs();
    prev = &mesh.rest(v);
  }
  double best = std::numeric_limits<double>::max();
  for (int a = 0; a < 3; ++a)
    if (ext[a] > 0 && step[a] / ext[a] < best) best = step[a] / ext[a], axis_ = a;
  double widest = 0;
  for (TetId t : mesh.tets()) {
    double a = std::numeric_limits<double>::max(), b = -a;
    for (VertexId v : mesh.tet_vertices(t)) {
      a = std::min(a, mesh.rest(v)[axis_]);
      b = std::max(b, mesh.rest(v)[axis_]);
    }
    widest = std::max(widest, b - a);
  }
  // Enough slabs per colour for load balance (3 colours x 16), none narrower than a tet.
  const double len = ext[axis_];
  std::size_t n = 48;
  if (widest > 0) n = std::min<std::size_t>(n, std::size_t(std::max(1.0, std::floor(len / (1.02 * widest)))));
  if (!(len > 0) || n < 6) n = 1;  // too short to split: one slab, serial
  origin_ = box.empty() ? 0.0 : box.lo[axis_];
  width_ = len > 0 ? len / double(n) : 1.0;
  blocks_.assign(n + 1, Block{});
}

void StiffnessKernel::add(const TetMesh& mesh, std::uint32_t t, const std::array<std::uint32_t, 4>& v,
                          const Eigen::Matrix3d& bm, double vmu, double vlambda, double volume) {
  remove(t);
  if (blocks_.empty()) blocks_.assign(2, Block{});  // not configured: one slab
  if (t >= block_.size()) {
    block_.resize(std::max<std::size_t>(t + 1, block_.size() + block_.size() / 2), kNone);
    slot_.resize(block_.size(), kNone);
  }
  double a = std::numeric_limits<double>::max(), b = -a, centre = 0;
  for (std::uint32_t w : v) {
    const double x = mesh.rest(VertexId(w))[axis_];
    a = std::min(a, x);
    b = std::max(b, x);
    centre += x / 4;
  }
  const std::size_t nslabs = blocks_.size() - 1;
  std::size_t c = nslabs;  // overflow
  if (nslabs == 1) c = 0;
  else if (b - a <= 0.99 * width_) c = std::size_t(std::clamp((centre - origin_) / width_, 0.0, double(nslabs - 1)));
  Block& blk = blocks_[c];
  const std::size_t s = blk.size(), k = s % kLanes;
  if (k == 0) {  // a new packet, all lanes zero
    blk.packets.emplace_back();
    std::memset(static_cast<void*>(&blk.packets.back()), 0, sizeof(Packet));
    if (corot_) {
      blk.rotations.emplace_back();
      std::memset(static_cast<void*>(&blk.rotations.back()), 0, sizeof(Rotations));
    }
  }
  Packet& p = blk.packets[s / kLanes];
  for (int i = 0; i < 4; ++i) p.v[i][k] = v[std::size_t(i)];
  for (int j = 0; j < 3; ++j)
    for (int m = 0; m < 3; ++m) p.b[3 * j + m][k] = bm(j, m);
  p.mu[k] = vmu;
  p.lam[k] = vlambda;
  p.vol[k] = volume;
  if (corot_)
    blk.rotations[s / kLanes].q[0][k] = 1.0;  // identity (the other components are zero)
  blk.tet.push_back(t);
  block_[t] = std::uint32_t(c);
  slot_[t] = std::uint32_t(s);
  ++count_;
}

void StiffnessKernel::remove(std::uint32_t t) {
  if (t >= block_.size() || block_[t] == kNone) return;
  Block& blk = blocks_[block_[t]];
  const std::size_t s = slot_[t], last = blk.size() - 1;
  Packet &ps = blk.packets[s / kLanes], &pl = blk.packets[last / kLanes];
  const std::size_t ks = s % kLanes, kl = last % kLanes;
  // The last tet moves into the freed slot; its old lane is cleared.
  for (int i = 0; i < 4; ++i) {
    ps.v[i][ks] = pl.v[i][kl];
    pl.v[i][kl] = 0;
  }
  for (int i = 0; i < 9; ++i) {
    ps.b[i][ks] = pl.b[i][kl];
    pl.b[i][kl] = 0;
  }
  ps.mu[ks] = pl.mu[kl];
  ps.lam[ks] = pl.lam[kl];
  ps.vol[ks] = pl.vol[kl];
  pl.mu[kl] = pl.lam[kl] = pl.vol[kl] = 0;
  if (corot_) {
    Rotations &rs = blk.rotations[s / kLanes], &rl = blk.rotations[last / kLanes];
    for (int i = 0; i < 4; ++i) {
      rs.q[i][ks] = rl.q[i][kl];
      rl.q[i][kl] = 0;
    }
  }
  blk.tet[s] = blk.tet[last];
  blk.tet.pop_back();
  if (s != last) slot_[blk.tet[s]] = std::uint32_t(s);
  if (kl == 0) {
    blk.packets.pop_back();
    if (corot_) blk.rotations.pop_back();
  }
  block_[t] = slot_[t] = kNone;
  --count_;
}

void StiffnessKernel::set_rotation(std::uint32_t t, const Eigen::Matrix3d& r) {
  set_rotation(t, Eigen::Quaterniond(r).normalized());  // r is a proper rotation
}

void StiffnessKernel::set_rotation(std::uint32_t t, const Eigen::Quaterniond& q) {
  if (!corot_ || t >= block_.size() || block_[t] == kNone) return;
  Block& blk = blocks_[block_[t]];
  const std::size_t s = slot_[t];
  Rotations& dst = blk.rotations[s / kLanes];
  dst.q[0][s % kLanes] = q.w();
  dst.q[1][s % kLanes] = q.x();
  dst.q[2][s % kLanes] = q.y();
  dst.q[3][s % kLanes] = q.z();
}

// Packets [begin, end) of a block.
void StiffnessKernel::multiply_block(const Block& blk, std::size_t begin, std::size_t end, const double* x,
                                     double* y, const double* pressure) const {
  Scratch sc;
  for (std::size_t pi = begin; pi < end; ++pi) {
    const Packet& p = blk.packets[pi];
    const std::size_t n = std::min(kLanes, blk.size() - pi * kLanes);
    for (std::size_t k = 0; k < n; ++k) {  // gather
      const double* x0 = x + 3 * std::size_t(p.v[0][k]);
      for (int j = 0; j < 3; ++j) {
        const double* xj = x + 3 * std::size_t(p.v[j + 1][k]);
        for (int c = 0; c < 3; ++c) sc.d[3 * c + j][k] = xj[c] - x0[c];
      }
    }
    for (std::size_t k = n; k < kLanes; ++k)  // empty lanes: finite inputs (their b is zero)
      for (int i = 0; i < 9; ++i) sc.d[i][k] = 0;
    if (corot_) packet_forces<true>(p, &blk.rotations[pi], sc, pressure);
    else packet_forces<false>(p, nullptr, sc, pressure);
    // Scatter (one thread per block), corner by corner: consecutive tets share vertices, and
    // read-modify-writes of one address back to back would wait on each other.
    for (int j = 0; j < 4; ++j)
      for (std::size_t k = 0; k < n; ++k) {
        double* yj = y + 3 * std::size_t(p.v[j][k]);
        for (int c = 0; c < 3; ++c) yj[c] += sc.f[3 * j + c][k];
      }
  }
}

void StiffnessKernel::multiply_padded(const Block& blk, const double* x, double* y, const double* pressure) const {
#ifdef INCISE_KERNEL_AVX2
  if (corot_) packets_avx2<true>(blk.packets.data(), blk.rotations.data(), blk.packets.size(), blk.size(), x, y, pressure);
  else packets_avx2<false>(blk.packets.data(), nullptr, blk.packets.size(), blk.size(), x, y, pressure);
#else
  (void)blk, (void)x, (void)y, (void)pressure;
#endif
}

bool StiffnessKernel::parallel() const { return count_ >= kSerialBelow && blocks_.size() >= 7; }  // 6 slabs

void StiffnessKernel::for_each_packet(const PacketVisitor& fn) {
  for_each_block(blocks_, parallel(), [&](Block& blk) {
    for (std::size_t pi = 0; pi < blk.packets.size(); ++pi)
      fn(blk.packets[pi], corot_ ? &blk.rotations[pi] : nullptr, blk.tet.data() + pi * kLanes,
         std::min(kLanes, blk.size() - pi * kLanes));
  });
}

// The portable path's front half for one lane k of packet p: h = R^T D B (D B when linear).
static inline void lane_gradient(const StiffnessKernel::Packet& p, const StiffnessKernel::Rotations* rot, std::size_t k,
                          const double* x, double* h) {
  double d[9];  // d[3c+j]: component c of x_{j+1} - x_0
  const double* x0 = x + 3 * std::size_t(p.v[0][k]);
  for (int j = 0; j < 3; ++j) {
    const double* xj = x + 3 * std::size_t(p.v[j + 1][k]);
    for (int c = 0; c < 3; ++c) d[3 * c + j] = xj[c] - x0[c];
  }
  for (int c = 0; c < 3; ++c)
    for (int m = 0; m < 3; ++m)
      h[3 * c + m] = d[3 * c] * p.b[m][k] + d[3 * c + 1] * p.b[3 + m][k] + d[3 * c + 2] * p.b[6 + m][k];
  if (rot) {
    double r[9], t[9];
    rotation_from_quaternion(rot->q[0][k], rot->q[1][k], rot->q[2][k], rot->q[3][k], r);
    for (int c = 0; c < 3; ++c)
      for (int m = 0; m < 3; ++m) t[3 * c + m] = r[c] * h[m] + r[3 + c] * h[3 + m] + r[6 + c] * h[6 + m];
    for (int i = 0; i < 9; ++i) h[i] = t[i];
  }
}

void StiffnessKernel::strain_sweep(const Eigen::VectorXd& x, double* out, double* sums) const {
  const double* xp = x.data();
  const bool simd = simd_ && simd_available();
  for_each_block(blocks_, parallel(), [&](const Block& blk) {
#ifdef INCISE_KERNEL_AVX2
    if (simd) {
      if (corot_) strains_avx2<true>(blk.packets.data(), blk.rotations.data(), blk.packets.size(), blk.tet.data(), blk.size(), xp, out, sums);
      else strains_avx2<false>(blk.packets.data(), nullptr, blk.packets.size(), blk.tet.data(), blk.size(), xp, out, sums);
      return;
    }
#endif
    for (std::size_t pi = 0; pi < blk.packets.size(); ++pi) {
      const Packet& p = blk.packets[pi];
      const std::size_t n = std::min(kLanes, blk.size() - pi * kLanes);
      for (std::size_t k = 0; k < n; ++k) {
        double h[9];
        lane_gradient(p, corot_ ? &blk.rotations[pi] : nullptr, k, xp, h);
        if (out) {
          const double v6 = p.vol[k] / 6;
          double* o = out + 6 * std::size_t(blk.tet[pi * kLanes + k]);
          o[0] = v6 * h[0];
          o[1] = v6 * h[4];
          o[2] = v6 * h[8];
          o[3] = v6 * 0.5 * (h[1] + h[3]);
          o[4] = v6 * 0.5 * (h[2] + h[6]);
          o[5] = v6 * 0.5 * (h[5] + h[7]);
        }
        if (sums)
          for (int j = 0; j < 4; ++j) sums[p.v[j][k]] += p.vol[k] * (h[0] + h[4] + h[8]);
      }
    }
  });
}

void StiffnessKernel::stress_forces(const double* stress, const double* pressure, Eigen::VectorXd& y,
                                    Eigen::Index rows) const {
  const bool padded = simd_ && simd_available();
  sweep_forces(y, rows, padded, [&](const Block& blk, double* yp) {
#ifdef INCISE_KERNEL_AVX2
    if (padded) {
      if (corot_)
        stresses_avx2<true>(blk.packets.data(), blk.rotations.data(), blk.packets.size(), blk.tet.data(), blk.size(),
                            stress, pressure, yp);
      else
        stresses_avx2<false>(blk.packets.data(), nullptr, blk.packets.size(), blk.tet.data(), blk.size(), stress,
                             pressure, yp);
      return;
    }
#endif
    for (std::size_t pi = 0; pi < blk.packets.size(); ++pi) {
      const Packet& p = blk.packets[pi];
      const std::size_t n = std::min(kLanes, blk.size() - pi * kLanes);
      for (std::size_t k = 0; k < n; ++k) {
        const double* st = stress + 6 * std::size_t(blk.tet[pi * kLanes + k]);
        double diag = 0;
        if (pressure)
          diag = 0.25 * (pressure[p.v[0][k]] + pressure[p.v[1][k]] + pressure[p.v[2][k]] + pressure[p.v[3][k]]);
        const double v = p.vol[k];
        double s[9] = {v * (st[0] + diag), v * st[3], v * st[4], v * st[3], v * (st[1] + diag), v * st[5],
                       v * st[4], v * st[5], v * (st[2] + diag)};
        if (corot_) {  // P = R s
          const Rotations& q = blk.rotations[pi];
          double r[9], t[9];
          rotation_from_quaternion(q.q[0][k], q.q[1][k], q.q[2][k], q.q[3][k], r);
          for (int c = 0; c < 3; ++c)
            for (int m = 0; m < 3; ++m) t[3 * c + m] = r[3 * c] * s[m] + r[3 * c + 1] * s[3 + m] + r[3 * c + 2] * s[6 + m];
          for (int i = 0; i < 9; ++i) s[i] = t[i];
        }
        double* y0 = yp + 3 * std::size_t(p.v[0][k]);
        for (int j = 0; j < 3; ++j) {
          double* yj = yp + 3 * std::size_t(p.v[j + 1][k]);
          for (int c = 0; c < 3; ++c) {
            const double f = s[3 * c] * p.b[3 * j][k] + s[3 * c + 1] * p.b[3 * j + 1][k] + s[3 * c + 2] * p.b[3 * j + 2][k];
            yj[c] += f;
            y0[c] -= f;
          }
        }
      }
    }
  });
}

void StiffnessKernel::multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y, Eigen::Index rows,
                               const double* pressure) const {
  const bool padded = simd_ && simd_available();
  const double* xp = x.data();
  sweep_forces(y, rows, padded, [&](const Block& blk, double* yp) {
    if (padded) multiply_padded(blk, xp, yp, pressure);
    else multiply_block(blk, 0, blk.packets.size(), xp, yp, pressure);
  });
}

void StiffnessKernel::sweep_forces(Eigen::VectorXd& y, Eigen::Index rows, bool padded,
                                   const std::function<void(const Block&, double*)>& run) const {
  const bool parallel = this->parallel();
  auto for_vertices = [&](std::size_t nv, auto&& f) {
    if (!parallel) {
      for (std::size_t v = 0; v < nv; ++v) f(v);
      return;
    }
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, nv, 4096), [&](const tbb::blocked_range<std::size_t>& rg) {
      for (std::size_t v = rg.begin(); v != rg.end(); ++v) f(v);
    });
  };
  double* yp = nullptr;
  const std::size_t nv = std::size_t(rows) / 3;
  if (padded) {
    // y with 4 doubles per vertex, so a corner's scatter is one vector read-modify-write
    // that touches no other vertex. It is all zeros between products (new entries are zero,
    // the unpacking pass below zeroes what it read): one O(V) pass per product.
    if (ypad_.size() < 4 * nv + 4) ypad_.resize(4 * nv + 4 + nv / 2, 0.0);
    yp = ypad_.data();
  } else {
    y.setZero(rows);
    yp = y.data();
  }
  for_each_block(blocks_, parallel, [&](const Block& blk) { run(blk, yp); });
  if (padded) {
    y.resize(rows);
    double* yo = y.data();
    double* yq = ypad_.data();
    for_vertices(nv, [&](std::size_t v) {
      yo[3 * v] = yq[4 * v];
      yo[3 * v + 1] = yq[4 * v + 1];
      yo[3 * v + 2] = yq[4 * v + 2];
      yq[4 * v] = yq[4 * v + 1] = yq[4 * v + 2] = 0;  // the 4th entry is never written
    });
    for (Eigen::Index i = Eigen::Index(3 * nv); i < rows; ++i) yo[i] = 0;
  }
}

}  // namespace incise
