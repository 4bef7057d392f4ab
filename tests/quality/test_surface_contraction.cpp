// Contraction along a curved or bent surface (CollapseOptions::surface_deviation): a surface
// vertex that check_collapse refuses (its faces are not one flat disc) may still go into a
// neighbour on its surface when it stays within the bound of the surface after; never across a
// feature line, never at a corner. Checked on a unit cube of 4x4x4 cells whose top face is
// bent by lifting one vertex by a known height.
#include <catch2/catch.hpp>

#include <limits>

#include "mesh/edge_collapse.h"
#include "mesh/generate.h"
#include "mesh/point_locator.h"
#include "quality/collapse.h"
#include "quality/improve_scope.h"
#include "quality/surface_star.h"
#include "testing/mesh_measures.h"

using namespace incise;
using incise::testing::vertex_at;

namespace {

// Distance from p to the boundary faces around v.
double distance_to_surface(const TetMesh& m, VertexId v, const Vec3& p) {
  double best = std::numeric_limits<double>::infinity();
  for (const SurfaceFace& f : surface_faces_after(m, v, {}, {}))
    best = std::min(best, (p - closest_on_triangle(p, m.rest(f.v[0]), m.rest(f.v[1]), m.rest(f.v[2]))).norm());
  return best;
}

// Mean length of the surface edges at v (what the deviation bound is relative to).
double mean_surface_edge(const TetMesh& m, VertexId v) {
  double sum = 0;
  const auto around = surface_neighbours(m, v);
  for (std::uint32_t w : around) sum += (m.rest(VertexId(w)) - m.rest(v)).norm();
  return sum / double(around.size());
}

}  // namespace

TEST_CASE("surface contraction: a vertex of a bent face goes within the deviation bound, not beyond it",
          "[quality][collapse]") {
  TetMesh m = make_box(Vec3(1, 1, 1), {4, 4, 4});
  const VertexId v = vertex_at(m, Vec3(0.5, 0.5, 1)), keep = vertex_at(m, Vec3(0.75, 0.5, 1));
  const double lift = 0.01;
  m.set_rest(v, Vec3(0.5, 0.5, 1 + lift));
  m.discard_change();
  // The plain check keeps every vertex of a surface that is not flat around it.
  CHECK(check_collapse(m, keep, v).refusal == CollapseRefusal::Boundary);
  const double h = mean_surface_edge(m, v);
  CollapseOptions opt;
  SECTION("a bound above the lift: contracted, the removed point within it of the surface after") {
    opt.surface_deviation = 1.5 * lift / h;
    const CollapseCheck c = check_surface_contraction(m, keep, v, opt);
    REQUIRE(c.ok());
    const Vec3 p = m.rest(v);
    const double volume = m.total_volume();
    collapse_edge(m, c.plan);
    m.validate({.check_orientation = true, .check_manifold_boundary = true});
    CHECK_FALSE(m.is_alive(v));
    // The top face is flat again: the point was `lift` above it, and the volume under it is gone.
    CHECK(distance_to_surface(m, keep, p) == Approx(lift).epsilon(1e-9));
    CHECK(m.total_volume() == Approx(1.0).epsilon(1e-12));
    CHECK(volume > 1.0);
  }
  SECTION("a bound below the lift: refused") {
    opt.surface_deviation = 0.5 * lift / h;
    CHECK(check_surface_contraction(m, keep, v, opt).refusal == CollapseRefusal::Boundary);
  }
  SECTION("off: improve_by_collapse's caller never asks, the check itself still refuses a zero bound") {
    opt.surface_deviation = 0;
    CHECK_FALSE(check_surface_contraction(m, keep, v, opt).ok());
  }
}

TEST_CASE("surface contraction: a crease vertex moves only along its crease, a corner never",
          "[quality][collapse]") {
  TetMesh m = make_box(Vec3(1, 1, 1), {4, 4, 4});
  // A vertex of the top front edge (y = 0, z = 1), lifted: the crease bends there.
  const VertexId v = vertex_at(m, Vec3(0.5, 0, 1));
  m.set_rest(v, Vec3(0.5, 0, 1.005));
  m.discard_change();
  CollapseOptions opt;
  opt.surface_deviation = 0.1;
  CHECK(check_surface_contraction(m, vertex_at(m, Vec3(0.75, 0, 1)), v, opt).ok());    // along the crease
  CHECK_FALSE(check_surface_contraction(m, vertex_at(m, Vec3(0.5, 0.25, 1)), v, opt).ok());  // onto the top face
  CHECK_FALSE(check_surface_contraction(m, vertex_at(m, Vec3(0.5, 0, 0.75)), v, opt).ok());  // onto the front face
  // A corner of the box keeps its place whatever the bound.
  const VertexId corner = vertex_at(m, Vec3(1, 1, 1));
  opt.surface_deviation = 10;
  CHECK_FALSE(check_surface_contraction(m, vertex_at(m, Vec3(0.75, 1, 1)), corner, opt).ok());
  // An interior vertex is not the surface contraction's business.
  CHECK_FALSE(check_surface_contraction(m, vertex_at(m, Vec3(0.75, 0.5, 0.5)), vertex_at(m, Vec3(0.5, 0.5, 0.5)), opt).ok());
}

// CollapseOptions::restore_volume (the cutter's exact_volumes): a contraction that moves the
// surface moves the kept vertex by what gives the label its volume back, within the cut planes
// there. A unit cube of 4x4x4 cells whose top edge from (1, 0.5, 1) to (0.75, 0.5, 1) is split a
// hair from its end: the new vertex is lifted off the top, and the right face (x = 1) is tagged
// as a cut.
TEST_CASE("surface contraction: restore_volume gives the volume back, the kept vertex staying in its cut plane",
          "[quality][collapse]") {
  TetMesh m = make_box(Vec3(1, 1, 1), {4, 4, 4});
  const VertexId keep = vertex_at(m, Vec3(1, 0.5, 1));
  const VertexId v = m.split_edge(keep, vertex_at(m, Vec3(0.75, 0.5, 1)), 0.04);
  const double lift = 0.002;
  m.set_rest(v, Vec3(0.99, 0.5, 1 + lift));
  for (TetId t : m.tets())
    for (int f = 0; f < 4; ++f) {
      if (m.neighbor(t, f).is_valid()) continue;
      bool right = true;
      for (int k = 0; k < 4; ++k)
        if (k != f) right = right && m.rest(m.tet_vertices(t)[std::size_t(k)]).x() == 1.0;
      if (right) m.set_face_tag(t, f, kTagCut);
    }
  m.discard_change();
  const double volume = m.total_volume();
  REQUIRE(volume > 1.0);
  TetId t;  // a tet of the short edge
  for (TetId u : m.incident_tets(v))
    for (VertexId w : m.tet_vertices(u))
      if (w == keep) t = u;
  REQUIRE(t.is_valid());
  CollapseOptions opt;
  opt.surface_deviation = 0.2;
  opt.feature_angle_deg = 30;
  ImproveScope scope;
  SECTION("restored: the volume to rounding, the kept vertex on x = 1 and raised by 3 dV / A") {
    // The volume the contraction alone moves, and the area of the kept vertex's top faces after
    // it: raising a vertex of a flat fan by h adds A h / 3.
    const CollapseCheck c = check_surface_contraction(m, keep, v, opt);
    REQUIRE(c.ok());
    TetMesh plain = m;
    collapse_edge(plain, c.plan);
    const double lost = volume - plain.total_volume();
    REQUIRE(lost > 0);
    double top = 0;
    for (const SurfaceFace& f : surface_faces_after(plain, keep, {}, {})) {
      const Vec3 a = plain.rest(f.v[0]), b = plain.rest(f.v[1]), d = plain.rest(f.v[2]);
      const Vec3 n = (b - a).cross(d - a);
      if (std::abs(n.normalized().z()) > 0.999) top += 0.5 * n.norm();
    }
    opt.restore_volume = true;
    const auto out = improve_by_collapse(m, t, scope, opt);
    REQUIRE(out);
    CHECK(out->kept == keep);
    CHECK(out->kept_moved);
    CHECK_FALSE(m.is_alive(v));
    m.validate({.check_orientation = true, .check_manifold_boundary = true});
    CHECK(m.total_volume() == Approx(volume).epsilon(1e-12));
    CHECK(std::abs(m.rest(keep).x() - 1.0) < 1e-12);
    CHECK(m.rest(keep).z() - 1.0 == Approx(3 * lost / top).epsilon(1e-6));
    CHECK(std::abs(m.rest(keep).y() - 0.5) < 1e-9);
  }
  SECTION("without restore_volume the same contraction moves the volume") {
    const auto out = improve_by_collapse(m, t, scope, opt);
    REQUIRE(out);
    CHECK_FALSE(out->kept_moved);
    CHECK(m.total_volume() < volume - 1e-7);
  }
  SECTION("the top a cut too: its tilted faces and the right face leave the kept vertex no direction, refused") {
    for (TetId u : m.tets())
      for (int f = 0; f < 4; ++f) {
        if (m.neighbor(u, f).is_valid()) continue;
        bool top = true;
        for (int k = 0; k < 4; ++k)
          if (k != f) top = top && m.rest(m.tet_vertices(u)[std::size_t(k)]).z() > 1 - 1e-9;
        if (top) m.set_face_tag(u, f, kTagCut);
      }
    opt.restore_volume = true;
    CHECK_FALSE(improve_by_collapse(m, t, scope, opt));
    CHECK(m.is_alive(v));
  }
}
