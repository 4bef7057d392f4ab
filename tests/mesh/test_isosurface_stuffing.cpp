// Isosurface stuffing: validity, the paper's dihedral angle bounds, volume convergence,
// boundary on the isosurface, topology of the boundary, over analytic shapes and scales.
#include <catch2/catch.hpp>

constexpr bool kGraded = false;  // stuff() and check() default to this mode
#include "tests/mesh/stuffing_checks.h"

INCISE_STUFFING_SHARED_TESTS("stuffing: ", "[stuffing]")

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
        const Shape s = lattice_capsule(axis, radius * h, shift, h);
        INFO("radius/h " << radius << " axis " << axis << " shift " << shift);
        check(stuff(s, h), s, h);
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
  check_clipped_sphere(false, 0.1, 0.03);  // half of the sphere sticks out of the box
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
  check_refused_as_too_large([&] { isosurface_stuffing(s, lo, hi, with([](auto& o) { o.cell_size = 1e-4; })); });
  CHECK_THROWS_AS(isosurface_stuffing(s, lo, hi, with([](auto& o) { o.max_tets = 1000; })), InvalidArgument);
}

TEST_CASE("stuffing: dihedral range over the meshes above", "[stuffing]") {
  check_dihedral_range("isosurface stuffing");
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
