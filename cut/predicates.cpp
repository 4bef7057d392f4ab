// CGAL stays in this file: the kernel headers are heavy and only the sign is needed.
#include "cut/predicates.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>

namespace incise {

int orient3d(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  using K = CGAL::Exact_predicates_inexact_constructions_kernel;
  using P = K::Point_3;
  // CGAL's orientation(p,q,r,s) is POSITIVE when s is on the positive side of the plane
  // (p,q,r) oriented so that (q-p, r-p, s-p) has positive determinant: the same convention.
  const CGAL::Orientation o = CGAL::orientation(P(a.x(), a.y(), a.z()), P(b.x(), b.y(), b.z()),
                                                P(c.x(), c.y(), c.z()), P(d.x(), d.y(), d.z()));
  return o == CGAL::POSITIVE ? 1 : (o == CGAL::NEGATIVE ? -1 : 0);
}

}  // namespace incise
