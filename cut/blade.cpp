#include "cut/blade.h"

#include <algorithm>
#include <cmath>

#include "mesh/errors.h"

namespace incise {

namespace {
bool non_degenerate(const CutTriangle& t) {
  const double l2 = std::max({(t.p[1] - t.p[0]).squaredNorm(), (t.p[2] - t.p[1]).squaredNorm(),
                              (t.p[0] - t.p[2]).squaredNorm()});
  // Area relative to the longest edge squared: a needle has no surface worth cutting.
  return l2 > 0 && t.normal().norm() > 1e-12 * l2;
}
}  // namespace

std::vector<CutTriangle> swept_triangles(const BladeSegment& from, const BladeSegment& to) {
  std::vector<CutTriangle> out;
  for (const CutTriangle& t : {CutTriangle{{from.a, from.b, to.b}}, CutTriangle{{from.a, to.b, to.a}}})
    if (non_degenerate(t)) out.push_back(t);
  return out;
}

std::vector<CutTriangle> plane_triangles(const Vec3& point, const Vec3& normal, const Vec3& lo, const Vec3& hi) {
  const double nn = normal.norm();
  if (!(nn > 0) || !std::isfinite(nn)) throw InvalidArgument("cut plane: the normal must be a nonzero finite vector");
  const Vec3 n = normal / nn;
  // Two in-plane directions, then a square around the projection of the box centre large
  // enough to contain the box's section.
  const Vec3 u = (std::abs(n.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY()).cross(n).normalized();
  const Vec3 v = n.cross(u);
  const Vec3 c = 0.5 * (lo + hi);
  const Vec3 centre = c - n * n.dot(c - point);
  const double r = 1.1 * (hi - lo).norm() + 1e-300;
  const Vec3 q0 = centre - r * u - r * v, q1 = centre + r * u - r * v, q2 = centre + r * u + r * v,
             q3 = centre - r * u + r * v;
  return {CutTriangle{{q0, q1, q2}}, CutTriangle{{q0, q2, q3}}};
}

}  // namespace incise
