// Cutting: invariants after every step, exact cut placement, separation and the front,
// degenerate contacts, carving, and the TopologyChange the backends consume.
#include <catch2/catch.hpp>

#include <cmath>
#include <random>
#include <string>

#include "cut/cutter.h"
#include "cut/fragments.h"
#include "cut/predicates.h"
#include "mesh/generate.h"
#include "mesh/io/tet_io.h"
#include "quality/metrics.h"
#include "quality/components.h"
#include "tests/cut/cut_checks.h"
#include "testing/mesh_edits.h"
#include "testing/draws.h"

using namespace incise;
using namespace incise::testing;

namespace {
CutOptions plain(double snap = 0) {
  CutOptions o;
  o.snap = snap;
  o.improve = false;
  return o;
}
// Largest distance of a kTagCut face vertex from the plane through `p` with normal `n`.
double cut_face_distance(const TetMesh& m, const Vec3& p, const Vec3& n) {
  double d = 0;
  for (const auto& f : m.boundary_faces())
    if (f.tag == kTagCut)
      for (VertexId v : f.vertices) d = std::max(d, std::abs(n.normalized().dot(m.rest(v) - p)));
  return d;
}
}  // namespace

TEST_CASE("orient3d follows the mesh's orientation convention", "[cut]") {
  CHECK(orient3d(Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(1, 1, 1)) == 1);
  CHECK(orient3d(Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(1, 1, -1)) == -1);
  CHECK(orient3d(Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(5, -3, 0)) == 0);
  // Exact on nearly coplanar input where a floating determinant is noise.
  CHECK(orient3d(Vec3(0.1, 0.1, 0.1), Vec3(0.2, 0.2, 0.2), Vec3(0.3, 0.3, 0.3), Vec3(1, 2, 3)) == 0);
}

TEST_CASE("a progressive through-cut separates the box into two parts", "[cut]") {
  for (double jit : {0.0, 0.3}) {
    TetMesh m = make_box(Vec3(1, 1, 1), {4, 4, 4});
    if (jit > 0) testing::jitter(m, jit, 3);
    m.discard_change();
    const auto vol0 = label_volumes(m);
    Cutter cutter(m, plain());
    // The blade spans x beyond the box, at a y between vertex layers, and moves down in z.
    const double y = 0.43;
    cutter.start({Vec3(-0.2, y, 1.3), Vec3(1.2, y, 1.3)});
    for (int s = 1; s <= 8; ++s) {
      const double z = 1.3 - s * 0.2;
      const CutStepReport r = cutter.advance({Vec3(-0.2, y, z), Vec3(1.2, y, z)});
      check_cut_invariants(m, vol0);
      CHECK(r.change.added_tets.size() == r.tets_added);
      if (s <= 4) CHECK(tet_components(m).count == 1);  // partial: still one piece
    }
    CHECK(tet_components(m).count == 2);
    // The cut surface is the unit square at y: both sides tagged, on the blade's plane.
    CHECK(tagged_area(m, kTagCut) == Approx(2.0).epsilon(1e-6));
    CHECK(cut_face_distance(m, Vec3(0, y, 0), Vec3(0, 1, 0)) < 1e-6);
  }
}

TEST_CASE("a partial cut keeps its front attached and the next step continues it", "[cut]") {
  TetMesh m = make_ellipsoid(Vec3(1, 0.8, 0.6), 4);
  m.discard_change();
  const auto vol0 = label_volumes(m);
  Cutter cutter(m, plain());
  // A blade shorter than the body, entering from the top and stopping inside.
  cutter.start({Vec3(-0.3, 0.05, 0.9), Vec3(0.4, 0.05, 0.9)});
  double swept_inside = 0;
  for (int s = 1; s <= 5; ++s) {
    const double z = 0.9 - 0.2 * s;
    cutter.advance({Vec3(-0.3, 0.05, z), Vec3(0.4, 0.05, z)});
    check_cut_invariants(m, vol0);
    CHECK(tet_components(m).count == 1);
  }
  (void)swept_inside;
  CHECK(tagged_area(m, kTagCut) > 0);
  CHECK(cut_face_distance(m, Vec3(0, 0.05, 0), Vec3(0, 1, 0)) < 1e-6);
}

TEST_CASE("blades through vertex layers, along edges and in faces are normal cases", "[cut]") {
  for (double snap : {0.0, 0.1}) {
    TetMesh m = make_box(Vec3(1, 1, 1), {4, 4, 4});
    m.discard_change();
    const auto vol0 = label_volumes(m);
    Cutter cutter(m, plain(snap));
    // y = 0.5 is a vertex layer; the Kuhn tets have faces and edges in it.
    cutter.start({Vec3(-0.1, 0.5, 1.2), Vec3(1.1, 0.5, 1.2)});
    for (int s = 1; s <= 4; ++s) {
      cutter.advance({Vec3(-0.1, 0.5, 1.2 - 0.35 * s), Vec3(1.1, 0.5, 1.2 - 0.35 * s)});
      check_cut_invariants(m, vol0);
    }
    CHECK(tet_components(m).count == 2);
    CHECK(tagged_area(m, kTagCut) == Approx(2.0).epsilon(1e-9));
    CHECK(cut_face_distance(m, Vec3(0, 0.5, 0), Vec3(0, 1, 0)) < 1e-12);
  }
  // A diagonal blade through vertices and edges of the Kuhn split.
  TetMesh m = make_box(Vec3(1, 1, 1), {3, 3, 3});
  m.discard_change();
  const auto vol0 = label_volumes(m);
  Cutter cutter(m, plain());
  const CutStepReport r = cutter.cut_plane(Vec3(0.5, 0.5, 0.5), Vec3(1, -1, 0));
  check_cut_invariants(m, vol0);
  CHECK(tet_components(m).count == 2);
  CHECK(tagged_area(m, kTagCut) == Approx(2 * std::sqrt(2.0)).epsilon(1e-9));
  CHECK(r.fragments.size() == 1);
}

TEST_CASE("a rotating blade cuts two non-coplanar triangles per step", "[cut]") {
  TetMesh m = make_box(Vec3(1, 1, 1), {5, 5, 5});
  testing::jitter(m, 0.2, 9);
  m.discard_change();
  const auto vol0 = label_volumes(m);
  Cutter cutter(m, plain(0.05));
  cutter.start({Vec3(-0.2, 0.5, 1.3), Vec3(1.2, 0.5, 1.3)});
  for (int s = 1; s <= 6; ++s) {
    const double a = 0.08 * s, z = 1.3 - 0.25 * s;
    cutter.advance({Vec3(-0.2, 0.5 - a, z), Vec3(1.2, 0.5 + a, z)});
    check_cut_invariants(m, vol0);
  }
  CHECK(tet_components(m).count == 2);
}

TEST_CASE("crossing blades near a shared corner do not cascade into slivers", "[cut]") {
  // Ten random sweeps over the liver (bench_cut's quality driver). Cut 10, step 5 used to
  // embed its two side segments interleaved: near their shared corner (just outside the
  // surface) each one's face split made a fresh face for the other, ~60 splits converging on
  // one spot and a tet with radius ratio 1.7e-21. One segment at a time, it is 3e-5.
  TetMesh m = read_tet_mesh(std::string(INCISE_SOURCE_DIR) + "/samples/liver.msh");
  m.discard_change();
  const auto vol0 = label_volumes(m);
  Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
  for (VertexId v : m.vertices()) {
    lo = lo.cwiseMin(m.rest(v));
    hi = hi.cwiseMax(m.rest(v));
  }
  std::mt19937 rng(2026);
  std::uniform_real_distribution<double> u(0, 1);
  std::normal_distribution<double> nd;
  const double diag = (hi - lo).norm();
  CutOptions opt;
  opt.improve = false;
  Cutter cutter(m, opt);
  for (int i = 0; i < 10; ++i) {
    const Vec3 c = lo + draw_vec3(u, rng).cwiseProduct(hi - lo);
    const Vec3 dir = draw_vec3(nd, rng).normalized();
    Vec3 sweep = draw_vec3(nd, rng);
    sweep = (sweep - sweep.dot(dir) * dir).normalized() * diag * (0.15 + 0.3 * u(rng));
    const double len = diag * (0.15 + 0.3 * u(rng));
    const Vec3 a = c - 0.5 * len * dir - 0.5 * sweep, b = c + 0.5 * len * dir - 0.5 * sweep;
    cutter.start({a, b});
    for (int s = 1; s <= 5; ++s) {
      const Vec3 off = sweep * (s / 5.0);
      const CutStepReport r = cutter.advance({a + off, b + off});
      CHECK(r.tets_added < 1000);
      check_cut_invariants(m, vol0);
    }
  }
  CHECK(quality_range(m).min_radius_ratio > 1e-9);
}

TEST_CASE("snapping trades distance from the blade for fewer new tets", "[cut]") {
  std::size_t added_exact = 0, added_snap = 0;
  for (double snap : {0.0, 0.3}) {
    TetMesh m = make_box(Vec3(1, 1, 1), {6, 6, 6});
    testing::jitter(m, 0.3, 5);
    m.discard_change();
    const auto vol0 = label_volumes(m);
    Cutter cutter(m, plain(snap));
    const auto r = cutter.cut_plane(Vec3(0.5, 0.52, 0.5), Vec3(0.1, 1, 0.05));
    check_cut_invariants(m, vol0);
    CHECK(tet_components(m).count == 2);
    const double d = cut_face_distance(m, Vec3(0.5, 0.52, 0.5), Vec3(0.1, 1, 0.05));
    if (snap == 0) {
      added_exact = r.tets_added;
      CHECK(d < 1e-6);
    } else {
      added_snap = r.tets_added;
      CHECK(d < snap * 0.5);  // within the threshold times the longest local edge
    }
  }
  CHECK(added_snap < added_exact);
}

TEST_CASE("carving removes the touched tets and tags what they expose", "[cut]") {
  TetMesh m = make_box(Vec3(1, 1, 1), {5, 5, 5});
  m.discard_change();
  const double vol0 = m.total_volume();
  CutOptions o = plain();
  o.mode = CutMode::Remove;
  Cutter cutter(m, o);
  cutter.start({Vec3(-0.2, 0.47, 1.3), Vec3(1.2, 0.47, 1.3)});
  for (int s = 1; s <= 4; ++s) cutter.advance({Vec3(-0.2, 0.47, 1.3 - 0.45 * s), Vec3(1.2, 0.47, 1.3 - 0.45 * s)});
  REQUIRE_NOTHROW(m.validate({true, true}));
  CHECK(m.total_volume() < vol0);
  CHECK(tet_components(m).count == 2);
  CHECK(tagged_area(m, kTagCut) > 2.0);
}

TEST_CASE("cuts act on the current configuration and new vertices follow it", "[cut]") {
  TetMesh m = make_box(Vec3(1, 1, 1), {4, 4, 4});
  m.discard_change();
  // A deformation: shear x += 0.3 z. The blade cuts the plane x = 0.6 in the deformed shape.
  std::vector<Vec3> cur(m.vertex_capacity());
  for (VertexId v : m.vertices()) cur[v.idx()] = m.rest(v) + Vec3(0.3 * m.rest(v).z(), 0, 0);
  auto pos = [&](VertexId v) { return cur[v.idx()]; };
  Cutter cutter(m, plain());
  const auto r = cutter.cut_plane(Vec3(0.6, 0, 0), Vec3(1, 0, 0), pos);
  m.validate({true, true});
  // Every new vertex's current position (interpolated with the record's weights) is on the
  // deformed blade plane or a duplicate of one that is.
  cur.resize(m.vertex_capacity());
  for (const VertexOrigin& o : r.change.added_vertices) {
    Vec3 x = Vec3::Zero(), rest = Vec3::Zero();
    for (int k = 0; k < 4; ++k)
      if (o.parents[k].is_valid()) {
        x += o.weights[k] * cur[o.parents[k].idx()];
        rest += o.weights[k] * m.rest(o.parents[k]);
      }
    cur[o.vertex.idx()] = x;
    CHECK((rest - m.rest(o.vertex)).norm() < 1e-12);
    CHECK(std::abs(x.x() - 0.6) < 1e-9);
  }
  CHECK(tet_components(m).count == 2);
}

TEST_CASE("bad blades are refused with a clear error", "[cut]") {
  TetMesh m = make_box(Vec3(1, 1, 1), {2, 2, 2});
  m.discard_change();
  CutOptions o;
  o.snap = 0.7;
  CHECK_THROWS_AS(Cutter(m, o), InvalidArgument);
  Cutter cutter(m, plain());
  CHECK_THROWS_AS(cutter.start({Vec3(NAN, 0, 0), Vec3(1, 0, 0)}), InvalidArgument);
  CHECK_THROWS_WITH(cutter.start({Vec3(1, 0, 0), Vec3(1, 0, 0)}), Catch::Contains("two ends are the same point"));
  CHECK_THROWS_AS(cutter.cut_plane(Vec3(0, 0, 0), Vec3(0, 0, 0)), InvalidArgument);
  // A blade that does not move or misses the body changes nothing.
  cutter.start({Vec3(0, 0.5, 2), Vec3(1, 0.5, 2)});
  CHECK(cutter.advance({Vec3(0, 0.5, 2), Vec3(1, 0.5, 2)}).change.empty());
  CHECK(cutter.advance({Vec3(0, 0.5, 3), Vec3(1, 0.5, 3)}).change.empty());
}

TEST_CASE("when a cut closes every part, the body is the largest by volume", "[cut]") {
  // Two separate boxes: 6 tets of volume 2, and 48 tets of volume 1 (finely meshed, as a part
  // that the finish's insertion refined). The second is the fragment however many tets it has.
  TetMesh m = make_box(Vec3(2, 1, 1), {1, 1, 1});
  const TetMesh fine = make_box(Vec3(1, 1, 1), {2, 2, 2});
  std::vector<VertexId> map(fine.vertex_capacity());
  for (VertexId v : fine.vertices()) map[v.idx()] = m.add_vertex(fine.rest(v) + Vec3(5, 0, 0));
  for (TetId t : fine.tets()) {
    const auto& tv = fine.tet_vertices(t);
    m.add_tet(map[tv[0].idx()], map[tv[1].idx()], map[tv[2].idx()], map[tv[3].idx()]);
  }
  REQUIRE(m.num_tets() == 54);
  std::vector<TetId> starts;
  for (TetId t : m.tets()) starts.push_back(t);
  cut_detail::FragmentScratch scratch;
  const auto parts = cut_detail::find_fragments(m, starts, 1000, scratch);
  REQUIRE(parts.size() == 1);
  CHECK(parts[0].tets.size() == 48);
  CHECK(parts[0].volume == Approx(1));
}
