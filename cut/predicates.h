#pragma once
// Exact geometric predicates for the cutter's sign decisions (CGAL's filtered exact
// orientation). Points are only ever constructed in floating point; decisions about which
// side of a blade a vertex lies on are exact, so two tests of the same configuration never
// disagree.
#include "mesh/tet_mesh.h"

namespace incise {

// Sign of det(b-a, c-a, d-a): +1 when d lies on the side of triangle (a,b,c) its right-hand
// normal points to, -1 on the other side, 0 exactly coplanar. Exact for any finite input.
int orient3d(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);

}  // namespace incise
