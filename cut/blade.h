#pragma once
// Blade geometry: what a cut step sweeps. Every blade reduces to a list of triangles (the cut
// surface of one step), so the cutter has one code path for swept segments, planes and given
// surfaces.
#include <array>
#include <vector>

#include "mesh/tet_mesh.h"

namespace incise {

struct CutTriangle {
  std::array<Vec3, 3> p;
  Vec3 normal() const { return (p[1] - p[0]).cross(p[2] - p[0]); }  // not normalized
  double area() const { return 0.5 * normal().norm(); }
};

// The scalpel's edge: segment a-b.
struct BladeSegment {
  Vec3 a = Vec3::Zero(), b = Vec3::Zero();
};

// The surface a segment sweeps moving from `from` to `to` (translation and rotation): the
// quad a0 b0 b1 a1 split along a0-b1 into two triangles. Degenerate (zero-area) triangles are
// dropped, so a blade that does not move sweeps nothing. The quad is bilinear when the blade
// rotates out of its plane; two triangles are the piecewise-planar surface through its
// corners, which is what the step cuts.
std::vector<CutTriangle> swept_triangles(const BladeSegment& from, const BladeSegment& to);

// A plane (point, normal) as two triangles covering the box [lo, hi] (inflated by 10%), so a
// plane cut is a through-cut of everything in the box.
std::vector<CutTriangle> plane_triangles(const Vec3& point, const Vec3& normal, const Vec3& lo, const Vec3& hi);

}  // namespace incise
