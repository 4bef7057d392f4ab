// Isosurface stuffing: validity, the paper's dihedral angle bounds, volume convergence,
// boundary on the isosurface, topology of the boundary, over analytic shapes and scales.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <numeric>
#include <set>
#include <utility>
#include <vector>

#include "mesh/errors.h"
#include "mesh/isosurface_stuffing.h"

using namespace incise;

namespace {

using Sdf = std::function<double(const Vec3&)>;
constexpr double kPi = 3.14159265358979323846;

// Measured over every mesh the tests build (reported at the end).
double g_min_dihedral = 180, g_max_dihedral = 0;

struct Shape {
  const char* name;
  Sdf sdf;
  double volume;     // analytic volume of {sdf < 0}
  Vec3 lo, hi;       // domain box with a margin
  double size;       // characteristic size (cell sizes are fractions of it)
  int components;    // connected components of the solid
  int euler;         // Euler characteristic of the boundary surface (2 per sphere, 0 torus)
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
      // Thinner than the coarsest lattice's 4 cells.
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
};

// Every property the algorithm promises, for one mesh of shape s at cell size h.
Checked check(const TetMesh& m, const Shape& s, double h) {
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
  }
  CHECK(non_positive == 0);
  CHECK(wrong_label == 0);
  INFO(s.name << " h=" << h << " dihedral " << r.min_dihedral << " .. " << r.max_dihedral);
  CHECK(r.min_dihedral >= kStuffingMinDihedral);
  CHECK(r.max_dihedral <= kStuffingMaxDihedral);
  g_min_dihedral = std::min(g_min_dihedral, r.min_dihedral);
  g_max_dihedral = std::max(g_max_dihedral, r.max_dihedral);

  // Boundary: tagged, on the isosurface, closed with the surface's Euler characteristic.
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

TetMesh stuff(const Shape& s, double h) {
  StuffingOptions opt;
  opt.cell_size = h;
  return isosurface_stuffing(s.sdf, s.lo, s.hi, opt);
}

}  // namespace

TEST_CASE("stuffing: analytic shapes at several resolutions and scales", "[stuffing]") {
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
        // Converges: finer is not worse (slack for the alignment noise of coarse lattices),
        // and a few percent at the finest h.
        CHECK(err <= std::max(prev_err * 1.05, 0.01));
        if (frac <= 0.125) CHECK(err < 0.03);
        prev_err = err;
      }
    }
  }
}

TEST_CASE("stuffing: extreme scales x1e-8 and x1e8", "[stuffing]") {
  for (double scale : {1e-8, 1e8})
    for (const Shape& base : shapes()) {
      Shape s = scaled(base, scale);
      double h = 0.125 * s.size;
      INFO(base.name << " scale " << scale);
      Checked c = check(stuff(s, h), s, h);
      CHECK(std::abs(c.volume - s.volume) / s.volume < 0.05);
    }
}

TEST_CASE("stuffing: sphere at h = r/20 and the same sphere in a huge box", "[stuffing]") {
  Shape s = shapes()[0];
  double h = 1.0 / 20;
  TetMesh m = stuff(s, h);
  Checked c = check(m, s, h);
  CHECK(std::abs(c.volume - s.volume) / s.volume < 0.01);

  // 40000 cells per axis: only the blocks near the sphere are visited, and the mesh is the
  // same up to the lattice offset.
  Shape big = s;
  big.lo = Vec3::Constant(-1000.0);
  big.hi = Vec3::Constant(1000.0);
  TetMesh mb = stuff(big, h);
  Checked cb = check(mb, big, h);
  CHECK(std::abs(cb.volume - s.volume) / s.volume < 0.01);
}

TEST_CASE("stuffing: rotated sphere lattices keep the bounds (random offsets)", "[stuffing]") {
  // Many lattice/surface alignments exercise every stencil and the warping rules.
  for (int i = 0; i < 20; ++i) {
    Vec3 c(0.37 * std::sin(1.7 * i), 0.29 * std::cos(2.3 * i), 0.11 * std::sin(0.9 * i + 1));
    double r = 0.6 + 0.05 * (i % 7);
    Shape s{"offset sphere", sphere(c, r), 4.0 / 3 * kPi * r * r * r, Vec3::Constant(-1.3), Vec3::Constant(1.3), 2 * r, 1, 2};
    double h = r / (3 + i % 5);
    TetMesh m = stuff(s, h);
    check(m, s, h);
  }
}

TEST_CASE("stuffing: thin capsules along lattice lines (inside long edge, outside long edge)", "[stuffing]") {
  // A capsule of radius ~0.35h around a line of cube centres (or corners) puts both ends of
  // long lattice edges inside and the opposite long edge outside, with no warping: the prism
  // stencil whose two quadrilaterals both follow the parity rule. Lattice centres sit at
  // lo - h + (i + 1/2) h, corners at lo - h + i h.
  const double h = 0.1;
  for (double radius : {0.3, 0.35, 0.4})
    for (int axis = 0; axis < 3; ++axis)
      for (double shift : {0.0, 0.5}) {  // through centres, through corners
        Vec3 a = Vec3::Zero(), b = Vec3::Zero();
        a[axis] = -0.52;
        b[axis] = 0.47;
        double r = radius * h;
        Sdf capsule = [=](const Vec3& p) {
          Vec3 d = b - a;
          double t = std::clamp((p - a).dot(d) / d.squaredNorm(), 0.0, 1.0);
          return (p - (a + t * d)).norm() - r;
        };
        Vec3 lo = Vec3::Constant(-(6.5 - shift) * h), hi = Vec3::Constant(0.8);
        Shape s{"capsule", capsule, 0, lo, hi, 1.0, 1, 2};
        INFO("radius/h " << radius << " axis " << axis << " shift " << shift);
        StuffingOptions opt;
        opt.cell_size = h;
        TetMesh m = isosurface_stuffing(capsule, lo, hi, opt);
        check(m, s, h);
      }
}

TEST_CASE("stuffing: box with faces on lattice planes (exact zeros at lattice points)", "[stuffing]") {
  // Cell sizes and box are dyadic, so lattice points on the faces evaluate to exactly 0.
  Shape s{"aligned box", box(Vec3::Zero(), Vec3(0.5, 0.75, 0.25)), 8 * 0.5 * 0.75 * 0.25, Vec3::Constant(-1),
          Vec3::Constant(1), 1.0, 1, 2};
  for (double h : {0.25, 0.125, 0.0625}) {
    INFO("h " << h);
    TetMesh m = stuff(s, h);
    Checked c = check(m, s, h);
    CHECK(c.volume == Approx(s.volume).epsilon(1e-9));  // faces, edges and corners are lattice-exact
  }
}

TEST_CASE("stuffing: object clipped by the domain box", "[stuffing]") {
  // Half of the sphere sticks out of the box: the mesh is the intersection, still valid.
  StuffingOptions opt;
  opt.cell_size = 0.1;
  TetMesh m = isosurface_stuffing(sphere(Vec3::Zero(), 1.0), Vec3(-1.5, -1.5, -1.5), Vec3(1.5, 1.5, 0.0), opt);
  m.validate({.check_orientation = true, .check_manifold_boundary = true});
  CHECK(m.total_volume() == Approx(2.0 / 3 * kPi).epsilon(0.03));
  double top = -1e300;
  for (VertexId v : m.vertices()) top = std::max(top, m.rest(v).z());
  CHECK(top <= 1e-9);
}

TEST_CASE("stuffing: bad options and empty results are refused", "[stuffing]") {
  Sdf s = sphere(Vec3::Zero(), 1.0);
  Vec3 lo = Vec3::Constant(-2), hi = Vec3::Constant(2);
  StuffingOptions opt;
  opt.cell_size = 0.2;
  auto with = [&](auto edit) {
    StuffingOptions o = opt;
    edit(o);
    return o;
  };
  CHECK_THROWS_AS(isosurface_stuffing(s, lo, hi, with([](auto& o) { o.cell_size = 0; })), InvalidArgument);
  CHECK_THROWS_AS(isosurface_stuffing(s, lo, hi, with([](auto& o) { o.cell_size = -1; })), InvalidArgument);
  CHECK_THROWS_AS(isosurface_stuffing(s, lo, hi, with([](auto& o) { o.cell_size = std::nan(""); })), InvalidArgument);
  CHECK_THROWS_AS(isosurface_stuffing(s, lo, hi, with([](auto& o) { o.cell_size = INFINITY; })), InvalidArgument);
  CHECK_THROWS_AS(isosurface_stuffing(s, lo, hi, with([](auto& o) { o.graded = true; o.cell_size = 0; })), InvalidArgument);
  CHECK_THROWS_AS(isosurface_stuffing(s, lo, hi, with([](auto& o) { o.alpha_long = 0.5; })), InvalidArgument);
  CHECK_THROWS_AS(isosurface_stuffing(s, lo, hi, with([](auto& o) { o.alpha_short = std::nan(""); })), InvalidArgument);
  CHECK_THROWS_AS(isosurface_stuffing(s, hi, lo, opt), InvalidArgument);                          // empty box
  CHECK_THROWS_AS(isosurface_stuffing(s, lo, Vec3(2, 2, -2), opt), InvalidArgument);              // flat box
  CHECK_THROWS_AS(isosurface_stuffing(s, Vec3(std::nan(""), 0, 0), hi, opt), InvalidArgument);    // NaN box
  CHECK_THROWS_AS(isosurface_stuffing(Sdf(), lo, hi, opt), InvalidArgument);                       // no sdf
  CHECK_THROWS_AS(isosurface_stuffing([](const Vec3&) { return 1.0; }, lo, hi, opt), InvalidArgument);  // empty
  CHECK_THROWS_AS(isosurface_stuffing(sphere(Vec3::Constant(5), 1), lo, hi, opt), InvalidArgument);   // outside box
  CHECK_THROWS_AS(isosurface_stuffing([](const Vec3&) { return std::nan(""); }, lo, hi, opt), InvalidArgument);
  // Too large: refused with an estimate, quickly (before building the lattice).
  try {
    isosurface_stuffing(s, lo, hi, with([](auto& o) { o.cell_size = 1e-4; }));
    FAIL("expected a refusal");
  } catch (const InvalidArgument& e) {
    INFO(e.what());
    CHECK(std::string(e.what()).find("about") != std::string::npos);
    CHECK(std::string(e.what()).find("max_tets") != std::string::npos);
  }
  CHECK_THROWS_AS(isosurface_stuffing(s, lo, hi, with([](auto& o) { o.max_tets = 1000; })), InvalidArgument);
}

TEST_CASE("stuffing: dihedral range over the meshes above", "[stuffing]") {
  if (g_max_dihedral > 0)
    WARN("isosurface stuffing: dihedral angles over all meshes " << g_min_dihedral << " .. " << g_max_dihedral
                                                                 << " deg (guaranteed " << kStuffingMinDihedral
                                                                 << " .. " << kStuffingMaxDihedral << ")");
  CHECK(g_min_dihedral >= kStuffingMinDihedral);
  CHECK(g_max_dihedral <= kStuffingMaxDihedral);
}

// Hidden: prints size, volume error and dihedral range per shape and resolution
// (./test_mesh "[.stuffing-report]").
TEST_CASE("stuffing: report", "[.stuffing-report]") {
  for (const Shape& s : shapes())
    for (double frac : {0.25, 0.125, 0.0625, 0.03125}) {
      double h = frac * s.size;
      TetMesh m = stuff(s, h);
      Checked c = check(m, s, h);
      WARN(s.name << " h=size*" << frac << ": " << m.num_tets() << " tets, volume error "
                  << (c.volume - s.volume) / s.volume * 100 << "%, dihedral " << c.min_dihedral << " .. "
                  << c.max_dihedral);
    }
}
