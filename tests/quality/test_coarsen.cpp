// Coarsening (quality/coarsen.h), checked against the input by brute force: the tet count
// falls to 1/4 .. 1/10, the mesh stays valid (positive tets, closed manifold boundary, no
// worse angles than the input's or the floor), labels and tags stay with their volumes and
// areas, every input surface vertex stays within the stated deviation of the coarse surface and
// every coarse surface vertex lies on the input's, and the result is the same every run.
#include <catch2/catch.hpp>

#include <map>

#include "mesh/errors.h"
#include "mesh/generate.h"
#include "mesh/io/tet_io.h"
#include "mesh/point_locator.h"
#include "quality/coarsen.h"
#include "quality/metrics.h"
#include "testing/mesh_measures.h"

using namespace incise;
using incise::testing::label_volumes;
using incise::testing::tag_areas;

namespace {


// Largest distance from a boundary vertex of `from` to the boundary surface of `to`.
double surface_distance(const TetMesh& from, const TetMesh& to) {
  const auto faces = to.boundary_faces();
  double worst = 0;
  for (const auto& f : from.boundary_faces())
    for (VertexId v : f.vertices) {
      const Vec3 p = from.rest(v);
      double best = 1e300;
      for (const auto& g : faces)
        best = std::min(best, (p - closest_on_triangle(p, to.rest(g.vertices[0]), to.rest(g.vertices[1]), to.rest(g.vertices[2]))).norm());
      worst = std::max(worst, best);
    }
  return worst;
}

struct Checked {
  TetMesh mesh;  // the coarse one, compacted
  CoarsenReport report;
  double ratio = 0, deviation_out = 0, deviation_in = 0;
};

// Everything that holds on any input; returns the figures the cases bound.
Checked coarsen_and_check(const TetMesh& input, const CoarsenOptions& opt = {}) {
  Checked c;
  c.mesh = input;
  TetMesh& m = c.mesh;
  c.report = coarsen(m, opt);
  m.discard_change();
  m.compact();
  TetMesh::ValidateOptions vo;
  vo.check_manifold_boundary = true;
  REQUIRE_NOTHROW(m.validate(vo));
  c.ratio = double(m.num_tets()) / double(input.num_tets());
  const QualityRange before = quality_range(input), after = quality_range(m);
  CHECK(after.min_dihedral >= std::min(opt.min_dihedral_deg, before.min_dihedral) - 1e-9);
  CHECK(after.max_dihedral <= std::max(opt.max_dihedral_deg, before.max_dihedral) + 1e-9);
  // Labels and tags: the same sets.
  const auto lv0 = label_volumes(input), lv1 = label_volumes(m);
  REQUIRE(lv0.size() == lv1.size());
  for (const auto& [l, v] : lv0) CHECK(lv1.count(l) == 1);
  const auto ta0 = tag_areas(input), ta1 = tag_areas(m);
  REQUIRE(ta0.size() == ta1.size());
  for (const auto& [t, a] : ta0) CHECK(ta1.count(t) == 1);
  // Two-sided surface distance: input surface vertices near the coarse surface, coarse surface
  // vertices on the input surface (they are input vertices, moved only within flat parts).
  c.deviation_out = surface_distance(input, m);
  c.deviation_in = surface_distance(m, input);
  CHECK(c.deviation_out <= c.report.max_deviation * (1 + 1e-9));
  CHECK(c.deviation_in <= 1e-9 * c.report.target_edge);
  return c;
}

}  // namespace

TEST_CASE("coarsening the sample liver: a quarter of the tets, the same body", "[quality][coarsen]") {
  const TetMesh liver = read_tet_mesh(std::string(INCISE_SOURCE_DIR) + "/samples/liver.msh");
  const Checked c = coarsen_and_check(liver);
  INFO("tets " << c.report.tets_before << " -> " << c.report.tets_after << ", mean edge " << c.report.mean_edge_before
               << " -> " << c.report.mean_edge_after << ", surface deviation " << c.deviation_out << " (bound "
               << c.report.max_deviation << ")");
  CHECK(c.ratio <= 0.3);
  CHECK(c.ratio >= 0.1);
  CHECK(c.report.mean_edge_after >= 1.3 * c.report.mean_edge_before);
  // The coarse surface's chords cut into the convex parts: a few percent of the volume
  // (measured -2.9%).
  const TetMesh& m = c.mesh;
  const double v0 = liver.total_volume(), v1 = m.total_volume();
  CHECK(std::abs(v1 - v0) <= 0.04 * v0);
  const auto ta0 = tag_areas(liver), ta1 = tag_areas(m);
  for (const auto& [t, a] : ta0) CHECK(std::abs(ta1.at(t) - a) <= 0.15 * a);
  // Its three labels (the smallest one 78 tets) keep their volumes within 10% (measured: -7%,
  // -6%, -2.5%): the interfaces are sheets with the same deviation bound.
  const auto lv0 = label_volumes(liver), lv1 = label_volumes(m);
  for (const auto& [l, v] : lv0) CHECK(std::abs(lv1.at(l) - v) <= 0.1 * v);
}

TEST_CASE("coarsening a two-label box keeps its corners, edges and label volumes exactly", "[quality][coarsen]") {
  TetMesh box = make_box(Vec3(2, 1, 1), {12, 6, 6});
  for (TetId t : box.tets()) {
    Vec3 c = Vec3::Zero();
    for (VertexId v : box.tet_vertices(t)) c += box.rest(v) / 4;
    if (c.x() > 1.2) box.set_label(t, 2);  // a flat interface at x = 1.2
  }
  const Checked c = coarsen_and_check(box);
  INFO("tets " << c.report.tets_before << " -> " << c.report.tets_after);
  CHECK(c.ratio <= 0.25);
  CHECK(c.ratio >= 1.0 / 16);
  const TetMesh& m = c.mesh;
  // Flat faces and a flat interface: volumes, areas and corners exactly (up to rounding).
  const auto lv0 = label_volumes(box), lv1 = label_volumes(m);
  for (const auto& [l, v] : lv0) CHECK(std::abs(lv1.at(l) - v) <= 1e-9 * v);
  const auto ta0 = tag_areas(box), ta1 = tag_areas(m);
  for (const auto& [t, a] : ta0) CHECK(std::abs(ta1.at(t) - a) <= 1e-9 * a);
  int corners = 0;
  for (VertexId v : m.vertices()) {
    const Vec3 p = m.rest(v);
    corners += (p.x() == 0 || p.x() == 2) && (p.y() == 0 || p.y() == 1) && (p.z() == 0 || p.z() == 1);
  }
  CHECK(corners == 8);
}

TEST_CASE("coarsening is deterministic", "[quality][coarsen]") {
  const TetMesh box = make_box(Vec3(1, 1, 1), {8, 8, 8});
  TetMesh a = box, b = box;
  coarsen(a);
  coarsen(b);
  REQUIRE(a.vertex_capacity() == b.vertex_capacity());
  REQUIRE(a.tet_capacity() == b.tet_capacity());
  for (VertexId v : a.vertices()) {
    REQUIRE(b.is_alive(v));
    CHECK(a.rest(v) == b.rest(v));
  }
  for (TetId t : a.tets()) {
    REQUIRE(b.is_alive(t));
    CHECK(a.tet_vertices(t) == b.tet_vertices(t));
  }
}

TEST_CASE("coarsening refuses bad options", "[quality][coarsen]") {
  TetMesh box = make_box(Vec3(1, 1, 1), {2, 2, 2});
  CoarsenOptions o;
  o.edge_factor = 0;
  CHECK_THROWS_AS(coarsen(box, o), InvalidArgument);
  o = {};
  o.max_deviation = -1;
  CHECK_THROWS_AS(coarsen(box, o), InvalidArgument);
}
