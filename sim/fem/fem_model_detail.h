#pragma once
// Helpers shared by the FemModel translation units (fem_model*.cpp): internal to sim/fem/.
#include <cstddef>
#include <cstdint>

#include <Eigen/Core>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace incise::fem_detail {


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
inline constexpr std::size_t kVolumetricSerialBelow = 8000;

template <class F>
void for_each_index(std::size_t n, bool serial, F&& f) {
  if (serial)
    for (std::size_t i = 0; i < n; ++i) f(i);
  else
    parallel_range(n, f);
}

// f(begin, end) over [0, n) in chunks (a kernel that runs a whole range per call).
template <class F>
void for_each_chunk(std::size_t n, bool serial, F&& f) {
  if (serial) {
    f(std::size_t(0), n);
    return;
  }
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 512),
                    [&](const tbb::blocked_range<std::size_t>& r) { f(r.begin(), r.end()); });
}

// A tet's six edges as pairs of local corners.
inline constexpr int kTetEdge[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};

inline std::uint64_t edge_key(std::uint32_t a, std::uint32_t b) {
  return a < b ? (std::uint64_t(a) << 32) | b : (std::uint64_t(b) << 32) | a;
}


}  // namespace incise::fem_detail
