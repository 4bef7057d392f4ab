#include "quality/metrics.h"

#include <algorithm>
#include <cmath>

#include "mesh/errors.h"

namespace incise {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kRadToDeg = 180.0 / kPi;
// Solid angle at each corner of the regular tetrahedron: 3 acos(1/3) - pi = acos(23/27).
const double kRegularSolidAngle = std::acos(23.0 / 27.0);
const double kSqrt2 = std::sqrt(2.0);
const double kSqrt6 = std::sqrt(6.0);

constexpr MetricInfo kMetrics[kNumMetrics] = {
    {Metric::Volume, "volume", "volume", true, 0, 0},
    {Metric::MinDihedral, "min_dihedral", "min dihedral (deg)", true, 0, 90},
    {Metric::MaxDihedral, "max_dihedral", "max dihedral (deg)", false, 0, 180},
    {Metric::RadiusRatio, "radius_ratio", "radius ratio", true, 0, 1},
    {Metric::MeanRatio, "mean_ratio", "mean ratio", true, 0, 1},
    {Metric::VolumeLength, "volume_length", "volume-length", true, 0, 1},
    {Metric::AspectRatio, "aspect_ratio", "aspect ratio", false, 1, 10},
    {Metric::MinSolidAngle, "min_solid_angle", "min solid angle", true, 0, 1},
    {Metric::RadiusEdge, "radius_edge", "radius-edge ratio", false, 1, 10},
};

// Solid angle at the apex of vectors a, b, c given |a.(b x c)| (Van Oosterom & Strackee):
// atan2 keeps it accurate for tiny and for > pi angles alike.
double solid_angle(const Vec3& a, const Vec3& b, const Vec3& c, double abs_det) {
  double la = a.norm(), lb = b.norm(), lc = c.norm();
  double denom = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
  return 2.0 * std::atan2(abs_det, denom);
}

double inverse_clamped(double q) { return q > 1.0 / kMaxRatio ? 1.0 / q : kMaxRatio; }

}  // namespace

const MetricInfo& metric_info(Metric m) { return kMetrics[static_cast<int>(m)]; }
std::span<const MetricInfo> all_metrics() { return kMetrics; }

Metric parse_metric(std::string_view name) {
  std::string names;
  for (const MetricInfo& mi : kMetrics) {
    if (name == mi.name) return mi.metric;
    names += names.empty() ? "" : ", ";
    names += mi.name;
  }
  throw InvalidArgument("unknown metric '" + std::string(name) + "' (one of: " + names + ")");
}

double metric_value(const TetQuality& q, Metric m) {
  switch (m) {
    case Metric::Volume: return q.volume;
    case Metric::MinDihedral: return q.min_dihedral;
    case Metric::MaxDihedral: return q.max_dihedral;
    case Metric::RadiusRatio: return q.radius_ratio;
    case Metric::MeanRatio: return q.mean_ratio;
    case Metric::VolumeLength: return q.volume_length;
    case Metric::AspectRatio: return q.aspect_ratio;
    case Metric::MinSolidAngle: return q.min_solid_angle;
    case Metric::RadiusEdge: return q.radius_edge;
  }
  return 0;
}

TetQuality tet_quality(const Vec3& p0, const Vec3& p1, const Vec3& p2, const Vec3& p3) {
  TetQuality q;
  // Direct differences: each edge is rounded once, whatever the offset of the tet.
  // Order: 01, 02, 03, 12, 13, 23.
  Vec3 e[6] = {p1 - p0, p2 - p0, p3 - p0, p2 - p1, p3 - p1, p3 - p2};
  double l2max = 0, l2min = e[0].squaredNorm();
  for (const Vec3& x : e) {
    l2max = std::max(l2max, x.squaredNorm());
    l2min = std::min(l2min, x.squaredNorm());
  }
  q.min_edge = std::sqrt(l2min);
  q.max_edge = std::sqrt(l2max);
  if (!(q.max_edge > 0) || !std::isfinite(q.max_edge)) return q;  // coincident points

  // Rescale by an exact power of two so the longest edge is in [1, 2): every product
  // below is O(1), far from overflow and underflow at any scale.
  const int k = std::ilogb(q.max_edge);
  const double s = std::ldexp(1.0, -k);
  for (Vec3& x : e) x *= s;
  double l2[6], sum_l2 = 0;
  for (int i = 0; i < 6; ++i) sum_l2 += (l2[i] = e[i].squaredNorm());
  const double lmax = q.max_edge * s, lmin = q.min_edge * s;

  const double det = e[0].dot(e[1].cross(e[2]));  // 6 V (scaled)
  q.volume = std::ldexp(det / 6.0, 3 * k);
  if (det == 0) return q;  // flat: every shape metric 0, dihedrals 0 and 180

  // Twice the area vectors of the faces opposite vertex 0..3 (outward when det > 0).
  const Vec3 n[4] = {e[3].cross(e[4]), e[2].cross(e[1]), e[0].cross(e[2]), e[1].cross(e[0])};
  double area_sum = 0;  // twice the total area
  for (const Vec3& x : n) area_sum += x.norm();

  // Dihedral angle at edge (i,j) is between the two faces opposite the other vertices.
  static constexpr int kEdgeFaces[6][2] = {{2, 3}, {1, 3}, {1, 2}, {0, 3}, {0, 2}, {0, 1}};
  bool zero_face = false;
  for (const Vec3& x : n) zero_face |= x.squaredNorm() == 0;
  if (!zero_face) {
    double dmin = 180, dmax = 0;
    for (const auto& f : kEdgeFaces) {
      const Vec3& a = n[f[0]];
      const Vec3& b = n[f[1]];
      double d = std::atan2(a.cross(b).norm(), -a.dot(b)) * kRadToDeg;
      dmin = std::min(dmin, d);
      dmax = std::max(dmax, d);
    }
    q.min_dihedral = dmin;
    q.max_dihedral = dmax;
  }

  const double sign = det > 0 ? 1.0 : -1.0;
  const double adet = std::abs(det);
  const double vol = adet / 6.0;  // |V| (scaled)

  q.mean_ratio = sign * 12.0 * std::pow(3.0 * vol, 2.0 / 3.0) / sum_l2;
  const double lrms = std::sqrt(sum_l2 / 6.0);
  q.volume_length = sign * 6.0 * kSqrt2 * vol / (lrms * lrms * lrms);

  // Circumcentre relative to p0 is alpha / (2 det), so R = |alpha| / (2 |det|).
  const Vec3 alpha = l2[0] * e[1].cross(e[2]) + l2[1] * e[2].cross(e[0]) + l2[2] * e[0].cross(e[1]);
  const double alen = alpha.norm();
  // r_in = 3|V| / A = |det| / area_sum (area_sum is 2A).
  const double r_in = adet / area_sum;
  if (alen > 0) {
    const double R = alen / (2.0 * adet);
    q.radius_ratio = sign * 3.0 * r_in / R;
    q.radius_edge = inverse_clamped((kSqrt6 / 4.0) * lmin / R);
  }
  q.aspect_ratio = inverse_clamped(2.0 * kSqrt6 * r_in / lmax);

  const Vec3 m0 = -e[0], m1 = -e[1], m2 = -e[2], m3 = -e[3], m4 = -e[4], m5 = -e[5];
  double omega = solid_angle(e[0], e[1], e[2], adet);
  omega = std::min(omega, solid_angle(m0, e[3], e[4], adet));
  omega = std::min(omega, solid_angle(m1, m3, e[5], adet));
  omega = std::min(omega, solid_angle(m2, m4, m5, adet));
  q.min_solid_angle = sign * omega / kRegularSolidAngle;
  return q;
}

TetQuality tet_quality(const TetMesh& mesh, TetId t, std::span<const Vec3> positions) {
  const auto& v = mesh.tet_vertices(t);
  if (positions.empty()) return tet_quality(mesh.rest(v[0]), mesh.rest(v[1]), mesh.rest(v[2]), mesh.rest(v[3]));
  return tet_quality(positions[v[0].idx()], positions[v[1].idx()], positions[v[2].idx()], positions[v[3].idx()]);
}

QualityRange quality_range(const TetMesh& mesh, double below_degrees) {
  QualityRange r;
  for (TetId t : mesh.tets()) {
    const TetQuality q = tet_quality(mesh, t);
    r.min_dihedral = std::min(r.min_dihedral, q.min_dihedral);
    r.max_dihedral = std::max(r.max_dihedral, q.max_dihedral);
    r.min_radius_ratio = std::min(r.min_radius_ratio, q.radius_ratio);
    r.below += q.min_dihedral < below_degrees;
  }
  return r;
}

}  // namespace incise
