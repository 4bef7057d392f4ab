// The mesh quality report on generated and hand-built meshes: statistics, classes, worst
// elements, boundary topology, components, labels.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>

#include "mesh/errors.h"
#include "mesh/generate.h"
#include "quality/report.h"
#include "quality/thin_parts.h"
#include "testing/mesh_measures.h"

using namespace incise;
using incise::testing::vertex_at;

namespace {

// Copies `src` into `dst`, translated by `offset`.
void append(TetMesh& dst, const TetMesh& src, const Vec3& offset, int label_shift = 0) {
  std::vector<VertexId> map(src.vertex_capacity());
  for (VertexId v : src.vertices()) map[v.idx()] = dst.add_vertex(src.rest(v) + offset);
  for (TetId t : src.tets()) {
    const auto& v = src.tet_vertices(t);
    dst.add_tet(map[v[0].idx()], map[v[1].idx()], map[v[2].idx()], map[v[3].idx()], src.label(t) + label_shift);
  }
  dst.discard_change();
}

// Percentile by sorting, linear interpolation (numpy's default).
double percentile(std::vector<double> x, double p) {
  std::sort(x.begin(), x.end());
  double pos = p / 100 * (x.size() - 1);
  std::size_t i = static_cast<std::size_t>(pos);
  double f = pos - i;
  return i + 1 < x.size() ? x[i] + f * (x[i + 1] - x[i]) : x[i];
}

const double kKuhnRadiusRatio = 0.717439;

}  // namespace

TEST_CASE("report on a box of Kuhn tets", "[quality][report]") {
  for (double scale : {1.0, 1e8, 1e-8}) {
    INFO("scale " << scale);
    const Vec3 size = Vec3(3, 2, 1) * scale;
    TetMesh m = make_box(size, {3, 2, 1}, 4);
    QualityReport r = compute_quality_report(m);
    CHECK(r.vertices == 4 * 3 * 2);
    CHECK(r.tets == 6 * 6);
    CHECK(r.unreferenced_vertices == 0);
    CHECK(r.total_volume == Approx(6 * scale * scale * scale).epsilon(1e-12));
    CHECK(r.bbox_min.norm() == 0);
    CHECK((r.bbox_max - size).norm() <= 1e-15 * scale);
    CHECK(r.min_edge == Approx(scale).epsilon(1e-14));
    CHECK(r.max_edge == Approx(std::sqrt(3.0) * scale).epsilon(1e-14));
    CHECK(r.inverted == 0);
    CHECK(r.degenerate == 0);
    CHECK(r.slivers == 0);
    // Every tet is a Kuhn tet: every statistic of min dihedral is 45, of max dihedral 90.
    const MetricStats& mind = r.stats(Metric::MinDihedral);
    CHECK(mind.count == r.tets);
    for (double x : {mind.min, mind.max, mind.mean, mind.percentiles[0], mind.percentiles[2], mind.percentiles[4]})
      CHECK(x == Approx(45).epsilon(1e-12));
    CHECK(r.stats(Metric::MaxDihedral).max == Approx(90).epsilon(1e-12));
    CHECK(r.stats(Metric::RadiusRatio).mean == Approx(kKuhnRadiusRatio).margin(1e-6));
    // Histogram over [0, 90] in 10 bins: all in [45, 54).
    REQUIRE(mind.histogram.counts.size() == 10);
    CHECK(mind.histogram.counts[5] == r.tets);
    CHECK(mind.histogram.below + mind.histogram.above == 0);
    CHECK(r.stats(Metric::Volume).histogram.counts.back() == r.tets);  // equal volumes: all near hi = max

    CHECK(r.components == 1);
    CHECK(r.boundary.faces == 2 * (6 + 3 + 2) * 2);
    CHECK(r.boundary.shells == 1);
    CHECK(r.boundary.closed());
    CHECK(r.boundary.manifold());
    CHECK(r.boundary.oriented());
    // Euler: a closed genus-0 triangulated surface has E = 3F/2.
    CHECK(r.boundary.edges * 2 == r.boundary.faces * 3);

    REQUIRE(r.labels.size() == 1);
    CHECK(r.labels[0].label == 4);
    CHECK(r.labels[0].tets == r.tets);
    CHECK(r.labels[0].volume == Approx(r.total_volume).epsilon(1e-14));
    CHECK(r.labels[0].min_dihedral == Approx(45).epsilon(1e-12));

    CHECK(r.worst.size() == 10);
    CHECK(r.solver.available);
    CHECK(r.solver.kappa > 1);
  }
}

TEST_CASE("report thresholds follow the options", "[quality][report]") {
  TetMesh m = make_box(Vec3(1, 1, 1), {2, 2, 2});
  QualityOptions o;
  o.sliver_angle = 50;  // every Kuhn tet (45 degrees) now counts as a sliver
  o.histogram_bins = 3;
  o.worst_count = 1000;
  o.worst_metric = Metric::MaxDihedral;
  QualityReport r = compute_quality_report(m, o);
  CHECK(r.slivers == r.tets);
  CHECK(r.worst.size() == r.tets);  // capped at the number of tets
  for (const MetricStats& s : r.metrics) CHECK(s.histogram.counts.size() == 3);
  o.histogram_bins = 0;
  CHECK_THROWS_AS(compute_quality_report(m, o), InvalidArgument);
  o.histogram_bins = 10;
  o.sliver_angle = -1;
  CHECK_THROWS_AS(compute_quality_report(m, o), InvalidArgument);
  o.sliver_angle = 10;
  o.worst_count = -1;
  CHECK_THROWS_AS(compute_quality_report(m, o), InvalidArgument);
}

TEST_CASE("report statistics match a brute-force computation on an ellipsoid", "[quality][report]") {
  TetMesh m = make_ellipsoid(Vec3(3, 2, 1), 4, 2);
  QualityOptions o;
  o.worst_count = 25;
  o.worst_metric = Metric::RadiusRatio;
  QualityReport r = compute_quality_report(m, o);
  const double pi = 3.14159265358979323846;
  CHECK(r.total_volume == Approx(4.0 / 3 * pi * 6).epsilon(0.1));
  CHECK(r.components == 1);
  CHECK(r.boundary.closed());
  CHECK(r.boundary.manifold());
  CHECK(r.boundary.shells == 1);
  CHECK(r.inverted == 0);
  for (const MetricInfo& mi : all_metrics()) {
    INFO(mi.name);
    std::vector<double> x;
    for (TetId t : m.tets()) x.push_back(metric_value(tet_quality(m, t), mi.metric));
    const MetricStats& s = r.stats(mi.metric);
    CHECK(s.count == x.size());
    CHECK(s.min == *std::min_element(x.begin(), x.end()));
    CHECK(s.max == *std::max_element(x.begin(), x.end()));
    double mean = 0;
    for (double v : x) mean += v / x.size();
    CHECK(s.mean == Approx(mean).epsilon(1e-12));
    for (std::size_t k = 0; k < kReportPercentiles.size(); ++k)
      CHECK(s.percentiles[k] == Approx(percentile(x, kReportPercentiles[k])).epsilon(1e-14));
    std::size_t total = s.histogram.below + s.histogram.above;
    for (std::size_t c : s.histogram.counts) total += c;
    CHECK(total == x.size());
    if (mi.metric == Metric::RadiusRatio) {
      // The worst list holds exactly the smallest values, in order.
      std::sort(x.begin(), x.end());
      REQUIRE(r.worst.size() == 25);
      for (std::size_t k = 0; k < r.worst.size(); ++k) {
        CHECK(r.worst[k].quality.radius_ratio == x[k]);
        CHECK(r.worst[k].label == 2);
        CHECK(m.is_alive(r.worst[k].tet));
      }
    }
  }
}

TEST_CASE("inverted and degenerate tets are counted and ranked first", "[quality][report]") {
  TetMesh m = make_box(Vec3(2, 2, 2), {2, 2, 2});
  VertexId c = vertex_at(m, Vec3(1, 1, 1));
  REQUIRE(c.is_valid());
  VertexId top = vertex_at(m, Vec3(2, 2, 2));
  // The centre vertex through the bottom face: tets with three vertices on z = 0 invert. The
  // top corner falls onto the vertex below it: the tets holding both collapse.
  std::vector<Vec3> pos(m.vertex_capacity());
  for (VertexId v : m.vertices()) pos[v.idx()] = m.rest(v);
  pos[c.idx()] = Vec3(1, 1, -0.5);
  pos[top.idx()] = Vec3(2, 2, 1);
  std::size_t flat = 0, negative = 0;
  for (TetId t : m.tets()) {
    const auto& v = m.tet_vertices(t);
    double det = (pos[v[1].idx()] - pos[v[0].idx()]).dot((pos[v[2].idx()] - pos[v[0].idx()]).cross(pos[v[3].idx()] - pos[v[0].idx()]));
    flat += det == 0;
    negative += det < 0;
  }
  REQUIRE(flat > 0);
  REQUIRE(negative > 0);
  QualityReport r = compute_quality_report(m, {}, pos);
  CHECK(r.degenerate == flat);
  CHECK(r.inverted == negative);
  CHECK(r.labels[0].degenerate == flat);
  CHECK(r.labels[0].inverted == negative);
  CHECK(r.stats(Metric::MeanRatio).min < 0);
  CHECK(r.stats(Metric::MeanRatio).histogram.below == negative);
  // Default ranking is by signed mean ratio: inverted first, then the flat ones.
  REQUIRE(r.worst.size() == 10);
  for (std::size_t k = 0; k < std::min<std::size_t>(negative, 10); ++k) CHECK(r.worst[k].quality.volume < 0);
  CHECK_FALSE(r.solver.available);
  for (const MetricStats& s : r.metrics) {
    CHECK(std::isfinite(s.min));
    CHECK(std::isfinite(s.max));
    CHECK(std::isfinite(s.mean));
  }
  // The rest configuration is untouched and clean.
  CHECK(compute_quality_report(m).inverted == 0);
}

TEST_CASE("components and boundary shells", "[quality][report]") {
  SECTION("two disjoint boxes") {
    TetMesh m = make_box(Vec3(1, 1, 1), {2, 2, 2}, 1);
    append(m, make_box(Vec3(1, 1.5, 0.5), {2, 3, 1}, 1), Vec3(5, 0, 0), 1);
    QualityReport r = compute_quality_report(m);
    CHECK(r.components == 2);
    CHECK(r.boundary.shells == 2);
    CHECK(r.boundary.closed());
    CHECK(r.boundary.manifold());
    REQUIRE(r.labels.size() == 2);
    CHECK(r.labels[0].label == 1);
    CHECK(r.labels[0].tets == 48);
    CHECK(r.labels[0].volume == Approx(1));
    CHECK(r.labels[1].label == 2);
    CHECK(r.labels[1].tets == 36);
    CHECK(r.labels[1].mean_radius_ratio == Approx(kKuhnRadiusRatio).margin(1e-6));
    CHECK(tet_components(m).sizes == std::vector<std::size_t>{48, 36});
  }
  SECTION("a box with a cavity: one component, two shells") {
    TetMesh m = make_box(Vec3(3, 3, 3), {3, 3, 3});
    for (TetId t : m.tets()) {
      Vec3 centroid = Vec3::Zero();
      for (VertexId v : m.tet_vertices(t)) centroid += m.rest(v) / 4;
      if ((centroid.array() > 1).all() && (centroid.array() < 2).all()) m.remove_tet(t);
    }
    REQUIRE(m.num_tets() == 26 * 6);
    QualityReport r = compute_quality_report(m);
    CHECK(r.components == 1);
    CHECK(r.boundary.shells == 2);
    CHECK(r.boundary.closed());
    CHECK(r.boundary.manifold());
    CHECK(r.total_volume == Approx(26));
  }
  SECTION("a box with a corner tet removed stays closed and manifold") {
    TetMesh m = make_box(Vec3(2, 2, 2), {2, 2, 2});
    VertexId corner = vertex_at(m, Vec3(0, 0, 0));
    REQUIRE(m.incident_tets(corner).size() == 6);
    m.remove_tet(m.incident_tets(corner)[0]);
    QualityReport r = compute_quality_report(m);
    CHECK(r.tets == 47);
    CHECK(r.components == 1);
    CHECK(r.boundary.shells == 1);
    CHECK(r.boundary.closed());
    CHECK(r.boundary.manifold());
    CHECK(r.boundary.oriented());
    CHECK_NOTHROW(m.validate({true, true}));
    CHECK(r.total_volume == Approx(8 - 1.0 / 6));
  }
  SECTION("a split mesh splits into components") {
    // Removing the middle layer of a 1x1x3 bar leaves two components.
    TetMesh m = make_box(Vec3(1, 1, 3), {1, 1, 3});
    for (TetId t : m.tets()) {
      double z = 0;
      for (VertexId v : m.tet_vertices(t)) z += m.rest(v).z() / 4;
      if (z > 1 && z < 2) m.remove_tet(t);
    }
    QualityReport r = compute_quality_report(m);
    CHECK(r.components == 2);
    CHECK(r.boundary.shells == 2);
    CHECK(r.unreferenced_vertices == 0);
  }
}

TEST_CASE("non-manifold configurations are counted", "[quality][report]") {
  SECTION("bowtie: two tets sharing only an edge") {
    TetMesh m;
    VertexId a = m.add_vertex(Vec3(0, 0, 0)), b = m.add_vertex(Vec3(0, 0, 1));
    VertexId c = m.add_vertex(Vec3(1, 0, 0)), d = m.add_vertex(Vec3(0, 1, 0));
    VertexId e = m.add_vertex(Vec3(-1, 0, 0)), f = m.add_vertex(Vec3(0, -1, 0));
    TetId t1 = m.add_tet(a, c, d, b);
    TetId t2 = m.add_tet(a, e, f, b);
    REQUIRE(m.volume(t1) > 0);
    REQUIRE(m.volume(t2) > 0);
    CHECK_THROWS(m.validate({true, true}));  // agrees: not a manifold boundary
    QualityReport r = compute_quality_report(m);
    CHECK(r.components == 2);
    CHECK(r.boundary.faces == 8);
    CHECK(r.boundary.non_manifold_edges == 1);
    CHECK(r.boundary.non_manifold_vertices == 2);  // the edge's endpoints
    CHECK(r.boundary.open_edges == 0);
    CHECK(r.boundary.closed());
    CHECK_FALSE(r.boundary.manifold());
    CHECK(r.boundary.shells == 1);  // the faces meet at the edge
    CHECK(format_quality_report(r).find("NON-MANIFOLD") != std::string::npos);
  }
  SECTION("two tets sharing only a vertex, and an isolated vertex") {
    TetMesh m;
    VertexId o = m.add_vertex(Vec3(0, 0, 0));
    VertexId p[6] = {m.add_vertex(Vec3(1, 0, 0)),  m.add_vertex(Vec3(0, 1, 0)),  m.add_vertex(Vec3(0, 0, 1)),
                     m.add_vertex(Vec3(-1, 0, 0)), m.add_vertex(Vec3(0, -1, 0)), m.add_vertex(Vec3(0, 0, -1))};
    m.add_tet(o, p[0], p[1], p[2]);
    m.add_tet(o, p[3], p[5], p[4]);
    m.add_vertex(Vec3(5, 5, 5));
    QualityReport r = compute_quality_report(m);
    CHECK(r.inverted == 0);
    CHECK(r.unreferenced_vertices == 1);
    CHECK(r.components == 2);
    CHECK(r.boundary.non_manifold_edges == 0);
    CHECK(r.boundary.non_manifold_vertices == 1);
    CHECK(r.boundary.shells == 2);  // shells connect through edges, not vertices
    CHECK(r.bbox_max == Vec3(5, 5, 5));
  }
  SECTION("an inverted tet's boundary faces run against their neighbours'") {
    TetMesh m;
    VertexId a = m.add_vertex(Vec3(0, 0, 0)), b = m.add_vertex(Vec3(1, 0, 0)), c = m.add_vertex(Vec3(0, 1, 0)),
             d = m.add_vertex(Vec3(0, 0, 1)), e = m.add_vertex(Vec3(1, 1, 1));
    m.add_tet(a, b, c, d);
    m.add_tet(b, c, e, d);  // shares face bcd; listed with the wrong orientation
    QualityReport r = compute_quality_report(m);
    CHECK(r.inverted == 1);
    CHECK(r.boundary.misoriented_edges == 3);
    CHECK_FALSE(r.boundary.oriented());
    CHECK(r.boundary.manifold());
  }
}

TEST_CASE("report on an empty mesh is well defined", "[quality][report]") {
  TetMesh m;
  QualityReport r = compute_quality_report(m);
  CHECK(r.tets == 0);
  CHECK(r.components == 0);
  CHECK(r.boundary.shells == 0);
  CHECK(r.worst.empty());
  CHECK(r.metrics.size() == kNumMetrics);
  CHECK(r.stats(Metric::MeanRatio).count == 0);
  CHECK_FALSE(r.solver.available);
  CHECK_FALSE(format_quality_report(r).empty());
}

TEST_CASE("text report shows the essentials", "[quality][report]") {
  TetMesh m = make_box(Vec3(1, 1, 1), {2, 2, 2}, 3);
  const std::string s = format_quality_report(compute_quality_report(m));
  for (const char* needle : {"tets 48", "1 component", "closed", "manifold", "min dihedral", "mean ratio",
                             "worst 10 by mean_ratio", "condition number", "0 inverted"})
    CHECK_THAT(s, Catch::Contains(needle));
}

TEST_CASE("sharpest boundary edge: the bound on the smallest dihedral angle", "[quality][report]") {
  // A box: every boundary edge is a 90-degree box edge or a flat (180) face diagonal.
  const TetMesh box = make_box(Vec3(1, 2, 3), {2, 3, 4});
  const auto a = smallest_boundary_angle(box);
  REQUIRE(a);
  CHECK(a->degrees == Approx(90).margin(1e-9));
  // The edge it names is a box edge: its two ends differ in exactly one coordinate.
  const Vec3 d = box.rest(a->b) - box.rest(a->a);
  CHECK(int(std::abs(d.x()) > 1e-12) + int(std::abs(d.y()) > 1e-12) + int(std::abs(d.z()) > 1e-12) == 1);
  // A single regular tet: each edge's interior angle is the tet's own dihedral angle.
  TetMesh one;
  const VertexId p0 = one.add_vertex(Vec3(1, 1, 1)), p1 = one.add_vertex(Vec3(1, -1, -1)),
                 p2 = one.add_vertex(Vec3(-1, 1, -1)), p3 = one.add_vertex(Vec3(-1, -1, 1));
  one.add_tet(p0, p1, p2, p3, 1);
  one.discard_change();
  REQUIRE(smallest_boundary_angle(one));
  CHECK(smallest_boundary_angle(one)->degrees == Approx(std::acos(1.0 / 3) * 180 / M_PI));
  // A wedge made sharper: squash the box in y and the box edges stay 90; shear it and the
  // sharp edge follows the shear (atan(1/2) from the shear x += 2 y on a unit box).
  TetMesh sheared = make_box(Vec3(1, 1, 1), {2, 2, 2});
  for (VertexId v : sheared.vertices()) sheared.set_rest(v, sheared.rest(v) + Vec3(2 * sheared.rest(v).y(), 0, 0));
  CHECK(smallest_boundary_angle(sheared)->degrees == Approx(std::atan2(1.0, 2.0) * 180 / M_PI));
  // The report carries it; an empty mesh has none.
  CHECK(compute_quality_report(box).boundary_angle->degrees == Approx(90));
  CHECK_FALSE(smallest_boundary_angle(TetMesh{}));
  CHECK(format_quality_report(compute_quality_report(box)).find("sharpest edge 90.00 deg") != std::string::npos);
}

TEST_CASE("tets forced below an angle by sharp boundary edges", "[quality][report]") {
  // The unit box of 2x2x2 cells sheared by x += 2 y: its z-edges at (x, y) = (0, 0) and (3, 1)
  // have the interior angle atan(1/2) = 26.57 deg, the other two 153.43, the rest 90 or flat.
  TetMesh sheared = make_box(Vec3(1, 1, 1), {2, 2, 2});
  for (VertexId v : sheared.vertices()) sheared.set_rest(v, sheared.rest(v) + Vec3(2 * sheared.rest(v).y(), 0, 0));
  auto on_sharp_line = [&](VertexId v) {
    const Vec3 p = sheared.rest(v);
    return (std::abs(p.x()) < 1e-12 && std::abs(p.y()) < 1e-12) || (std::abs(p.x() - 3) < 1e-12 && std::abs(p.y() - 1) < 1e-12);
  };
  // Independently: the tets with an edge along one of those two lines (two segments each).
  std::vector<TetId> expected;
  for (TetId t : sheared.tets()) {
    const auto& tv = sheared.tet_vertices(t);
    bool held = false;
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j)
        held = held || (on_sharp_line(tv[i]) && on_sharp_line(tv[j]) &&
                        std::abs(sheared.rest(tv[i]).x() - sheared.rest(tv[j]).x()) < 1e-12);
    if (held) expected.push_back(t);
  }
  REQUIRE_FALSE(expected.empty());
  const SharpBoundary s = sharp_boundary(sheared, 30);
  CHECK(s.edges == 4);
  CHECK(s.tets == expected);
  // Each of them is below the edge's angle, as the bound says.
  for (TetId t : s.tets) CHECK(tet_quality(sheared, t).min_dihedral < std::atan2(1.0, 2.0) * 180 / M_PI + 1e-9);
  // Below the sharpest edge nothing is forced; the box's 90-degree edges are not under 89.9, all 24 segments are under 90.01.
  CHECK(sharp_boundary(sheared, 26).edges == 0);
  CHECK(sharp_boundary(sheared, 26).tets.empty());
  CHECK(sharp_boundary(make_box(Vec3(1, 1, 1), {2, 2, 2}), 89.9).tets.empty());
  CHECK(sharp_boundary(make_box(Vec3(1, 1, 1), {2, 2, 2}), 90.01).edges == 24);
  // The report counts them among its slivers at that angle, and none below the sharpest edge.
  QualityOptions at30;
  at30.sliver_angle = 30;
  const QualityReport r30 = compute_quality_report(sheared, at30);
  CHECK(r30.forced_slivers == expected.size());
  CHECK(r30.slivers >= r30.forced_slivers);
  QualityOptions at26;
  at26.sliver_angle = 26;
  CHECK(compute_quality_report(sheared, at26).forced_slivers == 0);
  CHECK(format_quality_report(r30).find(std::to_string(expected.size()) + " of them forced by boundary edges") !=
        std::string::npos);
}

TEST_CASE("slivers across thin parts", "[quality][report]") {
  // A slab one cell of 1 x 1 wide and 0.05 thick: every tet has vertices on both faces, is at
  // most 0.05 across (the slab's thickness, independently of the normals the count reads) and
  // has an edge of at least 1: each is a sliver, and each lies across a part thinner than a
  // quarter of its longest edge.
  const TetMesh slab = make_box(Vec3(4, 4, 0.05), {4, 4, 1});
  std::size_t slivers = 0;
  for (TetId t : slab.tets()) slivers += tet_quality(slab, t).min_dihedral < 10;
  REQUIRE(slivers == slab.num_tets());
  const std::vector<TetId> thin = slivers_across_thin_parts(slab);
  CHECK(thin.size() == slab.num_tets());
  CHECK(std::is_sorted(thin.begin(), thin.end()));
  // The ratio is what decides: 0.05 over the longest edge (sqrt(2 + 0.0025)) is 0.0353.
  ThinPartOptions tighter;
  tighter.ratio = 0.035;
  CHECK(slivers_across_thin_parts(slab, tighter).empty());
  tighter.ratio = 0.036;
  CHECK(slivers_across_thin_parts(slab, tighter).size() == slab.num_tets());
  // Excluded tets are left out.
  CHECK(slivers_across_thin_parts(slab, {}, {thin.front()}).size() == thin.size() - 1);
  const QualityReport r = compute_quality_report(slab);
  CHECK(r.slivers == slab.num_tets());
  CHECK(r.forced_slivers == 0);
  CHECK(r.thin_slivers == slab.num_tets());
  CHECK(format_quality_report(r).find(std::to_string(r.thin_slivers) + " of them across parts thinner") != std::string::npos);

  // Slivers inside a thick body are not: a 4-cell cube with the vertex at its centre pushed
  // towards the layer of vertices above it flattens the tets on that layer, all of whose
  // vertices are inside.
  TetMesh cube = make_box(Vec3(4, 4, 4), {4, 4, 4});
  for (VertexId v : cube.vertices())
    if ((cube.rest(v) - Vec3(2, 2, 2)).norm() < 1e-12) cube.set_rest(v, Vec3(2, 2, 2.98));
  const QualityReport rc = compute_quality_report(cube);
  REQUIRE(rc.slivers > 0);
  CHECK(rc.thin_slivers == 0);
  CHECK(slivers_across_thin_parts(cube).empty());
  CHECK(format_quality_report(rc).find("thinner") == std::string::npos);
}

TEST_CASE("reflex boundary edges: the concave edges of a box with a corner cube taken out", "[quality][report]") {
  // A 2x2x2 box of unit cubes without the cube [1,2]^3: the three unit edges from (1,1,1)
  // towards (2,1,1), (1,2,1) and (1,1,2) have three quarter-spaces of body around them
  // (interior angle 270 degrees); every other boundary edge is at most 180.
  TetMesh m = make_box(Vec3(2, 2, 2), {2, 2, 2});
  for (TetId t : m.tets()) {
    Vec3 c = Vec3::Zero();
    for (VertexId v : m.tet_vertices(t)) c += 0.25 * m.rest(v);
    if (c.minCoeff() > 1) m.remove_tet(t);
  }
  const auto edges = reflex_boundary_edges(m, 269);
  REQUIRE(edges.size() == 3);
  for (const auto& [a, b] : edges) {
    const Vec3 pa = m.rest(a), pb = m.rest(b);
    const Vec3 lo = pa.cwiseMin(pb), hi = pa.cwiseMax(pb);
    CHECK((lo - Vec3(1, 1, 1)).norm() < 1e-12);                          // from the inner corner
    CHECK(((hi - lo).array() > 0.5).count() == 1);                      // one unit along an axis
    CHECK(a.idx() < b.idx());
  }
  CHECK(std::is_sorted(edges.begin(), edges.end()));
  CHECK(reflex_boundary_edges(m, 271).empty());
  CHECK(reflex_boundary_edges(make_box(Vec3(1, 1, 1), {2, 2, 2}), 181).empty());
}
