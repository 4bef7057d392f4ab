#pragma once
// Shared by the cut tests and the torture run: the invariants every cut step must keep.
#include <catch2/catch.hpp>

#include <cstdlib>
#include <iostream>
#include <map>
#include <unordered_set>
#include <cmath>
#include <vector>

#include "cut/cutter.h"
#include "mesh/tet_mesh.h"
#include "quality/components.h"
#include "testing/mesh_measures.h"  // label_volumes

namespace incise::testing {

inline double tagged_area(const TetMesh& m, std::uint16_t tag) {
  double a = 0;
  for (const auto& f : m.boundary_faces())
    if (f.tag == tag)
      a += 0.5 * (m.rest(f.vertices[1]) - m.rest(f.vertices[0])).cross(m.rest(f.vertices[2]) - m.rest(f.vertices[0])).norm();
  return a;
}

// Area a closed polygon encloses in its points' x-y plane (the shoelace formula); the points
// are anything with x() and y() (Vec3, Eigen::Vector2d).
template <class Point>
double polygon_area_xy(const std::vector<Point>& p) {
  double a = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    const Point& u = p[i];
    const Point& v = p[(i + 1) % p.size()];
    a += u.x() * v.y() - v.x() * u.y();
  }
  return 0.5 * std::abs(a);
}

// validate() with orientation and a closed manifold boundary, and every label's volume
// unchanged (subdivision mode) to `rel` of the total, plus `moved`: what the improvement's
// tolerance-mode contractions say they moved (their reports' volume_change, summed).
inline void check_cut_invariants(const TetMesh& m, const std::map<int, double>& vol0, double rel = 1e-9,
                                 double moved = 0) {
  REQUIRE_NOTHROW(m.validate({true, true}));
  double total = 0;
  for (const auto& [l, v] : vol0) total += v;
  const auto vol = label_volumes(m);
  REQUIRE(vol.size() == vol0.size());
  for (const auto& [l, v] : vol0) REQUIRE(std::abs(vol.at(l) - v) <= rel * total + moved);
}

// Area of the parallelogram swept by segment a-b moving by d, clipped to the box [lo, hi]
// (Sutherland-Hodgman against the six sides): the area a straight cut must open in a box.
// Each detached part a step reports is what the mesh holds after the step: live tets forming a
// whole face-connected part (the step's improvement replaces tets; a stale list once left a
// part's new tets behind when a scene removed it).
inline void check_fragments(const TetMesh& m, const CutStepReport& r) {
  for (const Fragment& f : r.fragments) {
    std::unordered_set<std::uint32_t> in;
    for (TetId t : f.tets) {
      REQUIRE(m.is_alive(t));
      in.insert(t.idx());
    }
    REQUIRE(in.size() == f.tets.size());
    for (TetId t : f.tets)
      for (int k = 0; k < 4; ++k) {
        const TetId n = m.neighbor(t, k);
        REQUIRE((!n.is_valid() || in.count(n.idx())));
      }
  }
}

inline double swept_area_in_box(const Vec3& a, const Vec3& b, const Vec3& d, const Vec3& lo, const Vec3& hi) {
  std::vector<Vec3> poly = {a, b, b + d, a + d};
  for (int axis = 0; axis < 3; ++axis)
    for (int side = 0; side < 2; ++side) {
      auto inside = [&](const Vec3& x) { return side == 0 ? x[axis] >= lo[axis] : x[axis] <= hi[axis]; };
      const double bound = side == 0 ? lo[axis] : hi[axis];
      std::vector<Vec3> out;
      for (std::size_t i = 0; i < poly.size(); ++i) {
        const Vec3 &p = poly[i], &q = poly[(i + 1) % poly.size()];
        if (inside(p)) out.push_back(p);
        if (inside(p) != inside(q)) out.push_back(p + (bound - p[axis]) / (q[axis] - p[axis]) * (q - p));
      }
      poly = std::move(out);
      if (poly.empty()) return 0;
    }
  Vec3 n = Vec3::Zero();
  for (std::size_t i = 1; i + 1 < poly.size(); ++i) n += (poly[i] - poly[0]).cross(poly[i + 1] - poly[0]);
  return 0.5 * n.norm();
}

}  // namespace incise::testing
