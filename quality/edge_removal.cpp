#include "quality/edge_removal.h"

#include <functional>

namespace incise {

std::array<std::array<Vec3, 4>, 2> ring_triangle_tets(std::span<const Vec3> ring, const Vec3& a, const Vec3& b,
                                                      int i, int j, int k) {
  return {{{ring[i], ring[j], ring[k], b}, {ring[i], ring[k], ring[j], a}}};
}

RingTriangulation best_ring_triangulation(std::span<const Vec3> ring, const Vec3& a, const Vec3& b,
                                          const AngleTargets& targets, double floor) {
  const int n = static_cast<int>(ring.size());
  // best[i][j]: worst quality of the best triangulation of sub-polygon c_i..c_j (j - i >= 2);
  // apex[i][j]: its triangle on side (i,j).
  std::vector<AngleQuality> best(n * n);
  std::vector<int> apex(n * n, -1);
  auto at = [n](int i, int j) { return i * n + j; };
  for (int len = 2; len < n; ++len)
    for (int i = 0; i + len < n; ++i) {
      const int j = i + len;
      AngleQuality& out = best[at(i, j)];
      out.q = -1e300;
      for (int k = i + 1; k < j; ++k) {
        // A choice whose worst is at most the floor is never the best of a triangulation above
        // the floor (the worst of a whole is the smallest of its parts' worst): skipped, which
        // leaves every choice above the floor, and so the result there, as it was.
        if ((k - i >= 2 && best[at(i, k)].q <= floor) || (j - k >= 2 && best[at(k, j)].q <= floor)) continue;
        AngleQuality w;
        bool low = false;
        for (const auto& t : ring_triangle_tets(ring, a, b, i, k, j)) {
          w.combine(angle_quality(t[0], t[1], t[2], t[3], targets));
          if ((low = w.q <= floor)) break;
        }
        if (low) continue;
        if (k - i >= 2) w.combine(best[at(i, k)]);
        if (j - k >= 2) w.combine(best[at(k, j)]);
        if (w.q > out.q) {
          out = w;
          apex[at(i, j)] = k;
        }
      }
    }
  RingTriangulation r;
  r.worst = best[at(0, n - 1)];
  if (r.worst.q <= floor) return r;  // nothing above the floor (apexes may be missing)
  std::function<void(int, int)> collect = [&](int i, int j) {
    if (j - i < 2) return;
    const int k = apex[at(i, j)];
    r.triangles.push_back({i, k, j});
    collect(i, k);
    collect(k, j);
  };
  collect(0, n - 1);
  return r;
}

}  // namespace incise
