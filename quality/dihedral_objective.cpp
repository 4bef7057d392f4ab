#include "quality/dihedral_objective.h"

#include <algorithm>
#include <cmath>

namespace incise {

void AngleQuality::combine(const AngleQuality& o) {
  q = std::min(q, o.q);
  min_dihedral = std::min(min_dihedral, o.min_dihedral);
  max_dihedral = std::max(max_dihedral, o.max_dihedral);
  radius_ratio = std::min(radius_ratio, o.radius_ratio);
}

namespace {
// One body for angle_quality() and its parts: the angles (q, min and max dihedral) and the
// radius ratio, each computed with exactly the same operations as in the whole, so the parts
// give the whole's values bit for bit.
constexpr int kAngles = 1, kRadius = 2, kAll = kAngles | kRadius;
template <int kParts>
inline AngleQuality angle_quality_impl(const Vec3& p0, const Vec3& p1, const Vec3& p2, const Vec3& p3,
                                       const AngleTargets& t) {
  const Vec3 p[4] = {p0, p1, p2, p3};
  // Edges by direct differences, rescaled so the longest is about 1: scale-free from 1e-8 to 1e8.
  const Vec3 e1 = p1 - p0, e2 = p2 - p0, e3 = p3 - p0;
  const double vol = e1.dot(e2.cross(e3));
  AngleQuality out;
  if (!(vol > 0)) {
    out.q = -1;
    out.min_dihedral = 0;
    out.max_dihedral = 180;
    out.radius_ratio = 0;
    return out;
  }
  // The longest edge: one square root of the largest squared length (sqrt is correctly
  // rounded and monotone, so this equals the largest of the six norms exactly).
  const double lmax = std::sqrt(std::max({e1.squaredNorm(), e2.squaredNorm(), e3.squaredNorm(),
                                          (p2 - p1).squaredNorm(), (p3 - p1).squaredNorm(), (p3 - p2).squaredNorm()}));
  const double s = 1.0 / lmax;
  // Outward normals of the faces opposite each vertex.
  Vec3 n[4];
  for (int f = 0; f < 4; ++f) {
    const Vec3& a = p[kFaceLocal[f][0]];
    const Vec3 u = (p[kFaceLocal[f][1]] - a) * s, w = (p[kFaceLocal[f][2]] - a) * s;
    n[f] = u.cross(w);
  }
  constexpr double kDeg = 180.0 / 3.14159265358979323846;
  // The extreme angles by their cosines (cheap), then atan2 on those two only (accurate near
  // 0 and 180 degrees, where slivers live). The dihedral angle at the edge shared by faces i
  // and j (opposite vertices i and j) is pi minus the angle between their outward normals.
  double inv[4];
  for (int f = 0; f < 4; ++f) inv[f] = 1.0 / n[f].norm();
  if constexpr ((kParts & kAngles) != 0) {
    double cmax = -2, cmin = 2;
    int imax = 0, jmax = 1, imin = 0, jmin = 1;
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j) {
        const double c = -n[i].dot(n[j]) * inv[i] * inv[j];
        if (c > cmax) cmax = c, imax = i, jmax = j;  // smallest angle
        if (c < cmin) cmin = c, imin = i, jmin = j;  // largest angle
      }
    out.min_dihedral = std::atan2(n[imax].cross(n[jmax]).norm(), -n[imax].dot(n[jmax])) * kDeg;
    out.max_dihedral = std::atan2(n[imin].cross(n[jmin]).norm(), -n[imin].dot(n[jmin])) * kDeg;
    out.q = std::min(out.min_dihedral / t.min_deg, (180 - out.max_dihedral) / (180 - t.max_deg));
  }
  if constexpr ((kParts & kRadius) != 0) {
    // Radius ratio 3 r_in / R_circ (scaled edges): r_in = 3V / area, R from the circumcentre
    // offset (|a|^2 (b x c) + |b|^2 (c x a) + |c|^2 (a x b)) / (2 a.(b x c)).
    const Vec3 a = e1 * s, b = e2 * s, c = e3 * s;
    const double v6 = a.dot(b.cross(c));
    const double area = 0.5 * (1 / inv[0] + 1 / inv[1] + 1 / inv[2] + 1 / inv[3]);
    const double r_in = v6 / (2 * area);
    const double r_circ =
        (a.squaredNorm() * b.cross(c) + b.squaredNorm() * c.cross(a) + c.squaredNorm() * a.cross(b)).norm() / (2 * v6);
    out.radius_ratio = r_circ > 0 ? std::min(1.0, 3 * r_in / r_circ) : 0;
  }
  return out;
}
}  // namespace

AngleQuality angle_quality(const Vec3& p0, const Vec3& p1, const Vec3& p2, const Vec3& p3, const AngleTargets& t) {
  return angle_quality_impl<kAll>(p0, p1, p2, p3, t);
}

AngleQuality angle_quality_angles(const Vec3& p0, const Vec3& p1, const Vec3& p2, const Vec3& p3,
                                  const AngleTargets& t) {
  return angle_quality_impl<kAngles>(p0, p1, p2, p3, t);
}

double angle_radius_ratio(const Vec3& p0, const Vec3& p1, const Vec3& p2, const Vec3& p3) {
  return angle_quality_impl<kRadius>(p0, p1, p2, p3, AngleTargets{}).radius_ratio;
}

double angle_q(const Vec3& p0, const Vec3& p1, const Vec3& p2, const Vec3& p3, const AngleTargets& t) {
  return angle_quality_impl<kAngles>(p0, p1, p2, p3, t).q;
}

AngleQuality angle_quality(const TetMesh& mesh, TetId t, const AngleTargets& targets) {
  const auto& v = mesh.tet_vertices(t);
  return angle_quality(mesh.rest(v[0]), mesh.rest(v[1]), mesh.rest(v[2]), mesh.rest(v[3]), targets);
}

AngleQuality angle_quality(const TetMesh& mesh, std::span<const std::array<VertexId, 4>> tets,
                           const AngleTargets& targets) {
  AngleQuality out;
  for (const auto& v : tets)
    out.combine(angle_quality(mesh.rest(v[0]), mesh.rest(v[1]), mesh.rest(v[2]), mesh.rest(v[3]), targets));
  return out;
}

bool better(const AngleQuality& after, const AngleQuality& before, const AngleTargets& t) {
  return after.q > before.q + 1e-6 && after.min_dihedral >= std::min(before.min_dihedral, t.min_deg) &&
         after.max_dihedral <= std::max({before.max_dihedral, t.max_deg, t.max_deg_cap}) &&
         after.radius_ratio >= std::min(before.radius_ratio, t.radius_ratio_floor);
}

}  // namespace incise
