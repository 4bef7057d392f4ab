#include "sim/fem/rotation_extraction.h"

#include <algorithm>
#include <cmath>

#include <Eigen/LU>
#include <Eigen/SVD>

#include "sim/linalg/simd_clones.h"

namespace incise {

// Well-shaped, uninverted F (the common case): scaled Newton iteration R <- (g R + R^-T / g) / 2
// (Higham), a few 3x3 inverses, many times cheaper than an SVD. Inverted or nearly degenerate
// F: the SVD, with the column of the smallest singular value flipped to get the closest proper
// rotation.
Eigen::Matrix3d polar_rotation(const Eigen::Matrix3d& f) {
  const double det = f.determinant(), fn = f.norm();
  if (det > 1e-3 * fn * fn * fn) {
    Eigen::Matrix3d r = f;
    for (int it = 0; it < 20; ++it) {
      const Eigen::Matrix3d rit = r.inverse().transpose();
      const double g = std::sqrt(std::sqrt(rit.squaredNorm() / r.squaredNorm()));
      const Eigen::Matrix3d next = 0.5 * (g * r + rit / g);
      const double change = (next - r).squaredNorm();
      r = next;
      if (change < 1e-28) break;
    }
    if ((r.transpose() * r - Eigen::Matrix3d::Identity()).squaredNorm() < 1e-24 && r.determinant() > 0) return r;
  }
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(f, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d uu = svd.matrixU();
  const Eigen::Matrix3d& vv = svd.matrixV();
  Eigen::Matrix3d r = uu * vv.transpose();
  if (r.determinant() < 0) {  // inverted (or reflected) element: nearest proper rotation
    uu.col(2) = -uu.col(2);
    r = uu * vv.transpose();
  }
  return r;
}

namespace {

constexpr std::size_t kLanes = RotationLanes::kLanes;
constexpr double kNotConverged = 1e300;  // the step of a lane whose M is not positive definite

// One Newton step on every lane (plain loops over the lanes, selects instead of branches: the
// compiler vectorizes them; sqrt needs -fno-math-errno, see sim/CMakeLists.txt).
INCISE_SIMD_CLONES void newton_step(RotationLanes& __restrict l) {
  for (std::size_t k = 0; k < kLanes; ++k) {
    const double w = l.q[0][k], x = l.q[1][k], y = l.q[2][k], z = l.q[3][k];
    // R of the unit quaternion, r[3a+c] = R(a, c).
    double r[9];
    rotation_from_quaternion(w, x, y, z, r);
    // S = R^T F.
    double s[9];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) s[3 * i + j] = r[i] * l.f[j][k] + r[3 + i] * l.f[3 + j][k] + r[6 + i] * l.f[6 + j][k];
    // a: axial vector of skew(S); M = tr(S) I - sym(S). The Newton step delta = 2 M^-1 a turns
    // R into R exp([delta]x).
    const double a0 = 0.5 * (s[7] - s[5]), a1 = 0.5 * (s[2] - s[6]), a2 = 0.5 * (s[3] - s[1]);
    const double t = s[0] + s[4] + s[8];
    const double m00 = t - s[0], m11 = t - s[4], m22 = t - s[8];
    const double m01 = -0.5 * (s[1] + s[3]), m02 = -0.5 * (s[2] + s[6]), m12 = -0.5 * (s[5] + s[7]);
    const double c00 = m11 * m22 - m12 * m12, c01 = m02 * m12 - m01 * m22, c02 = m01 * m12 - m02 * m11;
    const double c11 = m00 * m22 - m02 * m02, c12 = m01 * m02 - m00 * m12, c22 = m00 * m11 - m01 * m01;
    const double det = m00 * c00 + m01 * c01 + m02 * c02;
    // Positive definite (Sylvester) and not nearly singular relative to its size: otherwise
    // the start is not in the maximum's basin, or the rotation is ill-determined.
    const double tm = 2 * t;
    // As 0 or 1 and arithmetic instead of selects: the loop has no branch to vectorize.
    const double ok = double((m00 > 0) & (c22 > 0) & (det > 1e-9 * tm * tm * tm));
    const double inv = ok * 2 / (ok * det + (1 - ok));
    const double d0 = inv * (c00 * a0 + c01 * a1 + c02 * a2);
    const double d1 = inv * (c01 * a0 + c11 * a1 + c12 * a2);
    const double d2 = inv * (c02 * a0 + c12 * a1 + c22 * a2);
    const double norm = std::sqrt(d0 * d0 + d1 * d1 + d2 * d2);
    const double step = norm + (1 - ok) * kNotConverged;
    l.step[k] = step;
    // q <- q (x) (1, delta / 2), normalized (exp to second order; the error is the next step's).
    const double v0 = 0.5 * d0, v1 = 0.5 * d1, v2 = 0.5 * d2;
    const double nw = w - (x * v0 + y * v1 + z * v2);
    const double nx = w * v0 + x + (y * v2 - z * v1);
    const double ny = w * v1 + y + (z * v0 - x * v2);
    const double nz = w * v2 + z + (x * v1 - y * v0);
    const double sc = 1 / std::sqrt(nw * nw + nx * nx + ny * ny + nz * nz);
    l.q[0][k] = nw * sc;
    l.q[1][k] = nx * sc;
    l.q[2][k] = ny * sc;
    l.q[3][k] = nz * sc;
  }
}

}  // namespace

int refine_rotations(RotationLanes& lanes, int max_steps, double tolerance) {
  int steps = 0;
  while (steps < max_steps) {
    ++steps;
    newton_step(lanes);
    double worst = 0;  // NaN for a NaN F
    for (std::size_t k = 0; k < kLanes; ++k) worst = std::max(worst, std::isnan(lanes.step[k]) ? kNotConverged : lanes.step[k]);
    if (worst <= tolerance) break;
  }
  return steps;
}

Eigen::Quaterniond refine_rotation(const Eigen::Matrix3d& f, const Eigen::Quaterniond& start,
                                   const RotationRefinement& opt, bool* exact) {
  RotationLanes l;
  for (std::size_t k = 0; k < kLanes; ++k) {  // every lane a copy: no lane sees garbage
    for (int i = 0; i < 9; ++i) l.f[i][k] = f(i / 3, i % 3);
    l.q[0][k] = start.w();
    l.q[1][k] = start.x();
    l.q[2][k] = start.y();
    l.q[3][k] = start.z();
  }
  refine_rotations(l, opt.max_steps, opt.tolerance);
  const bool fallback = !(l.step[0] <= opt.tolerance);
  if (exact) *exact = fallback;
  if (fallback) return Eigen::Quaterniond(polar_rotation(f)).normalized();
  return Eigen::Quaterniond(l.q[0][0], l.q[1][0], l.q[2][0], l.q[3][0]);
}

}  // namespace incise
