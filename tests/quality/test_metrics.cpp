// Per-tet metrics: golden values, a textbook reference implementation, invariance under
// rigid motions and extreme scales, orientation sign, degenerate tets.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <random>

#include <Eigen/Dense>

#include "mesh/errors.h"
#include "quality/metrics.h"
#include "testing/draws.h"

using namespace incise;
using incise::testing::draw_vec3;

namespace {

constexpr double kPi = 3.14159265358979323846;

struct Tet {
  Vec3 p[4];
};

TetQuality quality(const Tet& t) { return tet_quality(t.p[0], t.p[1], t.p[2], t.p[3]); }

// Regular tetrahedron with edge 2 sqrt(2), positively oriented.
Tet regular() { return {{Vec3(1, 1, 1), Vec3(-1, 1, -1), Vec3(1, -1, -1), Vec3(-1, -1, 1)}}; }
Tet kuhn() { return {{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(1, 1, 1)}}; }

bool close_rel(double a, double b, double tol) { return std::abs(a - b) <= tol * std::max(1.0, std::max(std::abs(a), std::abs(b))); }

// Every metric of a (a transformed tet) and b (the original) agree to relative tolerance
// tol; the transform scales volumes by vs.
void require_same(const TetQuality& a, const TetQuality& b, double tol, double vs = 1.0) {
  INFO("volume " << a.volume << " vs " << b.volume << " * " << vs);
  CHECK(std::abs(a.volume - b.volume * vs) <= tol * std::abs(b.volume * vs));
  for (const MetricInfo& mi : all_metrics()) {
    if (mi.metric == Metric::Volume) continue;
    INFO(mi.name << ": " << metric_value(a, mi.metric) << " vs " << metric_value(b, mi.metric));
    CHECK(close_rel(metric_value(a, mi.metric), metric_value(b, mi.metric), tol));
  }
}

// Textbook formulas with none of the care: circumcentre by a linear solve, dihedral angles
// by acos of face normals, solid angles by the spherical excess of the dihedral angles.
struct Reference {
  double volume, radius_ratio, mean_ratio, volume_length, aspect_ratio, radius_edge, min_solid_angle;
  double dihedral[6];
};
Reference reference(const Tet& t) {
  Reference r{};
  const Vec3* p = t.p;
  r.volume = (p[1] - p[0]).dot((p[2] - p[0]).cross(p[3] - p[0])) / 6.0;
  Eigen::Matrix3d A;
  Eigen::Vector3d b;
  for (int i = 0; i < 3; ++i) {
    A.row(i) = 2.0 * (p[i + 1] - p[0]).transpose();
    b[i] = p[i + 1].squaredNorm() - p[0].squaredNorm();
  }
  Vec3 c = A.colPivHouseholderQr().solve(b);
  double R = (c - p[0]).norm();
  double area = 0;
  Vec3 normal[4];
  static const int fv[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  for (int f = 0; f < 4; ++f) {
    Vec3 n = (p[fv[f][1]] - p[fv[f][0]]).cross(p[fv[f][2]] - p[fv[f][0]]);
    area += 0.5 * n.norm();
    normal[f] = n.normalized() * (r.volume > 0 ? 1 : -1);  // outward
  }
  double V = std::abs(r.volume), rin = 3 * V / area;
  double sum_l2 = 0, lmin = 1e300, lmax = 0;
  for (int i = 0; i < 4; ++i)
    for (int j = i + 1; j < 4; ++j) {
      double l = (p[i] - p[j]).norm();
      sum_l2 += l * l;
      lmin = std::min(lmin, l);
      lmax = std::max(lmax, l);
    }
  double s = r.volume > 0 ? 1 : -1;
  r.radius_ratio = s * 3 * rin / R;
  r.mean_ratio = s * 12 * std::pow(3 * V, 2.0 / 3.0) / sum_l2;
  r.volume_length = s * 6 * std::sqrt(2.0) * V / std::pow(sum_l2 / 6, 1.5);
  r.aspect_ratio = lmax / (2 * std::sqrt(6.0) * rin);
  r.radius_edge = R / lmin / (std::sqrt(6.0) / 4);
  // Edge (i,j) lies in the faces opposite the two other vertices k, l.
  int e = 0;
  double dih[4][4] = {};
  for (int i = 0; i < 4; ++i)
    for (int j = i + 1; j < 4; ++j) {
      int kl[2], m = 0;
      for (int k = 0; k < 4; ++k)
        if (k != i && k != j) kl[m++] = k;
      dih[i][j] = dih[j][i] = r.dihedral[e++] = kPi - std::acos(normal[kl[0]].dot(normal[kl[1]]));
    }
  double omega = 1e300;
  for (int i = 0; i < 4; ++i) {
    double sum = 0;
    for (int j = 0; j < 4; ++j) sum += j != i ? dih[i][j] : 0;
    omega = std::min(omega, sum - kPi);
  }
  r.min_solid_angle = s * omega / std::acos(23.0 / 27.0);
  for (double& d : r.dihedral) d *= 180 / kPi;
  return r;
}

Tet random_tet(std::mt19937& rng, double min_mean_ratio) {
  std::uniform_real_distribution<double> u(-1, 1);
  for (;;) {
    Tet t;
    for (Vec3& p : t.p) p = draw_vec3(u, rng);
    if (std::abs(quality(t).mean_ratio) >= min_mean_ratio) return t;
  }
}

}  // namespace

TEST_CASE("regular tetrahedron scores 1 on every normalized metric", "[quality][metrics]") {
  const TetQuality q = quality(regular());
  const double a = 2 * std::sqrt(2.0);
  CHECK(q.volume == Approx(a * a * a / (6 * std::sqrt(2.0))).epsilon(1e-14));
  const double dih = std::acos(1.0 / 3.0) * 180 / kPi;
  CHECK(q.min_dihedral == Approx(dih).epsilon(1e-13));
  CHECK(q.max_dihedral == Approx(dih).epsilon(1e-13));
  for (Metric m : {Metric::RadiusRatio, Metric::MeanRatio, Metric::VolumeLength, Metric::AspectRatio,
                   Metric::MinSolidAngle, Metric::RadiusEdge}) {
    INFO(metric_info(m).name);
    CHECK(metric_value(q, m) == Approx(1.0).epsilon(1e-13));
  }
  CHECK(q.min_edge == Approx(a).epsilon(1e-15));
  CHECK(q.max_edge == Approx(a).epsilon(1e-15));
}

TEST_CASE("Kuhn tetrahedron golden values", "[quality][metrics]") {
  const TetQuality q = quality(kuhn());
  CHECK(q.volume == Approx(1.0 / 6).epsilon(1e-15));
  CHECK(q.radius_ratio == Approx(0.717439).margin(5e-7));
  CHECK(q.mean_ratio == Approx(0.755953).margin(5e-7));
  CHECK(q.volume_length == Approx(0.657267).margin(5e-7));
  CHECK(q.min_dihedral == Approx(45).epsilon(1e-13));
  CHECK(q.max_dihedral == Approx(90).epsilon(1e-13));
  // aspect = l_max A / (6 sqrt(6) V) = sqrt(3) (1 + sqrt(2)) / sqrt(6); R = sqrt(3)/2, l_min = 1.
  CHECK(q.aspect_ratio == Approx((1 + std::sqrt(2.0)) / std::sqrt(2.0)).epsilon(1e-14));
  CHECK(q.radius_edge == Approx(std::sqrt(2.0)).epsilon(1e-14));
  // The cube corner (pi/2 sr) is shared by its 6 Kuhn tets: pi/12 at (0,0,0) is the smallest.
  CHECK(q.min_solid_angle == Approx(kPi / 12 / std::acos(23.0 / 27)).epsilon(1e-14));
  // And against the spherical excess of the reference dihedral angles.
  CHECK(q.min_solid_angle == Approx(reference(kuhn()).min_solid_angle).epsilon(1e-12));
}

TEST_CASE("metrics agree with a textbook implementation on random tets", "[quality][metrics]") {
  std::mt19937 rng(7);
  for (int it = 0; it < 500; ++it) {
    Tet t = random_tet(rng, 0.05);
    TetQuality q = quality(t);
    Reference r = reference(t);
    INFO("tet " << it);
    CHECK(q.volume == Approx(r.volume).epsilon(1e-12));
    CHECK(q.radius_ratio == Approx(r.radius_ratio).epsilon(1e-9));
    CHECK(q.mean_ratio == Approx(r.mean_ratio).epsilon(1e-12));
    CHECK(q.volume_length == Approx(r.volume_length).epsilon(1e-12));
    CHECK(q.aspect_ratio == Approx(r.aspect_ratio).epsilon(1e-10));
    CHECK(q.radius_edge == Approx(r.radius_edge).epsilon(1e-9));
    CHECK(q.min_solid_angle == Approx(r.min_solid_angle).epsilon(1e-8));
    CHECK(q.min_dihedral == Approx(*std::min_element(r.dihedral, r.dihedral + 6)).epsilon(1e-9));
    CHECK(q.max_dihedral == Approx(*std::max_element(r.dihedral, r.dihedral + 6)).epsilon(1e-9));
    // Normalization: the regular tet is the best of all.
    for (Metric m : {Metric::RadiusRatio, Metric::MeanRatio, Metric::VolumeLength, Metric::MinSolidAngle})
      CHECK(std::abs(metric_value(q, m)) <= 1 + 1e-12);
    CHECK(q.aspect_ratio >= 1 - 1e-12);
    CHECK(q.radius_edge >= 1 - 1e-12);
    CHECK(q.min_dihedral <= std::acos(1.0 / 3.0) * 180 / kPi + 1e-9);
    CHECK(q.max_dihedral >= std::acos(1.0 / 3.0) * 180 / kPi - 1e-9);
  }
}

TEST_CASE("metrics are invariant under translation, rotation and extreme scales", "[quality][metrics]") {
  std::mt19937 rng(11);
  std::vector<Tet> tets = {regular(), kuhn()};
  for (int i = 0; i < 50; ++i) tets.push_back(random_tet(rng, 0.02));
  // Dyadic coordinates (multiples of 2^-10 in [-4, 4]) survive a 1e8 offset exactly; an
  // arbitrary coordinate would lose ~1e-8 in the input itself.
  std::uniform_int_distribution<int> di(-4096, 4096);
  for (int i = 0; i < 20; ++i) {
    Tet t;
    for (Vec3& p : t.p) p = draw_vec3(di, rng) / 1024.0;
    if (std::abs(quality(t).mean_ratio) > 0.02) tets.push_back(t);
  }
  const Eigen::Matrix3d rot = Eigen::Quaterniond(0.3, -0.5, 0.7, 0.2).normalized().toRotationMatrix();
  int idx = 0;
  for (const Tet& t : tets) {
    INFO("tet " << idx++);
    const TetQuality q = quality(t);
    Tet moved, rotated, big, small;
    bool dyadic = true;
    for (int k = 0; k < 4; ++k) {
      dyadic &= (t.p[k] * 1024.0).array().round().matrix() == t.p[k] * 1024.0;
      moved.p[k] = t.p[k] + Vec3(1e8, -3e8, 5e7);
      rotated.p[k] = rot * t.p[k] + Vec3(0.25, -7, 3);
      big.p[k] = t.p[k] * 1e8;
      small.p[k] = t.p[k] * 1e-8;
    }
    if (dyadic) require_same(quality(moved), q, 1e-15);
    require_same(quality(rotated), q, 1e-9);
    require_same(quality(big), q, 1e-9, 1e24);
    require_same(quality(small), q, 1e-9, 1e-24);
    // Scale and offset at once, far from the origin: 1e-8 sized tet at 1 (relative 1e-8
    // spacing is still ~1e8 ulps).
    Tet tiny_far;
    for (int k = 0; k < 4; ++k) tiny_far.p[k] = t.p[k] * std::ldexp(1.0, -27) + Vec3(1, 2, 3);
    if (dyadic) require_same(quality(tiny_far), q, 1e-15, std::ldexp(1.0, -81));
  }
}

TEST_CASE("swapping two vertices flips the sign of the signed metrics only", "[quality][metrics]") {
  std::mt19937 rng(3);
  std::vector<Tet> tets = {regular(), kuhn()};
  for (int i = 0; i < 50; ++i) tets.push_back(random_tet(rng, 0.01));
  for (const Tet& t : tets) {
    Tet s = t;
    std::swap(s.p[1], s.p[2]);
    TetQuality a = quality(t), b = quality(s);
    REQUIRE(a.volume != 0);
    CHECK(b.volume == Approx(-a.volume).epsilon(1e-14));
    for (Metric m : {Metric::RadiusRatio, Metric::MeanRatio, Metric::VolumeLength, Metric::MinSolidAngle}) {
      INFO(metric_info(m).name);
      CHECK(metric_value(b, m) == Approx(-metric_value(a, m)).epsilon(1e-12));
      // Positive orientation scores > 0, inverted < 0.
      CHECK((a.volume > 0) == (metric_value(a, m) > 0));
    }
    for (Metric m : {Metric::MinDihedral, Metric::MaxDihedral, Metric::AspectRatio, Metric::RadiusEdge})
      CHECK(metric_value(b, m) == Approx(metric_value(a, m)).epsilon(1e-12));
  }
}

TEST_CASE("degenerate tets give finite values: 0 for shape metrics, 0/180 for angles", "[quality][metrics]") {
  const std::vector<Tet> flat = {
      {{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(0, 1, 0)}},            // square
      {{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0.2, 0.2, 0)}},        // point in triangle
      {{Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3(2, 2, 2), Vec3(3, 3, 3)}},            // collinear
      {{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)}},            // repeated vertex
      {{Vec3(1, 2, 3), Vec3(1, 2, 3), Vec3(1, 2, 3), Vec3(1, 2, 3)}},            // one point
      {{Vec3(0, 0, 0), Vec3(0, 0, 0), Vec3(0, 0, 0), Vec3(0, 0, 1e-300)}},       // three coincide
      {{Vec3(1e8, 1e8, 0), Vec3(1e8 + 1, 1e8, 0), Vec3(1e8, 1e8 + 1, 0), Vec3(1e8 + 7, 1e8 - 3, 0)}},
  };
  for (std::size_t i = 0; i < flat.size(); ++i) {
    INFO("flat tet " << i);
    TetQuality q = quality(flat[i]);
    CHECK(q.volume == 0);
    CHECK(q.min_dihedral == 0);
    CHECK(q.max_dihedral == 180);
    for (Metric m : {Metric::RadiusRatio, Metric::MeanRatio, Metric::VolumeLength, Metric::MinSolidAngle})
      CHECK(metric_value(q, m) == 0);
    CHECK(q.aspect_ratio == kMaxRatio);
    CHECK(q.radius_edge == kMaxRatio);
  }
  // Nearly flat, at every scale: finite, tiny, and the right sign.
  for (double h : {1e-6, 1e-12, 1e-20, 1e-100, -1e-12}) {
    for (double scale : {1e-8, 1.0, 1e8}) {
      Tet t{{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0.3, 0.3, h)}};
      for (Vec3& p : t.p) p *= scale;
      TetQuality q = quality(t);
      INFO("h " << h << " scale " << scale);
      for (const MetricInfo& mi : all_metrics()) CHECK(std::isfinite(metric_value(q, mi.metric)));
      CHECK((q.volume > 0) == (h > 0));
      CHECK(std::abs(q.mean_ratio) < 1e-3);
      CHECK((q.mean_ratio > 0) == (h > 0));
      CHECK(q.min_dihedral < 1e-3);
      CHECK(q.max_dihedral > 180 - 1e-3);
      CHECK(q.aspect_ratio > 1e5);
    }
  }
}

TEST_CASE("flattening a regular tet lowers every quality monotonically", "[quality][metrics]") {
  TetQuality prev = quality(regular());
  for (double s = 0.9; s > 0.01; s *= 0.8) {
    Tet t = regular();
    for (Vec3& p : t.p) p.z() *= s;  // squash along z (apex pairs at z = +-1)
    TetQuality q = quality(t);
    for (Metric m : {Metric::RadiusRatio, Metric::MeanRatio, Metric::VolumeLength, Metric::MinSolidAngle,
                     Metric::MinDihedral})
      CHECK(metric_value(q, m) < metric_value(prev, m));
    for (Metric m : {Metric::AspectRatio, Metric::RadiusEdge, Metric::MaxDihedral})
      CHECK(metric_value(q, m) > metric_value(prev, m));
    prev = q;
  }
}

TEST_CASE("metric names parse and unknown names are rejected", "[quality][metrics]") {
  for (const MetricInfo& mi : all_metrics()) CHECK(parse_metric(mi.name) == mi.metric);
  CHECK_THROWS_AS(parse_metric("shape"), InvalidArgument);
  CHECK_THROWS_WITH(parse_metric("shape"), Catch::Contains("mean_ratio"));
}
