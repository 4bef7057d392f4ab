// Graded isosurface stuffing: the uniform variant's checks (validity, dihedral bounds, boundary
// on the isosurface, volume convergence, boundary topology, scales) plus what grading promises:
// coarse tets away from the surface, far fewer tets than the uniform lattice, the same
// boundary, and a correct mesh even from an sdf that breaks the Lipschitz contract.
#include <catch2/catch.hpp>
#include <cstdlib>

constexpr bool kGraded = true;  // stuff() and check() default to this mode
#include "tests/mesh/stuffing_checks.h"

INCISE_STUFFING_SHARED_TESTS("graded stuffing: ", "[stuffing][graded]")

TEST_CASE("graded stuffing: far fewer tets than uniform, coarse inside, same boundary", "[stuffing][graded]") {
  Shape s = shapes()[0];
  for (double r_over_h : {16.0, 32.0}) {
    const double h = 1.0 / r_over_h;
    INFO("r/h " << r_over_h);
    TetMesh g = stuff(s, h, true), u = stuff(s, h, false);
    Checked cg = check(g, s, h);
    // The interior is coarse: cells of 4h and more exist, and the far tets are not fine.
    CHECK(cg.far > 0);
    CHECK(cg.longest >= 4.0);
    // Size: the uniform lattice fills the volume, the graded one a shell of a few h.
    const double ratio = double(g.num_tets()) / double(u.num_tets());
    INFO("graded " << g.num_tets() << " uniform " << u.num_tets() << " ratio " << ratio);
    CHECK(ratio < (r_over_h < 20 ? 0.6 : 0.35));
    // Same lattice near the surface: the same boundary up to the warping order, hence
    // practically the same volume and boundary size.
    CHECK(std::abs(g.total_volume() - u.total_volume()) / u.total_volume() < 1e-3);
    const double bg = double(g.boundary_faces().size()), bu = double(u.boundary_faces().size());
    CHECK(std::abs(bg - bu) / bu < 0.02);
  }
}

TEST_CASE("graded stuffing: sphere in a huge box, random offsets", "[stuffing][graded]") {
  Shape s = shapes()[0];
  s.lo = Vec3::Constant(-1000.0);
  s.hi = Vec3::Constant(1000.0);
  Checked c = check(stuff(s, 1.0 / 16), s, 1.0 / 16);
  CHECK(std::abs(c.volume - s.volume) / s.volume < 0.02);

  for (int i = 0; i < 20; ++i) {
    Vec3 ctr(0.37 * std::sin(1.7 * i), 0.29 * std::cos(2.3 * i), 0.11 * std::sin(0.9 * i + 1));
    double r = 0.6 + 0.05 * (i % 7);
    Shape o{"offset sphere", sphere(ctr, r), 4.0 / 3 * kPi * r * r * r, Vec3::Constant(-1.3), Vec3::Constant(1.3), 2 * r, 1, 2};
    double h = r / (3 + 2 * (i % 5));
    INFO("offset sphere " << i);
    check(stuff(o, h), o, h);
  }
}

TEST_CASE("graded stuffing: thin capsules, aligned box, box clipping", "[stuffing][graded]") {
  const double h = 0.1;
  for (double radius : {0.3, 0.4})
    for (int axis = 0; axis < 3; ++axis)
      for (double shift : {0.0, 0.5}) {
        const Shape s = lattice_capsule(axis, radius * h, shift, h);
        INFO("radius/h " << radius << " axis " << axis << " shift " << shift);
        check(stuff(s, h), s, h);
      }

  Shape aligned{"aligned box", box(Vec3::Zero(), Vec3(0.5, 0.75, 0.25)), 8 * 0.5 * 0.75 * 0.25, Vec3::Constant(-1),
                Vec3::Constant(1), 1.0, 1, 2};
  for (double hh : {0.125, 0.0625}) {
    Checked c = check(stuff(aligned, hh), aligned, hh);
    CHECK(c.volume == Approx(aligned.volume).epsilon(1e-9));
  }

  check_clipped_sphere(true, 0.05, 0.02);
}

TEST_CASE("graded stuffing: sdf off its contract still gives a valid mesh", "[stuffing][graded]") {
  // Four times the distance within 2h of the surface (values above the distance, off the
  // contract): the Lipschitz bounds that place the finest band are wrong there, and the
  // run-time check refines until the stencils only meet finest tets. 0.3x the distance: a
  // loose but valid bound.
  const double h = 0.05;
  Sdf base = torus(1.0, 0.35);
  Sdf steep = [=](const Vec3& p) {
    double d = base(p);
    return d + 3 * std::clamp(d, -2 * h, 2 * h);
  };
  Sdf loose = [=](const Vec3& p) { return 0.3 * base(p); };
  for (const Sdf& f : {steep, loose}) {
    Shape s{"torus", f, 2 * kPi * kPi * 0.35 * 0.35, Vec3(-1.6, -1.6, -0.6), Vec3(1.6, 1.6, 0.6), 0.7, 1, 0, base};
    TetMesh m = stuff(s, h);
    // The boundary check is relative to h; |f| <= 1e-6 h still holds on it.
    Checked c = check(m, s, h);
    CHECK(std::abs(c.volume - s.volume) / s.volume < 0.03);
  }
}

TEST_CASE("graded stuffing: oversized requests are refused", "[stuffing][graded]") {
  Sdf s = sphere(Vec3::Zero(), 1.0);
  Vec3 lo = Vec3::Constant(-2), hi = Vec3::Constant(2);
  StuffingOptions opt;
  opt.graded = true;
  opt.cell_size = 1e-5;  // ~1e11 tets even graded: refused from the octree's upper levels
  check_refused_as_too_large([&] { isosurface_stuffing(s, lo, hi, opt); });
  opt.cell_size = 0.1;
  opt.max_tets = 1000;
  CHECK_THROWS_AS(isosurface_stuffing(s, lo, hi, opt), InvalidArgument);
  opt.max_tets = 50'000'000;
  CHECK_THROWS_AS(isosurface_stuffing([](const Vec3&) { return 1.0; }, lo, hi, opt), InvalidArgument);  // empty
  opt.alpha_long = 0.6;
  CHECK_THROWS_AS(isosurface_stuffing(s, lo, hi, opt), InvalidArgument);
}

TEST_CASE("graded stuffing: dihedral range over the meshes above", "[stuffing][graded]") {
  check_dihedral_range("graded isosurface stuffing");
}

// Hidden: tet counts against the uniform lattice and dihedral ranges on a sphere
// (./test_mesh "[.stuffing-graded-report]").
TEST_CASE("graded stuffing: report", "[.stuffing-graded-report]") {
  Shape s = shapes()[0];
  for (double r_over_h : {8.0, 16.0, 32.0, 64.0}) {
    const double h = 1.0 / r_over_h;
    TetMesh g = stuff(s, h, true), u = stuff(s, h, false);
    Checked cg = check(g, s, h);
    WARN("sphere r/h=" << r_over_h << ": graded " << g.num_tets() << " tets, uniform " << u.num_tets() << ", ratio "
                       << double(g.num_tets()) / double(u.num_tets()) << ", graded dihedral " << cg.min_dihedral
                       << " .. " << cg.max_dihedral << ", longest edge " << cg.longest << " h");
  }
}

// Dihedral ranges of graded and uniform meshes over many random shapes, placements and
// resolutions. INCISE_STUFFING_INPUTS sets how many (default 300; the sanitizer run uses fewer:
// 300 took 467 s instrumented).
TEST_CASE("graded stuffing: random inputs", "[long][stuffing-graded-random]") {
  int inputs = 300;
  if (const char* env = std::getenv("INCISE_STUFFING_INPUTS")) inputs = std::max(4, std::atoi(env));
  std::uint64_t state = 12345;
  auto rnd = [&]() {  // uniform in [0, 1)
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return double(state >> 11) / double(1ull << 53);
  };
  double gmin = 180, gmax = 0, umin = 180, umax = 0;
  std::size_t gtets = 0, utets = 0;
  for (int i = 0; i < inputs; ++i) {
    Vec3 c(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5);
    Eigen::Matrix3d rot = Eigen::AngleAxisd(3 * rnd(), Vec3(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5).normalized()).toRotationMatrix();
    Sdf f;
    int kind = i % 4;
    if (kind == 0) f = sphere(c, 0.5 + rnd());
    if (kind == 1) {
      Sdf e = ellipsoid(Vec3(0.4 + rnd(), 0.4 + rnd(), 0.4 + rnd()));
      f = [=](const Vec3& p) { return e(rot.transpose() * (p - c)); };
    }
    if (kind == 2) {
      Sdf t = torus(0.8 + 0.4 * rnd(), 0.2 + 0.3 * rnd());
      f = [=](const Vec3& p) { return t(rot.transpose() * (p - c)); };
    }
    if (kind == 3) f = box(c, Vec3(0.3 + rnd(), 0.3 + rnd(), 0.3 + rnd()), rot);
    const double h = 0.04 + 0.2 * rnd();
    Vec3 lo = Vec3::Constant(-2.5), hi = Vec3::Constant(2.5);
    StuffingOptions opt;
    opt.cell_size = h;
    for (bool graded : {true, false}) {
      opt.graded = graded;
      TetMesh m = isosurface_stuffing(f, lo, hi, opt);
      m.validate({.check_orientation = true, .check_manifold_boundary = true});
      double mn = 180, mx = 0;
      for (TetId t : m.tets()) {
        const auto& v = m.tet_vertices(t);
        for (double a : dihedrals({m.rest(v[0]), m.rest(v[1]), m.rest(v[2]), m.rest(v[3])})) {
          mn = std::min(mn, a);
          mx = std::max(mx, a);
        }
      }
      (graded ? gtets : utets) += m.num_tets();
      (graded ? gmin : umin) = std::min(graded ? gmin : umin, mn);
      (graded ? gmax : umax) = std::max(graded ? gmax : umax, mx);
    }
  }
  WARN(inputs << " random inputs: graded dihedral " << gmin << " .. " << gmax << " (" << gtets << " tets), uniform " << umin
                                             << " .. " << umax << " (" << utets << " tets)");
  CHECK(gmin >= kStuffingMinDihedral);
  CHECK(gmax <= kStuffingMaxDihedral);
}
