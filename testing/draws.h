#pragma once
// Random vectors whose draws happen in a fixed order. In `Vec3(u(rng), u(rng), u(rng))` the
// order of the three draws is the compiler's choice (gcc evaluates call arguments right to left,
// clang left to right), so one seed gave the two compilers different blades, jitter and
// perturbations. These draw z, then y, then x: gcc's order, so every figure measured with gcc
// stays the same, and a clang build runs the same cases.
#include <random>
#include <vector>

#include <Eigen/Geometry>

#include "mesh/rest_bounds.h"
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

// A straight blade swept across a body: segment a-b moved by `sweep`.
struct RandomBlade {
  Vec3 a, b, sweep;
};

// `count` random blades for a body (bench_cut's quality rows and the quality-floor tests):
// centre in the body's box, a random direction, a length and a sweep perpendicular to it of
// 15-45% of the box's diagonal each, the segment centred on the sweep's middle.
inline std::vector<RandomBlade> random_blades(const TetMesh& m, int count, unsigned seed) {
  const RestBounds box = rest_bounds(m);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::normal_distribution<double> nd;
  std::vector<RandomBlade> out;
  const double diag = box.size().norm();
  for (int i = 0; i < count; ++i) {
    const Vec3 c = box.lo + draw_vec3(u, rng).cwiseProduct(box.size());
    const Vec3 dir = draw_vec3(nd, rng).normalized();
    Vec3 sweep = draw_vec3(nd, rng);
    sweep = (sweep - sweep.dot(dir) * dir).normalized() * diag * (0.15 + 0.3 * u(rng));
    const double len = diag * (0.15 + 0.3 * u(rng));
    out.push_back({c - 0.5 * len * dir - 0.5 * sweep, c + 0.5 * len * dir - 0.5 * sweep, sweep});
  }
  return out;
}

}  // namespace incise::testing
