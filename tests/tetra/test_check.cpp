// Surface checks, clean-up, option parsing: no meshing, fast.
#include <catch2/catch.hpp>

#include "mesh/errors.h"
#include "mesh/tetrahedralize/surface_check.h"
#include "mesh/tetrahedralize/tetrahedralize.h"
#include "tests/tetra/shapes.h"

using namespace incise;
using namespace incise::testing;

TEST_CASE("Length and optimizer parsing", "[tetra]") {
  CHECK(Length::parse("0.05").value == Approx(0.05));
  CHECK_FALSE(Length::parse("0.05").relative);
  CHECK(Length::parse("5%").relative);
  CHECK(Length::parse("5%").resolve(200) == Approx(10));
  CHECK(Length::parse(Length::parse("2.5%").str()).value == Approx(0.025));
  for (const char* bad : {"", "%", "-1", "0", "abc", "1e999", "5%%", "nan"}) CHECK_THROWS_AS(Length::parse(bad), InvalidArgument);
  CHECK(parse_optimize("none") == kOptimizeNone);
  CHECK(parse_optimize("exude,odt") == (kOptimizeExude | kOptimizeOdt));
  CHECK(parse_optimize(optimize_str(kOptimizeLloyd | kOptimizePerturb)) == (kOptimizeLloyd | kOptimizePerturb));
  CHECK_THROWS_AS(parse_optimize("odt,fast"), InvalidArgument);
}

TEST_CASE("check_surface on clean closed shapes", "[tetra]") {
  for (double scale : {1e-6, 1.0, 1e6}) {
    const SurfaceMesh shapes[] = {box_surface(Vec3(1, 2, 3) * scale), sphere_surface(scale, 2), torus_surface(2 * scale, 0.5 * scale, 64, 32)};
    const double volumes[] = {6 * scale * scale * scale, 4.0 / 3 * M_PI * std::pow(scale, 3), 2 * M_PI * M_PI * 2 * 0.25 * std::pow(scale, 3)};
    for (int i = 0; i < 3; ++i) {
      INFO("shape " << i << " scale " << scale);
      SurfaceCheck c = check_surface(shapes[i]);
      CHECK(c.meshable());
      CHECK(c.summary() == "clean");
      CHECK(c.components == 1);
      CHECK(c.self_intersection_checked);
      CHECK(c.signed_volume == Approx(volumes[i]).epsilon(i == 0 ? 1e-12 : 0.05));
    }
  }
}

TEST_CASE("check_surface finds and cleans the benign problems", "[tetra]") {
  SurfaceMesh s = box_surface(Vec3(1, 1, 1));
  SECTION("unwelded vertices (STL style) are welded") {
    SurfaceMesh soup;
    for (auto t : s.triangles) {
      const int o = int(soup.vertices.size());
      for (int k = 0; k < 3; ++k) soup.vertices.push_back(s.vertices[t[k]]);
      soup.triangles.push_back({o, o + 1, o + 2});
    }
    SurfaceMesh cleaned;
    SurfaceCheck c = check_surface(soup, &cleaned);
    CHECK(c.welded_vertices == 36 - 8);
    CHECK(c.meshable());
    CHECK(cleaned.vertices.size() == 8);
  }
  SECTION("duplicate and degenerate faces are dropped") {
    s.triangles.push_back(s.triangles[3]);
    s.triangles.push_back({s.triangles[5][0], s.triangles[5][2], s.triangles[5][1]});  // reversed duplicate
    s.triangles.push_back({0, 0, 1});
    s.vertices.push_back((s.vertices[0] + s.vertices[1]) / 2);
    s.triangles.push_back({0, 1, int(s.vertices.size()) - 1});  // zero area
    SurfaceMesh cleaned;
    SurfaceCheck c = check_surface(s, &cleaned);
    CHECK(c.duplicate_faces == 2);
    CHECK(c.degenerate_faces == 2);
    CHECK(c.meshable());
    CHECK(cleaned.triangles.size() == 12);
  }
  SECTION("inverted orientation is flipped") {
    for (auto& t : s.triangles) std::swap(t[0], t[1]);
    SurfaceMesh cleaned;
    SurfaceCheck c = check_surface(s, &cleaned);
    CHECK(c.signed_volume == Approx(-1));
    CHECK(c.summary().find("inverted") != std::string::npos);
    CHECK(enclosed_volume(cleaned) == Approx(1));
  }
  SECTION("several shells are reported but meshable") {
    SurfaceCheck c = check_surface(merged(s, box_surface(Vec3(1, 1, 1), Vec3(3, 0, 0))));
    CHECK(c.components == 2);
    CHECK(c.meshable());
  }
}

TEST_CASE("check_surface finds what needs a repair", "[tetra]") {
  SurfaceMesh s = sphere_surface(1, 2);
  SECTION("holes") {
    s.triangles.erase(s.triangles.begin(), s.triangles.begin() + 1);
    s.triangles.erase(s.triangles.begin() + 100, s.triangles.begin() + 101);
    SurfaceCheck c = check_surface(s);
    CHECK(c.border_edges == 6);
    CHECK(c.holes == 2);
    CHECK(c.largest_hole_radius > 0.05);
    CHECK(c.largest_hole_radius < 0.3);
    CHECK_FALSE(c.meshable());
  }
  SECTION("self-intersections") {
    SurfaceCheck c = check_surface(merged(s, sphere_surface(1, 2, Vec3(0.7, 0.3, 0.1))));
    CHECK(c.self_intersections > 0);
    CHECK(c.components == 2);
    CHECK_FALSE(c.meshable());
  }
  SECTION("non-manifold edges") {
    auto t = s.triangles[0];
    s.vertices.push_back(Vec3(3, 3, 3));
    s.triangles.push_back({t[1], t[0], int(s.vertices.size()) - 1});  // a fin on edge (t0, t1)
    SurfaceCheck c = check_surface(s);
    CHECK(c.nonmanifold_edges == 1);
    CHECK_FALSE(c.meshable());
  }
  SECTION("inconsistent orientation") {
    std::swap(s.triangles[7][0], s.triangles[7][1]);
    SurfaceCheck c = check_surface(s);
    CHECK(c.misoriented_edges == 3);
    CHECK_FALSE(c.meshable());
  }
}

TEST_CASE("surface_distance", "[tetra]") {
  const SurfaceMesh a = box_surface(Vec3(1, 1, 1));
  CHECK(surface_distance(a, a).max == Approx(0).margin(1e-12));
  const SurfaceMesh b = box_surface(Vec3(1, 1, 1), Vec3(0, 0, 0.25));
  const SurfaceDistance d = surface_distance(a, b);
  CHECK(d.max == Approx(0.25).margin(1e-9));
  CHECK(d.mean > 0.01);
  CHECK(d.mean < 0.25);
}
