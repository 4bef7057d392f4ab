#pragma once
// Random vectors whose draws happen in a fixed order. In `Vec3(u(rng), u(rng), u(rng))` the
// order of the three draws is the compiler's choice (gcc evaluates call arguments right to left,
// clang left to right), so one seed gave the two compilers different blades, jitter and
// perturbations. These draw z, then y, then x: gcc's order, so every figure measured with gcc
// stays the same, and a clang build runs the same cases.
#include <Eigen/Geometry>

#include "mesh/tet_mesh.h"

namespace incise::testing {

template <class Dist, class Rng>
Vec3 draw_vec3(Dist& d, Rng& rng) {
  const double z = d(rng);
  const double y = d(rng);
  const double x = d(rng);
  return Vec3(x, y, z);
}

// A quaternion (w, x, y, z) with coefficients drawn z, y, x, w (gcc's order for the constructor).
template <class Dist, class Rng>
Eigen::Quaterniond draw_quaternion(Dist& d, Rng& rng) {
  const double z = d(rng);
  const double y = d(rng);
  const double x = d(rng);
  const double w = d(rng);
  return Eigen::Quaterniond(w, x, y, z);
}

}  // namespace incise::testing
