#pragma once
// Closed test surfaces with known volumes (tests/tetra only).
#include <catch2/catch.hpp>

#include <cmath>
#include <map>

#include "mesh/io/surface.h"
#include "mesh/tetrahedralize/tetrahedralize.h"

namespace incise::testing {

// Axis-aligned box [lo, lo + size], outward triangles.
inline SurfaceMesh box_surface(const Vec3& size, const Vec3& lo = Vec3::Zero()) {
  SurfaceMesh s;
  for (int i = 0; i < 8; ++i)
    s.vertices.push_back(lo + Vec3((i & 1) ? size.x() : 0, (i & 2) ? size.y() : 0, (i & 4) ? size.z() : 0));
  const int q[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (auto& f : q) {
    s.triangles.push_back({f[0], f[1], f[2]});
    s.triangles.push_back({f[0], f[2], f[3]});
  }
  return s;
}

// Icosphere: the icosahedron subdivided `level` times and projected on the sphere.
inline SurfaceMesh sphere_surface(double radius, int level, const Vec3& center = Vec3::Zero()) {
  const double t = (1 + std::sqrt(5.0)) / 2;
  SurfaceMesh s;
  s.vertices = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  s.triangles = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                 {11, 10, 2}, {10, 7, 6}, {7, 1, 8}, {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8},
                 {3, 8, 9}, {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
  for (int l = 0; l < level; ++l) {
    std::map<std::pair<int, int>, int> mid;
    auto midpoint = [&](int a, int b) {
      auto key = std::minmax(a, b);
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      s.vertices.push_back((s.vertices[a] + s.vertices[b]) / 2);
      return mid[key] = int(s.vertices.size()) - 1;
    };
    std::vector<std::array<int, 3>> next;
    for (auto [a, b, c] : s.triangles) {
      const int ab = midpoint(a, b), bc = midpoint(b, c), ca = midpoint(c, a);
      next.insert(next.end(), {{a, ab, ca}, {b, bc, ab}, {c, ca, bc}, {ab, bc, ca}});
    }
    s.triangles = std::move(next);
  }
  for (Vec3& v : s.vertices) v = center + radius * v.normalized();
  return s;
}

// Torus around the z axis: major radius R, minor radius r, n x m quads split in two.
inline SurfaceMesh torus_surface(double R, double r, int n, int m) {
  SurfaceMesh s;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < m; ++j) {
      const double u = 2 * M_PI * i / n, v = 2 * M_PI * j / m;
      s.vertices.emplace_back((R + r * std::cos(v)) * std::cos(u), (R + r * std::cos(v)) * std::sin(u), r * std::sin(v));
    }
  auto id = [&](int i, int j) { return ((i + n) % n) * m + (j + m) % m; };
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < m; ++j) {
      s.triangles.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
      s.triangles.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
    }
  if (enclosed_volume(s) < 0)
    for (auto& t : s.triangles) std::swap(t[1], t[2]);
  return s;
}

inline SurfaceMesh merged(const SurfaceMesh& a, const SurfaceMesh& b) {
  SurfaceMesh s = a;
  const int off = int(s.vertices.size());
  s.vertices.insert(s.vertices.end(), b.vertices.begin(), b.vertices.end());
  for (auto t : b.triangles) s.triangles.push_back({t[0] + off, t[1] + off, t[2] + off});
  return s;
}

// The invariants every output must satisfy.
inline void check_output(const TetMesh& m, double input_volume, double volume_tol) {
  REQUIRE(m.num_tets() > 0);
  m.validate({true, true});  // incidence, positive volumes, closed manifold boundary
  for (TetId t : m.tets()) REQUIRE(m.volume(t) > 0);
  for (const BoundaryFace& f : m.boundary_faces()) REQUIRE(f.tag == kTagSurface);
  INFO("volume ratio " << m.total_volume() / input_volume);
  CHECK(m.total_volume() == Approx(input_volume).epsilon(volume_tol));
}

}  // namespace incise::testing
