#pragma once
// Shared by the edge-removal and multi-face-removal tests: a jittered ring of n points around
// the z axis (counter-clockwise seen from above) with an apex below and one above, and every
// triangulation of a polygon, for brute force against the dynamic programs.
#include <array>
#include <cmath>
#include <random>
#include <vector>

#include "mesh/tet_mesh.h"
#include "testing/draws.h"

namespace incise::testing {

struct JitteredRing {
  std::vector<Vec3> ring;
  Vec3 below, above;
};

// Angles jittered by 0.3 of a step, radii by 0.4, heights by 0.3; apexes near (0, 0, -1)
// and (0, 0, 1). The ring need not be convex.
inline JitteredRing jittered_ring(int n, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1, 1);
  JitteredRing out;
  for (int i = 0; i < n; ++i) {
    const double th = 2 * M_PI * (i + 0.3 * u(rng)) / n;
    const double r = 1 + 0.4 * u(rng);
    out.ring.emplace_back(r * std::cos(th), r * std::sin(th), 0.3 * u(rng));
  }
  // Drawn z, y, x (see support/draws.h).
  const Vec3 b = draw_vec3(u, rng), a = draw_vec3(u, rng);
  out.below = Vec3(0.2 * b.x(), 0.2 * b.y(), -1 + 0.3 * b.z());
  out.above = Vec3(0.2 * a.x(), 0.2 * a.y(), 1 + 0.3 * a.z());
  return out;
}

// Every triangulation of polygon i..j (triangle lists), by the apex of side (i,j).
inline std::vector<std::vector<std::array<int, 3>>> all_triangulations(int i, int j) {
  if (j - i < 2) return {{}};
  std::vector<std::vector<std::array<int, 3>>> out;
  for (int k = i + 1; k < j; ++k)
    for (const auto& l : all_triangulations(i, k))
      for (const auto& r : all_triangulations(k, j)) {
        auto t = l;
        t.insert(t.end(), r.begin(), r.end());
        t.push_back({i, k, j});
        out.push_back(std::move(t));
      }
  return out;
}

}  // namespace incise::testing
