// Edge removal's dynamic program against brute force over every triangulation of the ring.
#include <catch2/catch.hpp>

#include <cmath>
#include <functional>
#include <random>

#include "quality/edge_removal.h"
#include "testing/ring.h"

using namespace incise;

namespace {

using testing::all_triangulations;

AngleQuality worst_of(std::span<const Vec3> ring, const Vec3& a, const Vec3& b,
                      const std::vector<std::array<int, 3>>& tris, const AngleTargets& tg) {
  AngleQuality w;
  for (const auto& t : tris)
    for (const auto& x : ring_triangle_tets(ring, a, b, t[0], t[1], t[2]))
      w.combine(angle_quality(x[0], x[1], x[2], x[3], tg));
  return w;
}

}  // namespace

TEST_CASE("edge removal: the dynamic program finds the best ring triangulation", "[improve]") {
  std::mt19937 rng(7);
  const AngleTargets tg;
  const std::size_t catalan[] = {1, 1, 2, 5, 14, 42, 132, 429};  // C_0..C_7
  for (int n = 3; n <= 8; ++n)
    for (int trial = 0; trial < 20; ++trial) {
      // A ring around the z axis, counter-clockwise seen from b = top, radii and heights jittered.
      const testing::JitteredRing jr = testing::jittered_ring(n, rng);
      const std::vector<Vec3>& ring = jr.ring;
      const Vec3 &a = jr.below, &b = jr.above;
      const auto all = all_triangulations(0, n - 1);
      REQUIRE(all.size() == catalan[n - 2]);
      double brute = -1e300;
      for (const auto& t : all) brute = std::max(brute, worst_of(ring, a, b, t, tg).q);
      const RingTriangulation dp = best_ring_triangulation(ring, a, b, tg);
      REQUIRE(dp.triangles.size() == static_cast<std::size_t>(n - 2));
      CHECK(dp.worst.q == Approx(brute).margin(1e-12));
      // The reported worst is the worst of the triangulation returned.
      CHECK(worst_of(ring, a, b, dp.triangles, tg).q == Approx(dp.worst.q).margin(1e-12));
    }
}

TEST_CASE("edge removal: orientation of the built tets matches the mesh's convention", "[improve]") {
  // A regular ring around the z axis: a below, b above; every tet of the best triangulation
  // is positively oriented, so the measure is positive.
  std::vector<Vec3> ring;
  for (int i = 0; i < 5; ++i) ring.emplace_back(std::cos(2 * M_PI * i / 5), std::sin(2 * M_PI * i / 5), 0);
  const RingTriangulation dp = best_ring_triangulation(ring, Vec3(0, 0, -1), Vec3(0, 0, 1), AngleTargets{});
  CHECK(dp.worst.q > 0);
}
