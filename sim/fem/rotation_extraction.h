#pragma once
// The rotation of a deformation gradient F for corotational elements: the proper rotation R that
// maximizes tr(R^T F). For det F > 0 that is the rotation of the polar decomposition F = R S;
// for det F <= 0 (inverted elements) it is the closest proper rotation, U diag(1, 1, -1) V^T from
// the SVD F = U Sigma V^T with the smallest singular value's column flipped.
//
// Two ways to get it:
// - polar_rotation(F): from scratch (scaled Newton on F, the SVD where F is inverted or nearly
//   degenerate). Exact to rounding; what the warm-started one falls back to.
// - refine_rotations(lanes): warm-started from a previous rotation, the quaternion iteration of
//   Mueller, Bender, Chentanez & Macklin 2016 ("A robust method to extract the rotational part of
//   deformations"): q <- q (x) exp(delta / 2), delta from the skew part of S = R^T F. Mueller et
//   al. scale the step by 1 / tr(S) (linear convergence, each step shrinks the error by about
//   sigma_max / tr(S), ~1/3 per step at small strain: 11-13 steps to 1e-6 from 0.05 rad);
//   here the step is the Newton step of tr(R^T F) on SO(3): delta = 2 M^-1 a with a the axial
//   vector of skew(S) and M = tr(S) I - sym(S) (quadratic convergence: a frame's rotation
//   change of 0.05 rad is at 1e-10 after 3 steps). |delta| of the last step estimates the
//   iterate's error to first order, so the residual costs nothing extra. M is positive definite
//   near the maximum (eigenvalues sigma_i + sigma_j, inverted: one of them is sigma_i - sigma_3);
//   where it is not (a start more than ~90 degrees off, an ambiguous rotation of a degenerate
//   or flat element) the lane reports no convergence and the caller uses polar_rotation.
// Lanes are a struct of arrays so the compiler vectorizes across them (AVX2 clone where the CPU
// has it), like the K x kernel's packets (sim/fem/stiffness_kernel.h).
#include <cstddef>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace incise {

Eigen::Matrix3d polar_rotation(const Eigen::Matrix3d& f);

// R of the unit quaternion (w, x, y, z), row-major: r[3a+c] = R(a, c). Inline, so that the lane
// loops that call it (the Newton step here, the corotational corner terms, the K x kernel)
// still vectorize.
inline void rotation_from_quaternion(double w, double x, double y, double z, double* r) {
  const double x2 = x + x, y2 = y + y, z2 = z + z;
  const double xx = x * x2, yy = y * y2, zz = z * z2, xy = x * y2, xz = x * z2, yz = y * z2;
  const double wx = w * x2, wy = w * y2, wz = w * z2;
  r[0] = 1 - (yy + zz);
  r[1] = xy - wz;
  r[2] = xz + wy;
  r[3] = xy + wz;
  r[4] = 1 - (xx + zz);
  r[5] = yz - wx;
  r[6] = xz - wy;
  r[7] = yz + wx;
  r[8] = 1 - (xx + yy);
}

struct RotationLanes {
  static constexpr std::size_t kLanes = 8;
  alignas(64) double f[9][kLanes];  // f[3r+c][k]: F(r, c) of lane k
  alignas(64) double q[4][kLanes];  // (w, x, y, z), unit: the start in, the result out
  // Out: |delta| of the last step taken, the error of the iterate before it (radians, to first
  // order); 1e300 where M was not safely positive definite (not converged).
  alignas(64) double step[kLanes];
};

// Newton steps on every lane until every lane's last step is at most `tolerance` (radians) or
// `max_steps` were taken; returns the number of steps. A lane has converged when step <= tolerance
// (its rotation is then within about |step|^2 of the exact one).
int refine_rotations(RotationLanes& lanes, int max_steps, double tolerance);

// Tuning of the warm-started extraction (FemModel::update_rotations).
struct RotationRefinement {
  int max_steps = 4;
  double tolerance = 1e-6;  // radians, on the last Newton step
};

// One rotation: warm-started from `start`, polar_rotation where the iteration does not converge
// (`exact`, if given, says so). Tests and callers outside a packet loop.
Eigen::Quaterniond refine_rotation(const Eigen::Matrix3d& f, const Eigen::Quaterniond& start,
                                   const RotationRefinement& opt = {}, bool* exact = nullptr);

}  // namespace incise
