#pragma once
// Shared by the uniform and graded isosurface stuffing tests: analytic shapes with their
// volumes and boundary topology, an independent dihedral-angle measure, and one check of
// everything stuffing promises. Include after defining `constexpr bool kGraded` (the
// default mode of stuff() and check()); everything here has internal linkage, one copy
// per test file.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <numeric>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "mesh/errors.h"
#include "mesh/isosurface_stuffing.h"

namespace {

using namespace incise;

using Sdf = std::function<double(const Vec3&)>;
constexpr double kPi = 3.14159265358979323846;

// Measured over every mesh this test file builds (reported at the end).
double g_min_dihedral = 180, g_max_dihedral = 0;

struct Shape {
  const char* name;
  Sdf sdf;
  double volume;   // analytic volume of {sdf < 0}
  Vec3 lo, hi;     // domain box with a margin
  double size;     // characteristic size (cell sizes are fractions of it)
  int components;  // connected components of the solid
  int euler;       // Euler characteristic of the boundary surface
  Sdf distance{};  // true distance where sdf is not one (empty: sdf)
};

Sdf sphere(const Vec3& c, double r) {
  return [=](const Vec3& p) { return (p - c).norm() - r; };
}
// 1-Lipschitz with the exact zero set: |D p| - 1 has gradient norm <= max(1/r_i).
Sdf ellipsoid(const Vec3& radii) {
  double m = radii.minCoeff();
  return [=](const Vec3& p) { return (p.cwiseQuotient(radii).norm() - 1.0) * m; };
}
Sdf torus(double big_r, double small_r) {
  return [=](const Vec3& p) {
    double q = std::hypot(p.x(), p.y()) - big_r;
    return std::hypot(q, p.z()) - small_r;
  };
}
// Exact box distance, centred at c with half extents b, rotated by rot (world = rot * local).
Sdf box(const Vec3& c, const Vec3& b, const Eigen::Matrix3d& rot = Eigen::Matrix3d::Identity()) {
  return [=](const Vec3& p) {
    Vec3 q = (rot.transpose() * (p - c)).cwiseAbs() - b;
    return q.cwiseMax(0.0).norm() + std::min(q.maxCoeff(), 0.0);
  };
}

Shape scaled(const Shape& s, double k) {
  Shape r = s;
  Sdf f = s.sdf;
  r.sdf = [=](const Vec3& p) { return k * f(p / k); };
  r.volume = s.volume * k * k * k;
  r.lo = s.lo * k;
  r.hi = s.hi * k;
  r.size = s.size * k;
  return r;
}

std::vector<Shape> shapes() {
  Eigen::Matrix3d rot = (Eigen::AngleAxisd(0.5, Vec3(1, 2, 3).normalized())).toRotationMatrix();
  const double s3 = std::sqrt(3.0);
  return {
      {"sphere", sphere(Vec3(0.013, -0.021, 0.007), 1.0), 4.0 / 3 * kPi, Vec3::Constant(-1.3), Vec3::Constant(1.3), 2.0, 1, 2},
      {"ellipsoid", ellipsoid(Vec3(1.2, 0.8, 0.5)), 4.0 / 3 * kPi * 1.2 * 0.8 * 0.5, Vec3(-1.5, -1.1, -0.8),
       Vec3(1.5, 1.1, 0.8), 1.6, 1, 2},
      {"torus", torus(1.0, 0.35), 2 * kPi * kPi * 1.0 * 0.35 * 0.35, Vec3(-1.6, -1.6, -0.6), Vec3(1.6, 1.6, 0.6), 0.7, 1, 0},
      {"box", box(Vec3(0.031, 0.017, -0.023), Vec3(0.9, 0.6, 0.4)), 8 * 0.9 * 0.6 * 0.4, Vec3(-1.2, -0.9, -0.7),
       Vec3(1.2, 0.9, 0.7), 0.8, 1, 2},
      {"rotated cube", box(Vec3::Zero(), Vec3::Constant(0.5), rot), 1.0, Vec3::Constant(-0.5 * s3 - 0.2),
       Vec3::Constant(0.5 * s3 + 0.2), 1.0, 1, 2},
      {"thin plate", box(Vec3(0.01, -0.02, 0.003), Vec3(0.6, 0.4, 0.05)), 8 * 0.6 * 0.4 * 0.05, Vec3(-0.8, -0.6, -0.3),
       Vec3(0.8, 0.6, 0.3), 0.2, 1, 2},
      {"two spheres",
       [a = sphere(Vec3(-0.8, 0, 0), 0.5), b = sphere(Vec3(0.8, 0.05, 0), 0.5)](const Vec3& p) { return std::min(a(p), b(p)); },
       2 * 4.0 / 3 * kPi * 0.125, Vec3(-1.5, -0.7, -0.7), Vec3(1.5, 0.7, 0.7), 1.0, 2, 4},
  };
}

// The six dihedral angles of a tet, in degrees.
std::array<double, 6> dihedrals(const std::array<Vec3, 4>& x) {
  static constexpr int kEdge[6][4] = {{0, 1, 2, 3}, {0, 2, 1, 3}, {0, 3, 1, 2}, {1, 2, 0, 3}, {1, 3, 0, 2}, {2, 3, 0, 1}};
  std::array<double, 6> out;
  for (int e = 0; e < 6; ++e) {
    const Vec3& a = x[kEdge[e][0]];
    Vec3 t = (x[kEdge[e][1]] - a).normalized();
    Vec3 u = x[kEdge[e][2]] - a, v = x[kEdge[e][3]] - a;
    u -= u.dot(t) * t;
    v -= v.dot(t) * t;
    double c = std::clamp(u.dot(v) / (u.norm() * v.norm()), -1.0, 1.0);
    out[e] = std::acos(c) * 180 / kPi;
  }
  return out;
}

double longest_edge(const std::array<Vec3, 4>& x) {
  double l = 0;
  for (int i = 0; i < 4; ++i)
    for (int j = i + 1; j < 4; ++j) l = std::max(l, (x[i] - x[j]).norm());
  return l;
}

int count_components(const TetMesh& m) {
  std::vector<std::uint32_t> parent(m.tet_capacity());
  std::iota(parent.begin(), parent.end(), 0u);
  auto find = [&](std::uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (TetId t : m.tets())
    for (int f = 0; f < 4; ++f)
      if (TetId n = m.neighbor(t, f); n.is_valid()) parent[find(t.idx())] = find(n.idx());
  std::set<std::uint32_t> roots;
  for (TetId t : m.tets()) roots.insert(find(t.idx()));
  return static_cast<int>(roots.size());
}

struct Checked {
  double volume = 0;
  double min_dihedral = 180, max_dihedral = 0;
  double longest = 0;         // longest tet edge, in units of h
  std::size_t far_fine = 0;   // tets at least 8h from the surface with no edge longer than 1.01h
  std::size_t far = 0;        // tets at least 8h from the surface
};

// Every property the algorithm promises, for one mesh of shape s at cell size h.
Checked check(const TetMesh& m, const Shape& s, double h, bool graded = kGraded) {
  Checked r;
  REQUIRE(m.num_tets() > 0);
  REQUIRE_FALSE(m.has_pending_change());
  m.validate({.check_orientation = true, .check_manifold_boundary = true});
  std::size_t non_positive = 0, wrong_label = 0;
  for (TetId t : m.tets()) {
    const auto& v = m.tet_vertices(t);
    std::array<Vec3, 4> x{m.rest(v[0]), m.rest(v[1]), m.rest(v[2]), m.rest(v[3])};
    double vol = (x[1] - x[0]).cross(x[2] - x[0]).dot(x[3] - x[0]) / 6;
    non_positive += !(vol > 0);
    r.volume += vol;
    for (double a : dihedrals(x)) {
      r.min_dihedral = std::min(r.min_dihedral, a);
      r.max_dihedral = std::max(r.max_dihedral, a);
    }
    wrong_label += m.label(t) != 1;
    const double longest = longest_edge(x) / h;
    r.longest = std::max(r.longest, longest);
    double nearest = std::numeric_limits<double>::infinity();
    for (const Vec3& p : x) nearest = std::min(nearest, std::abs(s.distance ? s.distance(p) : s.sdf(p)));
    if (nearest >= 8 * h) {
      ++r.far;
      r.far_fine += longest <= 1.01;
    }
  }
  CHECK(non_positive == 0);
  CHECK(wrong_label == 0);
  INFO(s.name << " h=" << h << " dihedral " << r.min_dihedral << " .. " << r.max_dihedral);
  CHECK(r.min_dihedral >= kStuffingMinDihedral);
  CHECK(r.max_dihedral <= kStuffingMaxDihedral);
  g_min_dihedral = std::min(g_min_dihedral, r.min_dihedral);
  g_max_dihedral = std::max(g_max_dihedral, r.max_dihedral);
  // Grading: nothing at the finest size far from the surface.
  if (graded) CHECK(r.far_fine == 0);

  std::set<std::uint32_t> bverts;
  std::set<std::pair<std::uint32_t, std::uint32_t>> bedges;
  auto faces = m.boundary_faces();
  double worst = 0;
  std::size_t untagged = 0;
  for (const auto& f : faces) {
    untagged += f.tag != kTagSurface;
    for (int k = 0; k < 3; ++k) {
      std::uint32_t a = f.vertices[k].idx(), b = f.vertices[(k + 1) % 3].idx();
      bverts.insert(a);
      bedges.insert({std::min(a, b), std::max(a, b)});
    }
  }
  CHECK(untagged == 0);
  for (std::uint32_t v : bverts) worst = std::max(worst, std::abs(s.sdf(m.rest(VertexId(v)))));
  INFO("worst |sdf| on the boundary / h = " << worst / h);
  CHECK(worst <= 1e-6 * h);
  CHECK(long(bverts.size()) - long(bedges.size()) + long(faces.size()) == s.euler);
  CHECK(count_components(m) == s.components);
  return r;
}

TetMesh stuff(const Shape& s, double h, bool graded = kGraded) {
  StuffingOptions opt;
  opt.cell_size = h;
  opt.graded = graded;
  return isosurface_stuffing(s.sdf, s.lo, s.hi, opt);
}

// Every shape at scales 1, 1e-3 and 1e3 and lattices of a quarter, an eighth (and at scale 1 a
// sixteenth) of its size: valid, within the angle bounds, and the volume converges (finer is
// not worse, with slack for the alignment noise of coarse lattices; a few percent at an eighth).
void check_shapes_converge() {
  for (double scale : {1.0, 1e-3, 1e3}) {
    for (const Shape& base : shapes()) {
      Shape s = scaled(base, scale);
      double prev_err = std::numeric_limits<double>::infinity();
      // The finest lattice only at scale 1, to keep the run short.
      std::vector<double> fracs{0.25, 0.125};
      if (scale == 1.0) fracs.push_back(0.0625);
      for (double frac : fracs) {
        double h = frac * s.size;
        INFO(base.name << " scale " << scale << " h " << h);
        TetMesh m = stuff(s, h);
        Checked c = check(m, s, h);
        double err = std::abs(c.volume - s.volume) / s.volume;
        INFO("relative volume error " << err);
        CHECK(err <= std::max(prev_err * 1.05, 0.01));
        if (frac <= 0.125) CHECK(err < 0.03);
        prev_err = err;
      }
    }
  }
}

// Every shape scaled by 1e-8 and 1e8 at an eighth of its size: the same checks, volume to 5%.
void check_extreme_scales() {
  for (double scale : {1e-8, 1e8})
    for (const Shape& base : shapes()) {
      Shape s = scaled(base, scale);
      double h = 0.125 * s.size;
      INFO(base.name << " scale " << scale);
      Checked c = check(stuff(s, h), s, h);
      CHECK(std::abs(c.volume - s.volume) / s.volume < 0.05);
    }
}

// The dihedral range over every mesh check() saw in this test program, against the bounds.
void check_dihedral_range(const char* what) {
  if (g_max_dihedral > 0)
    WARN(what << ": dihedral angles over all meshes " << g_min_dihedral << " .. " << g_max_dihedral << " deg (bounds "
              << kStuffingMinDihedral << " .. " << kStuffingMaxDihedral << ")");
  CHECK(g_min_dihedral >= kStuffingMinDihedral);
  CHECK(g_max_dihedral <= kStuffingMaxDihedral);
}

// A capsule of radius r along `axis` through the origin's lattice line, in a box whose lower
// corner sits `shift` cells off the lattice (0: the line runs through cube centres, 0.5:
// through corners): both ends of long lattice edges inside and the opposite long edge outside.
Shape lattice_capsule(int axis, double r, double shift, double h) {
  Vec3 a = Vec3::Zero(), b = Vec3::Zero();
  a[axis] = -0.52;
  b[axis] = 0.47;
  Sdf capsule = [=](const Vec3& p) {
    const Vec3 d = b - a;
    const double t = std::clamp((p - a).dot(d) / d.squaredNorm(), 0.0, 1.0);
    return (p - (a + t * d)).norm() - r;
  };
  return Shape{"capsule", capsule, 0, Vec3::Constant(-(6.5 - shift) * h), Vec3::Constant(0.8), 1.0, 1, 2};
}

// The unit sphere in a box that cuts off its upper half: the mesh is the intersection, valid,
// the half ball's volume within `tol`, nothing above the box.
void check_clipped_sphere(bool graded, double h, double tol) {
  StuffingOptions opt;
  opt.cell_size = h;
  opt.graded = graded;
  TetMesh m = isosurface_stuffing(sphere(Vec3::Zero(), 1.0), Vec3(-1.5, -1.5, -1.5), Vec3(1.5, 1.5, 0.0), opt);
  m.validate({.check_orientation = true, .check_manifold_boundary = true});
  CHECK(m.total_volume() == Approx(2.0 / 3 * kPi).epsilon(tol));
  double top = -1e300;
  for (VertexId v : m.vertices()) top = std::max(top, m.rest(v).z());
  CHECK(top <= 1e-9);
}

// A request far over max_tets is refused with an estimate and the option to raise.
void check_refused_as_too_large(const std::function<void()>& request) {
  try {
    request();
    FAIL("expected a refusal");
  } catch (const InvalidArgument& e) {
    INFO(e.what());
    CHECK(std::string(e.what()).find("about") != std::string::npos);
    CHECK(std::string(e.what()).find("max_tets") != std::string::npos);
  }
}

}  // namespace

// The test cases every mode runs alike, named with the mode's prefix and tags.
#define INCISE_STUFFING_SHARED_TESTS(prefix, tags)                                                           \
  TEST_CASE(prefix "analytic shapes at several resolutions and scales", tags "[long]") { check_shapes_converge(); } \
  TEST_CASE(prefix "extreme scales x1e-8 and x1e8", tags) { check_extreme_scales(); }
